"""What the controller believes about the ground: admissible foot forces and sinkage.

Granular terrain (from the controller's own terrain model): the RFT yield curve of the sole
at depth z — the force ``(F_h(γ), F_z(γ))`` the sand exerts while the foot flows in
direction γ — bounds every force the sand can hold. Normalised by the vertical capacity
``F_cap(z)`` its shape barely changes with depth, so an inner polytope of it, taken at the
largest sinkage the controller allows (``mpc.max_sinkage``), is used as the force
constraint:

    0 ≤ F_z ≤ F_cap(z_max)
    |F_h| ≤ μ_h F_z          (shear carried while the foot sinks: flow at ≥ 45°)
    |F_h| ≤ κ_h (F_cap − F_z) (no shear left at the vertical yield point)
    |F_l| ≤ μ_l F_z,  |F_l| ≤ L_cap(z_max)        (sole shear + developed bulldozing)

The lateral law of the terrain model (sole shear plus bulldozing pile) does not depend on
the vertical force at a given depth, so the lateral rows carry no coupling to F_z other
than the depth the load produces (μ_l = L_cap/F_cap at z_max).

Sinkage prediction: under a vertical load F the foot settles where the closed form's
vertical capacity equals F, ``z = Z(F)`` (plastic: it does not come back up on unloading).

Rigid ground: ``0 ≤ F_z ≤ F_max``, ``|F_h|, |F_l| ≤ μ F_z``, no sinkage.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..config import MPCConfig
from ..terrain.base import TerrainModel
from ..terrain.closed_form import yield_polygon
from ..terrain.rft import Coefficients


def interp_scalar(x: float, xp: list, fp: list) -> float:
    """``np.interp(x, xp, fp)`` for one Python float ``x`` on increasing ``xp`` (lists):
    the same formula (``slope·(x − xp[j]) + fp[j]``, ends held), without NumPy's
    per-call cost (≈ 3 µs per scalar call; this is ≈ 0.3 µs). NaN gives NaN."""
    if x != x:
        return x
    if x <= xp[0]:
        return fp[0]
    j = bisect_right(xp, x) - 1
    if j >= len(xp) - 1:
        return fp[-1]
    if xp[j] == x:
        return fp[j]
    return (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]) * (x - xp[j]) + fp[j]


@dataclass(frozen=True)
class ForcePolytope:
    """Per-foot force constraints ``G f ≤ h`` with f = (F_h, F_l, F_z) in the foot's
    heading frame, plus bounds 0 ≤ F_z ≤ f_max."""

    G: np.ndarray
    h: np.ndarray
    f_max: float

    def scaled(self, share: float) -> "ForcePolytope":
        """The same set for one of several contact points sharing the foot's load."""
        return ForcePolytope(self.G, self.h * share, self.f_max * share)

    @property
    def cone_rows(self) -> np.ndarray:
        """Rows with h = 0: a friction-like cone, the same for any share of the load
        (applied to each contact point)."""
        return np.flatnonzero(self.h <= 0.0)

    @property
    def capacity_rows(self) -> np.ndarray:
        """Rows with h > 0: what the ground bears in total (applied to a foot's sum)."""
        return np.flatnonzero(self.h > 0.0)

    def contains(self, f: np.ndarray, tol: float = 1e-6) -> bool:
        return bool(np.all(self.G @ f <= self.h + tol) and -tol <= f[2] <= self.f_max + tol)


@dataclass(frozen=True)
class GroundModel:
    """The controller's ground model (immutable): force polytope and sinkage law."""

    kind: str                 # "granular" or "rigid"
    polytope: ForcePolytope
    surface_height: float
    _depths: np.ndarray       # tabulated Z(F): depth grid [m]
    _caps: np.ndarray         # vertical capacity at those depths [N]

    @property
    def granular(self) -> bool:
        return self.kind == "granular"

    @cached_property
    def lateral_ratio(self) -> float:
        """Largest |F_l|/F_z the ground model admits (μ_l on sand, μ on rigid ground)."""
        G = self.polytope.G
        rows = [i for i in range(G.shape[0]) if G[i, 1] > 0 and G[i, 2] < 0]
        return float(min(-G[i, 2] for i in rows))

    @cached_property
    def _table(self) -> tuple[list, list, float]:
        """The tabulated Z(F) as Python lists (depths [m], capacities [N]) and f_max [N],
        for the scalar look-ups of the controller's tick."""
        return self._depths.tolist(), self._caps.tolist(), float(self.polytope.f_max)

    def capacity(self, depth: float) -> float:
        """Vertical force [N] the medium bears at ``depth`` [m] (the polytope's f_max at and
        beyond the allowed sinkage; unbounded → f_max on rigid ground)."""
        if not self.granular:
            return self.polytope.f_max
        if depth <= 0.0:
            return 0.0
        depths, caps, f_max = self._table
        # np.interp's numbers on Python floats (called per foot at every WBC tick)
        return min(interp_scalar(float(depth), depths, caps), f_max)

    def capacities(self, depths) -> np.ndarray:
        """:meth:`capacity` of each of ``depths`` [m] in one interpolation (the same
        numbers: ``np.interp`` evaluates each point alone) [N]."""
        d = np.asarray(depths, dtype=float)
        if not self.granular:
            return np.full(d.shape, float(self.polytope.f_max))
        cap = np.minimum(np.interp(d, self._depths, self._caps), self.polytope.f_max)
        return np.where(d <= 0.0, 0.0, cap)

    def sinkage(self, force: float) -> float:
        """Depth Z(F) [m] at which the vertical capacity equals ``force`` [N] (0 on rigid)."""
        if not self.granular or force <= 0.0:
            return 0.0
        depths, caps, _ = self._table
        return interp_scalar(float(force), caps, depths)

    def sinkage_slope(self, force: float) -> float:
        """dZ/dF [m/N] at ``force``."""
        if not self.granular:
            return 0.0
        i = int(np.clip(np.searchsorted(self._caps, force), 1, len(self._caps) - 1))
        return float((self._depths[i] - self._depths[i - 1]) / (self._caps[i] - self._caps[i - 1]))


def ground_model(terrain: TerrainModel, mpc: MPCConfig) -> GroundModel:
    """Build the controller's ground model from a terrain model and the MPC settings."""
    if terrain.kind == "rigid":
        mu = mpc.friction
        G = np.array([[1, 0, -mu], [-1, 0, -mu], [0, 1, -mu], [0, -1, -mu]], dtype=float)
        poly = ForcePolytope(G, np.zeros(4), mpc.max_normal_force)
        return GroundModel("rigid", poly, terrain.surface_height, np.zeros(2), np.array([0.0, 1.0]))
    z_max = min(mpc.max_sinkage, 0.95 * terrain.config.layer_depth)
    c = terrain.config
    mu_h, kappa_h, cap = yield_polygon(terrain.shape, math.radians(c.phi_s_deg), z_max,
                                       coeffs=Coefficients.from_config(c.rft), zeta=c.zeta)
    _, lat = terrain.horizontal_capacity(z_max)
    mu_l = float(lat / cap)
    G = np.array([[1, 0, -mu_h], [-1, 0, -mu_h], [1, 0, kappa_h], [-1, 0, kappa_h],
                  [0, 1, -mu_l], [0, -1, -mu_l], [0, 1, 0], [0, -1, 0]], dtype=float)
    h = np.array([0, 0, kappa_h * cap, kappa_h * cap, 0, 0, lat, lat])
    poly = ForcePolytope(G, h, min(cap, mpc.max_normal_force))
    depths = np.linspace(0.0, z_max * 1.5, 200)
    caps = np.array([terrain.vertical_capacity(z) for z in depths])
    caps = np.maximum.accumulate(caps + 1e-9 * np.arange(len(caps)))
    return GroundModel("granular", poly, terrain.surface_height, depths, caps)


__all__ = ["ForcePolytope", "GroundModel", "ground_model", "interp_scalar"]
