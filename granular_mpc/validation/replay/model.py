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
from ...exceptions import ConfigError
from ...robot.model import Biped
from ...terrain import build_terrain
from ...effects import EffectInfo, effect_info

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
    """

    biped: Biped
    terrain: Any
    sim: SimConfig
    steps_per_sample: int
    terrain_effects: tuple = ()

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
                       terrain_effects: Sequence[str] = ()) -> ReplayModel:
    """Compile the terrain with the terrain-force effects ``terrain_effects`` (all at their
    neutral values: switch them on through :class:`Variant` θ)."""
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
    return ReplayModel(biped, terrain, sim, sps,
                       tuple(list(already) + [s.name for s in specs]))


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
