"""The replayed model: what every replay shares, and the settings (variants) it runs with.

A :class:`ReplayModel` holds the robot, the terrain (with every terrain-force effect that
may be switched on compiled in at its neutral value), the plant settings and the plant
steps per measurement sample; a :class:`Variant` is one setting of it (terrain θ, joint
and sensor effects). :func:`model_terrain` and :func:`resolve_effect_specs` turn the
user's terrain, calibrated parameters and ``--effect`` arguments into them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ...config import EffectSpec, SimConfig, load_terrain, terrain_from_dict
from ...dynamics import Plant
from ...dynamics.select import PlantChoice, default_plant_choice, select_plant
from ...dynamics.step_sx import trace_joint_effect_params
from ...exceptions import ConfigError
from ...robot.model import Biped
from ...terrain import build_terrain
from ...effects import EffectInfo, all_effects, effect_info, joint_torque_function

MODELS = ("granular", "rigid", "planar")
#: replay parameters that are not terrain θ: ``touchdown_depth`` [m] is the depth of the
#: measured touchdown point below the free surface (touchdown is detected one step late:
#: every foot's surface is raised by it)
REPLAY_PARAMS = ("touchdown_depth",)
#: θ names of the terrain that the calibration may change (see diagnose)
TERRAIN_THETA_CONFIG = {"zeta": "zeta", "phi_s": "phi_s_deg",
                        "bulldozing_length": "bulldozing_length",
                        "sole_shear_alpha": "sole_shear_alpha",
                        "added_mass_scale": "added_mass_scale", "layer_depth": "layer_depth"}


@dataclass(frozen=True)
class Variant:
    """One setting of the replayed model.

    Attributes:
        theta: terrain θ values by name (``zeta``, ``phi_s`` [rad], ``cohesion.suction``,
            ``surface_slope_x`` …) overriding the model's; effect parameters included.
        joints: joint effects ``(EffectInfo, params)``.
        sensors: sensor effects ``(EffectInfo, params)`` (applied to the outputs).
        label: a name for reports.
    """

    theta: Mapping[str, float] = field(default_factory=dict)
    joints: tuple = ()
    sensors: tuple = ()
    label: str = ""

    def with_theta(self, **updates: float) -> "Variant":
        th = dict(self.theta)
        th.update(updates)
        return Variant(th, self.joints, self.sensors, self.label)


@dataclass(frozen=True, eq=False)
class ReplayModel:
    """What the replays share: robot, terrain (with every effect that may be switched on
    compiled in), plant step and sample period.

    Attributes:
        biped: robot.
        terrain: terrain model; its θ holds ``<effect>.<param>`` for each compiled effect.
        sim: plant settings (``dt``, integrator).
        steps_per_sample: plant steps per measurement sample.
        terrain_effects: names of the compiled terrain-force effects.
        plant: the plant the ``granular`` replay steps: ``compiled`` (default, unless
            ``$GRANULAR_MPC_PLANT`` says otherwise) or ``reference``
            (:mod:`granular_mpc.dynamics.select`).
    """

    biped: Biped
    terrain: Any
    sim: SimConfig
    steps_per_sample: int
    terrain_effects: tuple = ()
    plant: str = field(default_factory=default_plant_choice)

    def compiled_plant(self):
        """The compiled plant of the ``granular`` replay, built once per model (by
        :func:`build_replay_model`, before any worker process forks, so they inherit it):
        each foot its own terrain θ, every registered joint effect that CasADi can trace
        compiled in with its parameters in θ (off at their neutral values), one call per
        measurement sample (``chunk = steps_per_sample``).

        Returns:
            ``(FastPlant or None, PlantChoice)``: None when ``plant`` is ``reference`` or
            the compiled plant does not model this one (the choice says why).
        """
        cache = self.__dict__.get("_compiled_cache")
        if cache is None:
            na = len(self.biped.idx_v)
            joints = []
            for info in all_effects(("joint",)).values():
                if not info.neutral:
                    continue
                try:
                    trace_joint_effect_params(info, na)
                except ConfigError:
                    continue                  # replays using it step the reference plant
                joints.append(info)
            plant, choice = select_plant(Plant(self.biped, self.terrain, self.sim), self.plant,
                                         per_foot_theta=True, joint_params=tuple(joints),
                                         chunk=self.steps_per_sample)
            cache = (plant if choice.resolved == "compiled" else None, choice)
            object.__setattr__(self, "_compiled_cache", cache)
        return cache

    def replay_plant(self, variant: "Variant"):
        """The plant a ``granular`` replay of ``variant`` steps and the choice record:
        the compiled plant (:meth:`compiled_plant`) when it models the variant's joint
        effects, else the reference :class:`~granular_mpc.dynamics.Plant` with the reason."""
        fast, choice = self.compiled_plant()
        if fast is not None:
            compiled = {i.name for i in fast.compiled.joint_params}
            names = [info.name for info, _ in variant.joints]
            missing = [n for n in names if n not in compiled]
            if len(set(names)) != len(names):
                missing = missing or ["an effect listed twice"]
            if not missing:
                return fast, choice
            choice = PlantChoice(choice.requested, "reference",
                                 f"joint effect(s) {', '.join(missing)} not compiled")
        jfn = joint_torque_function(list(variant.joints))
        return Plant(self.biped, self.terrain, self.sim,
                     joint_effects=() if jfn is None else (jfn,)), choice

    @property
    def dt(self) -> float:
        return self.sim.dt

    @property
    def contact_stiffness(self) -> float:
        return float(self.terrain.config.contact_stiffness)

    def theta_vector(self, theta: Mapping[str, float]) -> np.ndarray:
        names = self.terrain.param_names
        vec = self.terrain.param_values
        for k, v in theta.items():
            if k in REPLAY_PARAMS:
                continue
            if k not in names:
                raise ConfigError(f"unknown terrain parameter {k!r} for the replay", key="params",
                                  allowed=", ".join(names))
            vec[names.index(k)] = float(v)
        return vec


def build_replay_model(biped: Biped, terrain_cfg, *, sample_rate_hz: float,
                       sim: SimConfig | None = None,
                       terrain_effects: Sequence[str] = (),
                       plant: str | None = None, compile_plant: bool = True) -> ReplayModel:
    """Compile the terrain with the terrain-force effects ``terrain_effects`` (all at their
    neutral values: switch them on through :class:`Variant` θ); ``plant`` (``compiled``,
    ``reference``, default :func:`~granular_mpc.dynamics.select.default_plant_choice`)
    chooses the plant of the ``granular`` replay. ``compile_plant=False`` leaves building
    the compiled plant (≈ 0.3 s even with its library cached) to the first replay, or to
    the :class:`~.pool.ReplayPool` before it forks: for a model that is never replayed."""
    sim = sim or SimConfig()
    names = []
    for n in terrain_effects:
        if n not in names and effect_info(n).kind == "terrain_force":
            names.append(n)
    specs = [EffectSpec(name=n, params=effect_info(n).neutral_params()) for n in names]
    already = {e.name for e in terrain_cfg.effects}
    specs = [s for s in specs if s.name not in already]
    terrain = build_terrain(terrain_cfg, biped.config, extra_effects=specs)
    sps = max(1, int(round(1.0 / (sample_rate_hz * sim.dt))))
    model = ReplayModel(biped, terrain, sim, sps,
                        tuple(list(already) + [s.name for s in specs]),
                        default_plant_choice() if plant is None else plant)
    if model.plant == "compiled" and compile_plant:
        model.compiled_plant()               # here, so that forked workers inherit it
    return model


def effect_variant(specs: Sequence[tuple[EffectInfo, Mapping[str, float]]],
                   base: Variant | None = None, label: str = "") -> Variant:
    """``base`` plus the effects ``specs`` (terrain-force and geometry as θ, joint and
    sensor as callables)."""
    base = base or Variant()
    theta = dict(base.theta)
    joints = list(base.joints)
    sensors = list(base.sensors)
    for info, p in specs:
        if info.kind == "terrain_force":
            for k, v in p.items():
                theta[f"{info.name}.{k}"] = float(v)
        elif info.kind == "geometry":
            theta.update({k: float(v) for k, v in info.fn(dict(p)).items()})
        elif info.kind == "joint":
            joints.append((info, dict(p)))
        elif info.kind == "sensor":
            sensors.append((info, dict(p)))
    return Variant(theta, tuple(joints), tuple(sensors), label or base.label)



def model_terrain(terrain: str | Mapping | Any = "dry_sand",
                  params: Mapping[str, float] | None = None):
    """The model's terrain config: a terrain name/path or config, with calibrated θ
    (``zeta``, ``phi_s`` [rad] …) applied."""
    if isinstance(terrain, (str, Path)):
        cfg = load_terrain(str(terrain))
    elif isinstance(terrain, Mapping):
        cfg = terrain_from_dict(terrain)
    else:
        cfg = terrain
    if params:
        upd = {}
        for k, v in params.items():
            if k == "phi_s":
                upd["phi_s_deg"] = math.degrees(float(v))
            elif k in TERRAIN_THETA_CONFIG:
                upd[TERRAIN_THETA_CONFIG[k]] = float(v)
            elif k in ("surface_slope_x", "surface_slope_y", "surface_height") or k in REPLAY_PARAMS:
                continue        # geometry is per stance in the replay; replay parameters
            else:
                raise ConfigError(f"unknown calibrated parameter {k!r}", key="params",
                                  allowed=", ".join(TERRAIN_THETA_CONFIG))
        cfg = cfg.model_copy(update=upd)
    return cfg


def resolve_effect_specs(effects: Sequence[Any], fitted: Mapping[str, Mapping] | None = None
                         ) -> list[tuple[EffectInfo, dict[str, float]]]:
    """(EffectInfo, parameters) per effect: explicit values win, then fitted values, then
    the registered defaults."""
    out = []
    for e in effects or ():
        spec = e if isinstance(e, EffectSpec) else EffectSpec.model_validate(e)
        info = effect_info(spec.name)
        given = dict((fitted or {}).get(spec.name, {}))
        given = {k: v for k, v in given.items() if k in info.params}
        given.update(spec.params)
        out.append((info, info.resolve_params(given)))
    return out


__all__ = ["MODELS", "REPLAY_PARAMS", "TERRAIN_THETA_CONFIG", "Variant", "ReplayModel",
           "build_replay_model", "effect_variant", "model_terrain", "resolve_effect_specs"]
