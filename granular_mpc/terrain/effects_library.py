"""The effects library: physically named candidate effects of four kinds, and their taxonomy.

An *effect* is a small, parameterised physical term that a model may be missing. The
validation workbench injects effects into synthetic data (``granular-mpc synth --effect``),
adds them to a replayed model (``granular-mpc validate --effect``) and tests them as
candidates (``granular-mpc diagnose``). Every effect has a **kind**, which says where it
acts and therefore how it is injected:

==================  ================================================================
kind                acts on … / injected as …
==================  ================================================================
``terrain_force``   the foot–terrain force: ``fn(o, s: PatchState, p) -> (fx, fy, fz)``
                    [N], compiled into the plant's CasADi contact function (registry of
                    :mod:`granular_mpc.terrain.effects`, ``register_effect``)
``joint``           the joints: ``fn(q_a, dq_a, p) -> tau_a`` [N·m] (actuator order),
                    added to the actuator torques inside ``Plant.forward`` (the plant's
                    joint-effect hook); the measured torque stays the commanded one
``sensor``          the measurement only: ``fn(cols, p, ctx) -> {column: values}`` replaces
                    columns of a trial (format v1 names) after the plant has run
``geometry``        the terrain geometry: ``fn(p) -> {theta_name: value}`` sets terrain
                    parameters of the plant (``surface_height``, ``surface_slope_x`` …)
==================  ================================================================

Register terrain-force effects with :func:`granular_mpc.terrain.effects.register_effect`
(they are ``terrain_force`` automatically) and the others with
:func:`register_joint_effect`, :func:`register_sensor_effect` or
:func:`register_geometry_effect`. :func:`effect_info` returns one :class:`EffectInfo` for
any registered name, whatever its kind, so that ``synth``, ``validate`` and ``diagnose``
dispatch by kind and user effects plug in like the built-in ones.

Each effect also names its **main coefficient** (the magnitude the diagnosis reports) and
the **neutral** parameter values that switch it off (the baseline of a sensitivity); by
default the main coefficient is the first parameter and it is neutral at 0 (or at the
bound nearest to 0). ``depends_on`` lists, in words, what the term scales with (used to
propose the experiment that separates two candidates the data cannot tell apart).

Built in (defaults are the magnitudes a YoboGo-10S-class robot on sand would notice):

* ``inertial_drag`` (terrain_force, in :mod:`.effects`): −½ c_d ρ A_h |v| v;
* ``cohesion`` (terrain_force): suction of wet sand resisting pull-out;
* ``depth_hardening`` (terrain_force): stress ∝ depthⁿ instead of depth¹;
* ``elastic_unloading`` (terrain_force): compacted sand pushing a rising sole back;
* ``joint_friction`` (joint): viscous + Coulomb joint friction;
* ``force_sensor_bias`` (sensor): constant offset of the foot force sensor;
* ``terrain_slope`` (geometry): the free surface z = h + s_x x + s_y y.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from typing import Any, Callable, Literal, Mapping, Sequence

import numpy as np

from ..exceptions import ConfigError
from .effects import _REGISTRY as _TERRAIN_REGISTRY
from .effects import Param, PatchState, register_effect, resolve_params

EffectKind = Literal["terrain_force", "joint", "sensor", "geometry"]
KINDS: tuple[str, ...] = ("terrain_force", "joint", "sensor", "geometry")

#: θ names a geometry effect may set (terrain parameters of the compiled contact function)
GEOMETRY_THETA = ("surface_height", "surface_slope_x", "surface_slope_y", "layer_depth")


@dataclass(frozen=True)
class EffectInfo:
    """One registered effect of any kind.

    Attributes:
        name: registered name.
        kind: ``terrain_force``, ``joint``, ``sensor`` or ``geometry``.
        params: parameter specs (default, bounds, unit, meaning).
        fn: the function (signature depends on ``kind``, see the module docstring).
        doc: first paragraph of the function's docstring.
        main: name of the main coefficient (the reported magnitude).
        neutral: parameter values that switch the effect off.
        depends_on: what the term scales with, in words (e.g. ``"sole speed²"``).
    """

    name: str
    kind: str
    params: Mapping[str, Param]
    fn: Callable
    doc: str = ""
    main: str = ""
    neutral: Mapping[str, float] = field(default_factory=dict)
    depends_on: tuple[str, ...] = ()

    def resolve_params(self, given: Mapping[str, float] | None = None) -> dict[str, float]:
        """Defaults overridden by ``given``; unknown names and out-of-range values rejected."""
        return resolve_params(self.name, self.params, given)

    def neutral_params(self) -> dict[str, float]:
        """Parameters with the effect switched off (shape parameters at their defaults)."""
        out = {k: spec.default for k, spec in self.params.items()}
        out.update(self.neutral)
        return out

    @property
    def summary(self) -> str:
        return self.doc.split("\n\n")[0].replace("\n", " ").strip()


# ----------------------------------------------------------------------------- registry
_OTHER: dict[str, EffectInfo] = {}          # joint, sensor and geometry effects
_META: dict[str, dict[str, Any]] = {}        # main / neutral / depends_on per name


def _default_neutral(params: Mapping[str, Param], main: str) -> dict[str, float]:
    if not main:
        return {}
    spec = params[main]
    if spec.lower <= 0.0 <= spec.upper:
        return {main: 0.0}
    return {main: spec.lower if abs(spec.lower) < abs(spec.upper) else spec.upper}


def describe_effect(name: str, *, main: str | None = None,
                    neutral: Mapping[str, float] | None = None,
                    depends_on: Sequence[str] = ()) -> None:
    """Attach diagnosis metadata to a registered effect (of any kind).

    Args:
        name: the effect.
        main: its main coefficient (default: the first parameter).
        neutral: parameter values that switch it off (default: main = 0).
        depends_on: what it scales with, in words.
    """
    meta = _META.setdefault(name, {})
    if main is not None:
        meta["main"] = main
    if neutral is not None:
        meta["neutral"] = dict(neutral)
    if depends_on:
        meta["depends_on"] = tuple(depends_on)


def _register_other(kind: str, name: str, params: Mapping[str, Param] | None, replace: bool,
                    main: str | None, neutral: Mapping[str, float] | None,
                    depends_on: Sequence[str]):
    def deco(fn: Callable) -> Callable:
        if not replace and (name in _OTHER or name in _TERRAIN_REGISTRY):
            raise ConfigError(f"effect '{name}' is already registered (pass replace=True)")
        if name in _TERRAIN_REGISTRY:
            del _TERRAIN_REGISTRY[name]
        _OTHER[name] = EffectInfo(name, kind, dict(params or {}), fn,
                                  (fn.__doc__ or "").strip())
        describe_effect(name, main=main, neutral=neutral, depends_on=depends_on)
        return fn

    return deco


def register_joint_effect(name: str, *, params: Mapping[str, Param] | None = None,
                          replace: bool = False, main: str | None = None,
                          neutral: Mapping[str, float] | None = None,
                          depends_on: Sequence[str] = ()):
    """Decorator registering ``fn(q_a, dq_a, p) -> tau_a`` [N·m] as a joint effect.

    ``q_a`` [rad], ``dq_a`` [rad/s] and the returned torque are NumPy arrays in actuator
    order; the torque is *added* to the actuator torques (friction returns a torque
    opposing ``dq_a``). It must be cheap: the plant calls it at every step.
    """
    return _register_other("joint", name, params, replace, main, neutral, depends_on)


def register_sensor_effect(name: str, *, params: Mapping[str, Param] | None = None,
                           replace: bool = False, main: str | None = None,
                           neutral: Mapping[str, float] | None = None,
                           depends_on: Sequence[str] = ()):
    """Decorator registering ``fn(cols, p, ctx) -> {column: values}`` as a sensor effect.

    ``cols`` maps format-v1 column names to NumPy arrays (one trial, or a replayed
    prediction of it); ``ctx`` is a :class:`SensorContext` (stance labels, time, joint
    names). Return the columns the sensor changes (new arrays; never modify ``cols``).
    """
    return _register_other("sensor", name, params, replace, main, neutral, depends_on)


def register_geometry_effect(name: str, *, params: Mapping[str, Param] | None = None,
                             replace: bool = False, main: str | None = None,
                             neutral: Mapping[str, float] | None = None,
                             depends_on: Sequence[str] = ()):
    """Decorator registering ``fn(p) -> {theta_name: value}`` as a geometry effect.

    The returned names are terrain parameters of the compiled contact function
    (:data:`GEOMETRY_THETA`); the plant's terrain uses these values.
    """
    return _register_other("geometry", name, params, replace, main, neutral, depends_on)


def effect_info(name: str) -> EffectInfo:
    """The :class:`EffectInfo` of any registered effect; unknown names get a did-you-mean."""
    meta = _META.get(name, {})
    if name in _TERRAIN_REGISTRY:
        eff = _TERRAIN_REGISTRY[name]
        base = EffectInfo(name, "terrain_force", dict(eff.params), eff.force, eff.doc)
    elif name in _OTHER:
        base = _OTHER[name]
    else:
        known = sorted(set(_TERRAIN_REGISTRY) | set(_OTHER))
        close = difflib.get_close_matches(name, known, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise ConfigError(f"unknown effect '{name}'{hint}", key="effects", value=name,
                          allowed=", ".join(known))
    main = meta.get("main") or (next(iter(base.params)) if base.params else "")
    neutral = dict(_default_neutral(base.params, main))
    neutral.update(meta.get("neutral", {}))
    return EffectInfo(base.name, base.kind, base.params, base.fn, base.doc, main, neutral,
                      tuple(meta.get("depends_on", ())))


def effect_kind(name: str) -> str:
    """``terrain_force``, ``joint``, ``sensor`` or ``geometry``."""
    return effect_info(name).kind


def all_effects(kinds: Sequence[str] = KINDS) -> dict[str, EffectInfo]:
    """Every registered effect (all kinds by default), by name."""
    names = sorted(set(_TERRAIN_REGISTRY) | set(_OTHER))
    out = {}
    for n in names:
        info = effect_info(n)
        if info.kind in kinds:
            out[n] = info
    return out


@dataclass(frozen=True)
class SensorContext:
    """What a sensor effect may read besides the columns.

    Attributes:
        stance: stance labels (``left`` / ``right`` / ``none``) per row.
        time: sample times [s].
        joint_names: actuated joints in actuator order.
    """

    stance: np.ndarray
    time: np.ndarray
    joint_names: tuple[str, ...]

    @property
    def in_stance(self) -> np.ndarray:
        """1.0 on rows with a stance foot (its force sensor is read), else 0.0."""
        return (np.asarray(self.stance).astype(str) != "none").astype(float)


def joint_torque_function(specs: Sequence[tuple[EffectInfo, Mapping[str, float]]]
                          ) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
    """One callable ``(q_a, dq_a) -> tau_a`` summing the joint effects ``specs``
    (``None`` if there are none): what :class:`~granular_mpc.dynamics.Plant` takes."""
    items = [(info.fn, dict(p)) for info, p in specs if info.kind == "joint"]
    if not items:
        return None

    def tau(q_a: np.ndarray, dq_a: np.ndarray) -> np.ndarray:
        out = np.zeros_like(dq_a)
        for fn, p in items:
            out = out + np.asarray(fn(q_a, dq_a, p), dtype=float)
        return out

    return tau


def apply_sensor_effects(cols: Mapping[str, np.ndarray],
                         specs: Sequence[tuple[EffectInfo, Mapping[str, float]]],
                         ctx: SensorContext) -> dict[str, np.ndarray]:
    """The columns after the sensor effects ``specs`` (in order); others unchanged."""
    out = dict(cols)
    for info, p in specs:
        if info.kind != "sensor":
            continue
        changed = info.fn(out, dict(p), ctx)
        for k, v in changed.items():
            out[k] = np.asarray(v, dtype=float)
    return out


def geometry_theta(specs: Sequence[tuple[EffectInfo, Mapping[str, float]]]) -> dict[str, float]:
    """Terrain parameters set by the geometry effects ``specs`` (later ones win)."""
    out: dict[str, float] = {}
    for info, p in specs:
        if info.kind != "geometry":
            continue
        vals = info.fn(dict(p))
        for k, v in vals.items():
            if k not in GEOMETRY_THETA:
                raise ConfigError(f"geometry effect '{info.name}' sets {k!r}, which is not a "
                                  "terrain geometry parameter", key=f"effects.{info.name}",
                                  allowed=", ".join(GEOMETRY_THETA))
            out[k] = float(v)
    return out


# ============================================================================ terrain force
@register_effect("cohesion", params={
    "suction": Param(3000.0, 0.0, 50000.0, "Pa",
                     "largest suction (pull-out) stress on the submerged sole area"),
    "release": Param(0.003, 0.0005, 0.05, "m",
                     "rise from the deepest point over which the suction builds up"),
})
def cohesion(o, s: PatchState, p):
    """Suction of wet (cohesive) sand resisting the pull-out of a buried sole.

    f_z = −σ_c A_h (1 − e^{−δ/δ_c}),  δ = depth_max − depth ≥ 0 (rise since the deepest
    point of this stance), A_h the submerged horizontal sole area. The capillary bridges
    hold the sole once it starts to rise; the pull grows over ``release`` δ_c and acts
    until the sole leaves the sand. Depends on displacement, not velocity, so it never
    chatters when the sole rests. Dry sand: σ_c = 0; wet sand: a few kPa.
    """
    rise = o.fmax(s.depth_max - s.depth, 0.0)
    k = -p["suction"] * s.area_h * (1.0 - o.exp(-rise / p["release"])) * s.in_contact
    return (0.0, 0.0, k)


@register_effect("depth_hardening", params={
    "n": Param(1.5, 0.3, 3.0, "-", "exponent of depth in the stress law (1: RFT, no effect)"),
    "d_ref": Param(0.02, 0.002, 0.1, "m", "depth at which the stress equals the RFT value"),
})
def depth_hardening(o, s: PatchState, p):
    """Stress ∝ depthⁿ instead of RFT's depth¹ (compaction: deeper sand is stiffer).

    The terrain force of the patch is scaled by (d/d_ref)^{n−1}: f = f_terrain ·
    ((d/d_ref)^{n−1} − 1), depth d clamped to [1 mm, 10 d_ref]. While the medium yields
    (penetration) this is the hardened capacity F_yield (d/d_ref)^{n−1}; while the sole
    rests it only rescales the elastic regularisation, so it never chatters. n = 1: off.
    """
    d = o.fmin(o.fmax(s.depth, 1e-3), 10.0 * p["d_ref"])
    factor = (d / p["d_ref"]) ** (p["n"] - 1.0) - 1.0
    k = factor * s.in_contact
    return (k * s.f_terrain[0], k * s.f_terrain[1], k * s.f_terrain[2])


@register_effect("elastic_unloading", params={
    "pressure": Param(4000.0, 0.0, 50000.0, "Pa",
                      "peak rebound pressure of the compacted sand on the submerged sole"),
    "recovery": Param(0.002, 0.0003, 0.02, "m", "rise at which the rebound peaks"),
})
def elastic_unloading(o, s: PatchState, p):
    """Compacted sand springing back under a sole that rises from its deepest point.

    f_z = p_r A_h (δ/δ_r) e^{1 − δ/δ_r},  δ = depth_max − depth ≥ 0: zero while the sole
    penetrates (δ = 0), the largest push-back p_r A_h at δ = δ_r, fading as the sole leaves
    the compacted zone. Depends on the rise, not on velocity.
    """
    rise = o.fmax(s.depth_max - s.depth, 0.0)
    x = rise / p["recovery"]
    k = p["pressure"] * s.area_h * x * o.exp(1.0 - x) * s.in_contact
    return (0.0, 0.0, k)


# ================================================================================= joint
@register_joint_effect("joint_friction", params={
    "viscous": Param(0.02, 0.0, 2.0, "N·m·s/rad", "viscous friction coefficient b"),
    "coulomb": Param(0.1, 0.0, 5.0, "N·m", "Coulomb friction torque τ_c"),
    "smoothing": Param(0.2, 0.01, 5.0, "rad/s", "velocity below which Coulomb friction is smoothed"),
}, main="coulomb", neutral={"viscous": 0.0, "coulomb": 0.0},
    depends_on=("joint velocity (sign and magnitude)",))
def joint_friction(q_a, dq_a, p):
    """Viscous + Coulomb friction in every actuated joint (gearbox, bearings).

    τ_f = −b q̇ − τ_c tanh(q̇ / ω_s), same for every joint; added to the motor torques, so
    the joints deliver less than the measured (current-based) torque.
    """
    return -p["viscous"] * dq_a - p["coulomb"] * np.tanh(dq_a / p["smoothing"])


# ================================================================================ sensor
@register_sensor_effect("force_sensor_bias", params={
    "bias_x": Param(0.0, -50.0, 50.0, "N", "offset of grf_x"),
    "bias_y": Param(0.0, -50.0, 50.0, "N", "offset of grf_y"),
    "bias_z": Param(6.0, -50.0, 50.0, "N", "offset of grf_z"),
}, main="bias_z", neutral={"bias_x": 0.0, "bias_y": 0.0, "bias_z": 0.0},
    depends_on=("nothing: constant on every stance sample",))
def force_sensor_bias(cols, p, ctx: SensorContext):
    """Constant offset of the foot force sensor (zero drift), world axes.

    grf_i ← grf_i + b_i on every row with a stance foot (rows without one stay 0).
    """
    on = ctx.in_stance
    return {f"grf_{ax}": np.asarray(cols[f"grf_{ax}"], dtype=float) + p[f"bias_{ax}"] * on
            for ax in "xyz"}


# ============================================================================== geometry
@register_geometry_effect("terrain_slope", params={
    "slope_x": Param(0.02, -0.3, 0.3, "-", "dz/dx of the free surface (uphill along +x > 0)"),
    "slope_y": Param(0.0, -0.3, 0.3, "-", "dz/dy of the free surface"),
}, main="slope_x", neutral={"slope_x": 0.0, "slope_y": 0.0},
    depends_on=("position of the footprint along the walk",))
def terrain_slope(p):
    """A sloped free surface z = h + s_x x + s_y y (an inclined sand bed)."""
    return {"surface_slope_x": p["slope_x"], "surface_slope_y": p["slope_y"]}


# ------------------------------------------------------------------------ metadata
describe_effect("inertial_drag", main="c_d", depends_on=("sole speed squared",))
describe_effect("cohesion", main="suction",
                depends_on=("rise of the sole from its deepest point (pull-out)",))
describe_effect("depth_hardening", main="n", neutral={"n": 1.0},
                depends_on=("depth (relative to d_ref)", "load during penetration"))
describe_effect("elastic_unloading", main="pressure",
                depends_on=("rise of the sole from its deepest point (unloading)",))

__all__ = ["EffectKind", "KINDS", "EffectInfo", "SensorContext", "GEOMETRY_THETA",
           "register_joint_effect", "register_sensor_effect", "register_geometry_effect",
           "describe_effect", "effect_info", "effect_kind", "all_effects",
           "joint_torque_function", "apply_sensor_effects", "geometry_theta",
           "cohesion", "depth_hardening", "elastic_unloading", "joint_friction",
           "force_sensor_bias", "terrain_slope"]
