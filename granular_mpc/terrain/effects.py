"""Optional physical effects: a registry of named force terms added to any terrain model.

An *effect* is a small, parameterised force on a contact patch, written once with the
``o`` math namespace (``o.sin``, ``o.sqrt``, ``o.fmax``, ``o.if_else`` …) so that the
same source compiles into the plant's CasADi contact function (fast, and with exact
derivatives for calibration) and evaluates on plain floats.

Add one from YAML (``effects: [{name: inertial_drag, params: {c_d: 1.2}}]`` in a terrain
file, or ``"inertial_drag:c_d=1.2"``) or from user code::

    from granular_mpc.terrain.effects import Param, register_effect

    @register_effect("sole_adhesion", params={"f0": Param(2.0, 0.0, 50.0, "N", "pull-off force")})
    def sole_adhesion(o, s, p):
        '''Constant pull toward the sand while the sole is buried and rising.'''
        rising = o.if_else(s.v_c[2] > 0.0, 1.0, 0.0)
        return (0.0, 0.0, -p["f0"] * rising * s.in_contact)

The function receives ``s`` (:class:`PatchState`, world frame, SI units) and ``p`` (the
parameter values by name) and returns the world force on the foot (fx, fy, fz) [N].
Effects see the terrain's own forces in ``s`` but never change them: they add.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

from ..exceptions import ConfigError


@dataclass(frozen=True)
class Param:
    """One effect parameter: default value, physical bounds, unit and meaning."""

    default: float
    lower: float
    upper: float
    unit: str = ""
    doc: str = ""

    def check(self, effect: str, name: str, value: float) -> float:
        value = float(value)
        if not (self.lower <= value <= self.upper):
            raise ConfigError(f"effect '{effect}': parameter {name} = {value} is out of range",
                              key=f"effects.{effect}.{name}", value=value,
                              allowed=f"[{self.lower}, {self.upper}] {self.unit}".strip())
        return value


@dataclass
class PatchState:
    """What an effect may read about one contact patch (values or CasADi expressions).

    Attributes:
        depth: depth of the lowest sole point below the free surface [m] (> 0 in contact).
        in_contact: 1 when the patch touches the terrain, else 0.
        p_c: contact point (lowest sole point) in W [m].
        v_c: its velocity in W [m/s].
        a_c: its acceleration in W (finite difference over one step) [m/s²].
        intrusion: (x_s, y_s, z_s) = contact point relative to the touchdown point C0,
            z positive deeper [m].
        heading, lateral: unit horizontal vectors along the foot's x axis and left of it.
        f_terrain: the terrain model's own force on the patch in W [N].
        f_yield_z: vertical force the medium bears at this depth for pure penetration [N].
        area_h: horizontal area of the submerged sole of the patch [m²].
        width: patch (slice) width [m].
        density: bulk density of the medium [kg/m³] (0 for rigid ground).
        dt: plant step [s].
        depth_max: deepest depth of this patch since touchdown [m].
        t_stance: time since touchdown [s].
    """

    depth: Any
    in_contact: Any
    p_c: tuple
    v_c: tuple
    a_c: tuple
    intrusion: tuple
    heading: tuple
    lateral: tuple
    f_terrain: tuple
    f_yield_z: Any
    area_h: Any
    width: float
    density: float
    dt: Any
    depth_max: Any = 0.0
    t_stance: Any = 0.0


ForceFn = Callable[[Any, PatchState, Mapping[str, Any]], tuple]


@dataclass(frozen=True)
class Effect:
    """A registered effect: its force function and its parameters."""

    name: str
    force: ForceFn
    params: Mapping[str, Param] = field(default_factory=dict)
    doc: str = ""

    def resolve_params(self, given: Mapping[str, float]) -> dict[str, float]:
        """Defaults overridden by ``given``; unknown names and out-of-range values rejected."""
        return resolve_params(self.name, self.params, given)


def resolve_params(effect: str, params: Mapping[str, Param],
                   given: Mapping[str, float] | None) -> dict[str, float]:
    """Parameter values of ``effect``: ``params`` defaults overridden by ``given``.

    Unknown names (with a did-you-mean) and out-of-range values raise :class:`ConfigError`.
    """
    given = dict(given or {})
    unknown = set(given) - set(params)
    if unknown:
        bad = sorted(unknown)[0]
        close = difflib.get_close_matches(bad, list(params), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise ConfigError(f"effect '{effect}' has no parameter '{bad}'{hint}",
                          key=f"effects.{effect}.{bad}", allowed=", ".join(params) or "none")
    return {k: spec.check(effect, k, given.get(k, spec.default)) for k, spec in params.items()}


_REGISTRY: dict[str, Effect] = {}


def register_effect(name: str, *, params: Mapping[str, Param] | None = None,
                    replace: bool = False):
    """Decorator registering ``fn(o, s, p) -> (fx, fy, fz)`` as effect ``name``."""

    def deco(fn: ForceFn) -> ForceFn:
        if name in _REGISTRY and not replace:
            raise ConfigError(f"effect '{name}' is already registered (pass replace=True)")
        _REGISTRY[name] = Effect(name, fn, dict(params or {}), (fn.__doc__ or "").strip())
        return fn

    return deco


def get_effect(name: str) -> Effect:
    """The registered effect ``name``; unknown names get a did-you-mean."""
    try:
        return _REGISTRY[name]
    except KeyError:
        close = difflib.get_close_matches(name, list(_REGISTRY), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise ConfigError(f"unknown effect '{name}'{hint}", key="effects", value=name,
                          allowed=", ".join(sorted(_REGISTRY))) from None


def registered_effects() -> dict[str, Effect]:
    return dict(_REGISTRY)


def load_effect_file(path: str) -> list[str]:
    """Import a user Python file that registers effects; returns the names it added."""
    import importlib.util
    from pathlib import Path

    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"effect file not found: {p}", key="effects", value=str(p))
    before = set(_REGISTRY)
    spec = importlib.util.spec_from_file_location(f"granular_mpc_user_{p.stem}", p)
    module = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(module)
    return sorted(set(_REGISTRY) - before)


# ---------------------------------------------------------------------------- built-ins

@register_effect("inertial_drag", params={
    "c_d": Param(1.0, 0.0, 20.0, "-", "drag coefficient of the submerged sole"),
})
def inertial_drag(o, s: PatchState, p):
    """Inertial (velocity-squared) drag of the grains the sole sets in motion.

    F = −½ c_d ρ A_h |v| v while in contact (Katsuragi & Durian, Nature Physics 2007: the
    v² term of granular impact drag). A_h: horizontal area of the submerged sole.
    """
    vx, vy, vz = s.v_c
    speed = o.sqrt(vx * vx + vy * vy + vz * vz + 1e-12)
    k = -0.5 * p["c_d"] * s.density * s.area_h * speed * s.in_contact
    return (k * vx, k * vy, k * vz)


__all__ = ["Param", "PatchState", "Effect", "register_effect", "resolve_params", "get_effect",
           "registered_effects", "load_effect_file", "inertial_drag"]

# the effects library (cohesion, depth hardening, … and the joint / sensor / geometry kinds)
from . import effects_library  # noqa: E402,F401  (registers the library effects)
