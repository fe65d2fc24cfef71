"""The terrain model interface: one immutable object per (terrain config, robot foot).

    terrain = build_terrain(load_terrain("dry_sand"), biped.config)
    data = terrain.new_data()            # patch states, buffers
    data.kin[0][:] = ...                 # left foot kinematics (see contact.N_KIN)
    data.evaluate(); data.commit()       # forces in data.force, contact points in data.point

Besides the plant-side contact function, a terrain model answers the questions the MPC,
the analysis and the calibration ask, as floats or CasADi expressions:
:meth:`TerrainModel.foot_forces` (closed form for the whole foot),
:meth:`TerrainModel.vertical_capacity`, :meth:`TerrainModel.quasi_static_depth` and
:meth:`TerrainModel.casadi_foot_forces` (exact derivatives w.r.t. state and parameters).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..config import FootGeometry, GranularTerrainConfig, RigidTerrainConfig, RobotConfig
from ..config.terrain import TrackTerrainConfig
from ..exceptions import ConfigError
from .closed_form import FLOAT, FootShape, lateral_capacity, sagittal_forces
from .contact import CompiledContact, ContactData
from ..effects import Effect, get_effect
from .granular import GRANULAR_PARAMS, granular_param_values, make_granular_law
from .rft import Coefficients
from .rigid import RIGID_PARAMS, make_rigid_law, rigid_param_values
from .track import TrackTerrain, build_track


@dataclass(frozen=True)
class TerrainModel:
    """Immutable terrain model for one robot's feet.

    Attributes:
        config: the validated terrain config.
        kind: ``"granular"`` or ``"rigid"``.
        foot: the sole geometry (full width).
        contact: the compiled all-patch contact function.
        effects: the optional effects with their parameter values.
    """

    config: Any
    kind: str
    foot: FootGeometry
    contact: CompiledContact
    effects: tuple[tuple[Effect, dict], ...] = ()
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # ------------------------------------------------------------------ plant side
    def new_data(self, dt: float | None = None) -> ContactData:
        data = self.contact.new_data()
        if dt is not None:
            data.set_dt(dt)
        return data

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def surface_height(self) -> float:
        return float(self.config.surface_height)

    @property
    def param_names(self) -> tuple[str, ...]:
        return self.contact.param_names

    @property
    def param_values(self) -> np.ndarray:
        return self.contact.param_values.copy()

    @property
    def shape(self) -> FootShape:
        return FootShape.from_geometry(self.foot)

    # ------------------------------------------------------------------ closed form
    def foot_forces(self, depth: float, pitch: float = 0.0, v_h: float = 0.0,
                    v_z: float = -1.0):
        """Closed-form force on the whole foot (all slices level) [N].

        Args:
            depth: depth of the lowest sole point [m].
            pitch: foot pitch ψ_c [rad] (angle of the foot's −z axis from down, toward +x).
            v_h, v_z: direction of motion, forward and up [any unit].

        Returns:
            :class:`~.closed_form.SagittalForces`; for rigid ground the vertical force is
            unbounded and this returns ``f_z = inf`` for depth > 0.
        """
        if self.kind == "rigid":
            from .closed_form import SagittalForces
            inf = math.inf if depth > 0 else 0.0
            return SagittalForces(0.0, inf, 0.0, 0.0, depth)
        c = self.config
        return sagittal_forces(FLOAT, self.shape, math.radians(c.phi_s_deg), depth, pitch,
                               v_h, v_z, coeffs=Coefficients.from_config(c.rft), zeta=c.zeta)

    def vertical_capacity(self, depth: float, pitch: float = 0.0) -> float:
        """Vertical force the medium bears for pure penetration at ``depth`` [N]."""
        return float(self.foot_forces(depth, pitch, 0.0, -1.0).f_z)

    def horizontal_capacity(self, depth: float, *, lateral_slip: float | None = None) -> tuple[float, float]:
        """Shear limits (forward, lateral) [N] at ``depth`` for horizontal motion.

        Forward: the RFT resistance to pure horizontal motion. Lateral: sole shear plus
        the bulldozing pile (fully developed unless ``lateral_slip`` [m] is given).
        """
        if self.kind == "rigid":
            return math.inf, math.inf
        c = self.config
        sag = self.foot_forces(depth, 0.0, 1.0, 0.0)
        y = 10.0 * c.bulldozing_length if lateral_slip is None else lateral_slip
        lat = lateral_capacity(FLOAT, self.shape, sag, 1.0, 0.0, y, zeta=c.zeta,
                               bulldozing_length=c.bulldozing_length,
                               shear_alpha=c.sole_shear_alpha, full_width=self.foot.width,
                               coeffs=Coefficients.from_config(c.rft))
        return abs(float(sag.f_h)), float(lat)

    def quasi_static_depth(self, load: float, pitch: float = 0.0, *, max_depth: float | None = None) -> float:
        """Depth [m] at which pure penetration bears ``load`` [N] (bisection on the closed form)."""
        if self.kind == "rigid" or load <= 0.0:
            return 0.0
        hi = max_depth if max_depth is not None else self.config.layer_depth
        if self.vertical_capacity(hi, pitch) < load:
            raise ConfigError(f"the layer cannot bear {load:.1f} N above its floor",
                              key="terrain.layer_depth", value=self.config.layer_depth)
        lo = 0.0
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if self.vertical_capacity(mid, pitch) < load:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    def casadi_foot_forces(self):
        """CasADi function (depth, pitch, v_h, v_z, θ) → (f_h, f_z, S₁, Q) for the whole foot.

        θ holds ``(zeta, phi_s, bulldozing_length, sole_shear_alpha)``; derivatives are exact.
        """
        if "cas_ff" in self._cache:
            return self._cache["cas_ff"]
        import casadi as ca

        from .closed_form import casadi_ops

        if self.kind == "rigid":
            raise ConfigError("rigid ground has no force–depth law", key="terrain.kind")
        o = casadi_ops()
        x = ca.SX.sym("x", 4)
        th = ca.SX.sym("theta", 4)
        r = sagittal_forces(o, self.shape, th[1], x[0], x[1], x[2], x[3],
                            coeffs=Coefficients.from_config(self.config.rft), zeta=th[0])
        f = ca.Function("foot_forces", [x, th],
                        [ca.vertcat(r.f_h, r.f_z, r.shear_moment, r.side_moment)],
                        ["state", "theta"], ["forces"])
        self._cache["cas_ff"] = f
        return f

    @property
    def casadi_theta(self) -> np.ndarray:
        c = self.config
        return np.array([c.zeta, math.radians(c.phi_s_deg), c.bulldozing_length, c.sole_shear_alpha])


def build_terrain(config, robot: RobotConfig, *, extra_effects: Sequence = ()) -> TerrainModel | TrackTerrain:
    """Build the terrain model for ``robot``'s feet from a validated terrain config.

    Args:
        config: a :class:`GranularTerrainConfig`, :class:`RigidTerrainConfig` or
            :class:`~granular_mpc.config.terrain.TrackTerrainConfig` (then a
            :class:`~.track.TrackTerrain` of one model per segment).
        robot: the robot config (sole geometry and number of slices).
        extra_effects: more :class:`~granular_mpc.config.EffectSpec` (e.g. from the CLI);
            on a track, added to every segment.
    """
    if isinstance(config, TrackTerrainConfig):
        return build_track(config, [build_terrain(s.terrain, robot, extra_effects=extra_effects)
                                    for s in config.segments])
    foot = robot.foot
    n = foot.slices
    width = foot.width / n
    slice_shape = FootShape(foot.radius, foot.half_angle, width)
    offsets = (np.arange(n) + 0.5) * width - foot.width / 2.0
    effects = []
    for spec in list(config.effects) + list(extra_effects):
        eff = get_effect(spec.name)
        effects.append((eff, eff.resolve_params(spec.params)))
    if isinstance(config, GranularTerrainConfig):
        law = make_granular_law(config, slice_shape, foot.width)
        names, values, density = list(GRANULAR_PARAMS), granular_param_values(config), config.density
    elif isinstance(config, RigidTerrainConfig):
        law = make_rigid_law(config)
        names, values, density = list(RIGID_PARAMS), rigid_param_values(config), 0.0
    else:  # pragma: no cover - validated upstream
        raise ConfigError(f"unknown terrain config {type(config).__name__}", key="terrain.kind")
    for eff, vals in effects:
        for pname, val in vals.items():
            names.append(f"{eff.name}.{pname}")
            values.append(val)
    contact = CompiledContact(law, slice_offsets=offsets, radius=foot.radius,
                              half_angle=foot.half_angle, param_names=names,
                              param_values=values, effects=effects, density=density,
                              slice_width=width)
    return TerrainModel(config=config, kind=config.kind, foot=foot, contact=contact,
                        effects=tuple(effects))


__all__ = ["TerrainModel", "build_terrain", "GranularTerrainConfig", "RigidTerrainConfig",
           "TrackTerrainConfig", "TrackTerrain"]
