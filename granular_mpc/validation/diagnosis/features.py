"""The force-equation samples and the library of physically named features a proposed
term is built from (``docs/validation.md`` §3.6).

While the stance foot sinks, the medium yields and the model's vertical and forward
force *is* the closed-form RFT force at the measured depth, pitch and direction of
motion (model.md §2.4; the same samples as the calibration, §3.1). What the measured foot
force has beyond it is the force the model is missing — an *equation error* at the
measured state, free of the replay's drift and of the way a missing force moves into
the depth in a replay (the robot's weight must be carried either way). Each feature is a
function of the measured state of the stance foot with a :class:`PatchState` expression
of the same quantity, so a selected combination can be written as a terrain-force
effect in the plugin format (:mod:`.proposal_file`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..prepare import StanceWindow

#: sinking samples: sink rate [m/s], depth [m], vertical force [N]. The rate is twice the
#: calibration's: at the end of the sinking the smoothed rate lags the foot coming to rest,
#: and those samples (≈ 10 % of the calibration's) carry a 20–35 N equation error on data
#: the model reproduces exactly — more than the effects a proposal is after.
MIN_SINK_RATE = 0.4
MIN_DEPTH = 2e-3
MIN_FORCE = 10.0

#: the force axes a proposal is fitted on: vertical (W z, up) and forward (along the sole's heading)
AXES = ("z", "h")


@dataclass(frozen=True)
class Feature:
    """One physically named regressor.

    Attributes:
        name: identifier (also the coefficient's name in the effect file).
        description: what it is, in words.
        unit: the feature's unit (the coefficient's unit is N per this).
        patch_expression: the same quantity written on a :class:`PatchState` ``s`` with the
            math namespace ``o`` (empty: not expressible in the plugin state).
        compute: (sample columns) → feature values.
        relative: a share of the terrain law's own force (a foot-level coefficient is
            then the same per patch), not a force per unit of a state (divided among the
            foot's patches).
        in_library: whether the whole-library fit (the proposal's ``library`` stage) uses
            it; the depth-layer features are fitted only alone, in their own stage
            (:data:`LAYER_DEPTHS`).
    """

    name: str
    description: str
    unit: str
    patch_expression: str
    compute: Callable[[Mapping[str, np.ndarray]], np.ndarray]
    relative: bool = False
    in_library: bool = True

    @property
    def expressible(self) -> bool:
        """Whether a terrain-force effect can read it."""
        return bool(self.patch_expression)


_V_H = "(s.v_c[0] * s.heading[0] + s.v_c[1] * s.heading[1])"
_V_L = "(s.v_c[0] * s.lateral[0] + s.v_c[1] * s.lateral[1])"
_F_H = "(s.f_terrain[0] * s.heading[0] + s.f_terrain[1] * s.heading[1])"

#: the feature library (foot level; all zero out of contact). On sinking samples v_z < 0,
#: so |v_z| and sign(v_z) would duplicate v_z and the constant: they are not in it.
#: Foot identity enters as a constant on the right foot and as the right foot's share of
#: the law's own force (a right track of other sand, or a worn right sole): with ζ free
#: (the law's common scale), a left-foot version of either would duplicate it.
_STATE_FEATURES: tuple[Feature, ...] = (
    Feature("contact", "constant force while in contact", "1", "s.in_contact",
            lambda c: np.ones_like(c["depth"])),
    Feature("depth", "depth of the sole below the free surface", "m", "s.depth",
            lambda c: c["depth"]),
    Feature("depth_sq", "depth squared", "m²", "s.depth ** 2", lambda c: c["depth"] ** 2),
    Feature("v_z", "vertical sole velocity (W z, up; < 0 while sinking)", "m/s", "s.v_c[2]",
            lambda c: c["v_z"]),
    Feature("v_z_abs_v_z", "v_z·|v_z| (quadratic vertical drag)", "m²/s²",
            "s.v_c[2] * o.fabs(s.v_c[2])", lambda c: c["v_z"] * np.abs(c["v_z"])),
    Feature("depth_v_z", "depth × vertical sole velocity", "m²/s", "s.depth * s.v_c[2]",
            lambda c: c["depth"] * c["v_z"]),
    Feature("v_h", "forward sole velocity (along the heading)", "m/s", _V_H,
            lambda c: c["v_h"]),
    Feature("abs_v_h", "forward sole speed |v_h|", "m/s", f"o.fabs{_V_H}",
            lambda c: np.abs(c["v_h"])),
    Feature("sign_v_h", "sign of the forward sole velocity (Coulomb-like)", "1",
            f"o.if_else({_V_H} > 0.0, 1.0, -1.0)", lambda c: np.sign(c["v_h"])),
    Feature("v_h_abs_v_h", "v_h·|v_h| (quadratic forward drag)", "m²/s²",
            f"{_V_H} * o.fabs{_V_H}", lambda c: c["v_h"] * np.abs(c["v_h"])),
    Feature("v_l", "lateral sole velocity (left of the heading)", "m/s", _V_L,
            lambda c: c["v_l"]),
    Feature("a_z", "vertical sole acceleration", "m/s²", "s.a_c[2]", lambda c: c["a_z"]),
    Feature("t_stance", "time since touchdown", "s", "s.t_stance", lambda c: c["t_stance"]),
    Feature("right_foot", "1 on the right foot (per-foot difference)", "1", "s.is_right",
            lambda c: c["foot"].astype(float)),
    Feature("right_law_z", "the terrain law's vertical force on the right foot only "
            "(per-foot sand or sole)", "N", "s.is_right * s.f_terrain[2]",
            lambda c: c["foot"] * c["law_z"], relative=True),
    Feature("right_law_h", "the terrain law's forward force on the right foot only "
            "(per-foot sand or sole)", "N", f"s.is_right * {_F_H}",
            lambda c: c["foot"] * c["law_h"], relative=True),
)


#: interface depths [m] of the depth-layer features (issue 11 item 3: a loose top layer
#: over a harder bed, or a crust over looser sand). Each is tried alone in the proposal's
#: ``layer`` stage, never in the whole-library fit: beside depth and depth² a hinge at a
#: grid of depths is a flexible curve that fits the closed form's own null pattern. The
#: grid spans the sinking samples' depths on sand_walk (2–32 mm, median 13 mm).
LAYER_DEPTHS = (0.005, 0.010, 0.015, 0.020, 0.025, 0.030)


def _layer_features() -> tuple[Feature, ...]:
    """Two forms per interface depth d_L: a stiffness that acts only below it, k·(d −
    d_L)⁺ (a harder bed under loose sand, k > 0; a looser bed under a crust, k < 0), and the
    law's own vertical force scaled by the depth's share below it, f_law,z·(d − d_L)⁺/d —
    the stress growing (1 + g) times as fast below d_L (``effects.variants.hard_layer``'s
    form; a share, so > −1)."""
    out = []
    for d in LAYER_DEPTHS:
        mm = f"{1e3 * d:.0f}mm"
        below = f"o.fmax(s.depth - {d:g}, 0.0)"
        out.append(Feature(
            f"below_{mm}", f"depth below {1e3 * d:.0f} mm (a layer of other stiffness under it)",
            "m", below,
            lambda c, d=d: np.maximum(c["depth"] - d, 0.0), in_library=False))
        out.append(Feature(
            f"law_below_{mm}", f"the terrain law's vertical force × the share of the depth "
            f"below {1e3 * d:.0f} mm (the stress grows faster or slower under it)", "N",
            f"s.f_terrain[2] * {below} / o.fmax(s.depth, 1e-4)",
            lambda c, d=d: c["law_z"] * np.maximum(c["depth"] - d, 0.0)
            / np.maximum(c["depth"], 1e-4), relative=True, in_library=False))
    return tuple(out)


FEATURES: tuple[Feature, ...] = _STATE_FEATURES + _layer_features()
#: columns of :data:`FEATURES` the whole-library fit uses
LIBRARY_INDEX = np.array([k for k, f in enumerate(FEATURES) if f.in_library])


def feature_names() -> tuple[str, ...]:
    """Names of :data:`FEATURES`, in order."""
    return tuple(f.name for f in FEATURES)


def feature(name: str) -> Feature:
    """The feature called ``name``."""
    return next(f for f in FEATURES if f.name == name)


@dataclass(frozen=True, eq=False)
class ForceSamples:
    """The equation-error samples of the force, per axis.

    Attributes:
        target: axis → measured − model force at the calibrated θ [N], (N,).
        nuisance: axis → ∂(model force)/∂ζ [N], (N,) (ζ stays free: never a feature).
        features: (N, F) feature values (:data:`FEATURES` order).
        trial, window, foot: per sample (foot 0 left, 1 right).
        n_slices: contact patches per foot (a foot-level coefficient / n_slices is the
            per-patch coefficient of an effect file).
    """

    target: Mapping[str, np.ndarray]
    nuisance: Mapping[str, np.ndarray]
    features: np.ndarray
    trial: np.ndarray
    window: np.ndarray
    foot: np.ndarray
    n_slices: int

    @property
    def n(self) -> int:
        return int(self.trial.size)


def sample_columns(windows: Sequence[StanceWindow]) -> dict[str, np.ndarray]:
    """The measured state on the sinking samples of every window (the calibration's
    samples): depth, pitch, sole velocity (W z; forward and lateral along the heading),
    vertical acceleration, time in stance, forward and vertical force, trial, window, foot;
    the heading (W x, y), the rise from the deepest point so far and the sink rate."""
    keys = ("depth", "pitch", "v_h", "v_l", "v_z", "a_z", "t_stance", "f_h", "f_z", "window",
            "trial", "foot", "heading_x", "heading_y", "rise", "depth_rate")
    cols: dict[str, list] = {k: [] for k in keys}
    for w in windows:
        f = w.features
        m = (f["sink_velocity"] > MIN_SINK_RATE) & (f["depth"] > MIN_DEPTH) & (f["grf_z"] > MIN_FORCE)
        if not m.any():
            continue
        n = int(m.sum())
        cols["depth"].append(f["depth"][m])
        cols["pitch"].append(f["pitch"][m])
        cols["v_h"].append(f["v_h"][m])
        cols["v_l"].append(f["v_l"][m])
        cols["v_z"].append(f["vc_z"][m])
        cols["a_z"].append(-f["sink_acceleration"][m])
        cols["t_stance"].append(f["time_in_stance"][m])
        cols["f_h"].append(w.meas["grf_x"][m] * f["heading_x"][m]
                           + w.meas["grf_y"][m] * f["heading_y"][m])
        cols["f_z"].append(w.meas["grf_z"][m])
        cols["window"].append(np.full(n, w.index))
        cols["trial"].append(np.full(n, w.trial, dtype=object))
        cols["foot"].append(np.full(n, w.foot))
        cols["heading_x"].append(f["heading_x"][m])
        cols["heading_y"].append(f["heading_y"][m])
        cols["rise"].append(f["rise_from_deepest"][m])
        cols["depth_rate"].append(f["sink_velocity"][m])
    return {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in cols.items()}


def force_samples(windows: Sequence[StanceWindow], terrain, theta: Mapping[str, float], *,
                  n_slices: int) -> ForceSamples:
    """Equation-error force samples at the calibrated θ and the feature matrix.

    Args:
        windows: stance windows.
        terrain: the model's :class:`~granular_mpc.terrain.TerrainModel` (granular).
        theta: calibrated parameters (``zeta``; ``phi_s`` if calibrated).
        n_slices: contact patches per foot.
    """
    import casadi as ca

    c = sample_columns(windows)
    N = int(c["depth"].size)
    if N == 0:
        z = np.zeros(0)
        return ForceSamples({a: z for a in AXES}, {a: z for a in AXES},
                            np.zeros((0, len(FEATURES))), c["trial"], c["window"], c["foot"],
                            n_slices)
    cfg = terrain.config
    th = terrain.casadi_theta.copy()
    th[0] = float(theta.get("zeta", th[0]))
    if "phi_s" in theta:
        th[1] = float(theta["phi_s"])
    K, tau = cfg.contact_stiffness, cfg.direction_time_constant
    u_h = c["v_h"] - c["f_h"] / (n_slices * K * tau)
    u_z = c["v_z"] - c["f_z"] / (n_slices * K * tau)
    X = ca.DM(np.vstack([c["depth"], c["pitch"], u_h, u_z]))
    fn = terrain.casadi_foot_forces()
    ths = ca.MX.sym("th", 4)
    Xs = ca.MX.sym("X", 4, N)
    out = fn.map(N, "serial")(Xs, ca.repmat(ths, 1, N))
    fh, fz = ca.transpose(out[0, :]), ca.transpose(out[1, :])
    ev = ca.Function("ff", [Xs, ths], [fh, fz, ca.jacobian(fh, ths)[:, 0],
                                       ca.jacobian(fz, ths)[:, 0]])
    mh, mz, jh, jz = (np.asarray(v).ravel() for v in ev(X, th))
    F = np.column_stack([f.compute({**c, "law_z": mz, "law_h": mh}) for f in FEATURES])
    return ForceSamples({"z": c["f_z"] - mz, "h": c["f_h"] - mh}, {"z": jz, "h": jh}, F,
                        c["trial"].astype(str), c["window"].astype(int), c["foot"].astype(int),
                        n_slices)


__all__ = ["Feature", "FEATURES", "LAYER_DEPTHS", "LIBRARY_INDEX", "ForceSamples",
           "force_samples", "sample_columns", "feature_names", "feature", "AXES"]
