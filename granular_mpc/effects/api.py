"""The plugin API: what a user's effect file imports to add effects of any kind.

A terrain force, written once with the ``o`` math namespace (``o.sin``, ``o.sqrt``,
``o.fmax``, ``o.if_else`` …) so that the same source compiles into the plant's CasADi
contact function (fast, exact derivatives for calibration) and evaluates on floats::

    from granular_mpc.effects import Param, register_effect

    @register_effect("sole_adhesion", params={"f0": Param(2.0, 0.0, 50.0, "N", "pull-off force")})
    def sole_adhesion(o, s, p):
        '''Constant pull toward the sand while the sole is buried and rising.'''
        rising = o.if_else(s.v_c[2] > 0.0, 1.0, 0.0)
        return (0.0, 0.0, -p["f0"] * rising * s.in_contact)

The function receives ``s`` (:class:`PatchState`, world frame, SI units) and ``p`` (the
parameter values by name) and returns the world force on the patch (fx, fy, fz) [N].
Effects see the terrain's own forces in ``s`` but never change them: they add. The other
kinds: :func:`register_joint_effect`, :func:`register_sensor_effect`,
:func:`register_geometry_effect` (signatures in :mod:`.registry`). Pass the file to the
command line with ``--effect-file`` (:func:`load_effect_file`), or switch an effect on from
YAML (``effects: [{name: inertial_drag, params: {c_d: 1.2}}]`` in a terrain file, or
``"inertial_drag:c_d=1.2"``).

(``from granular_mpc.terrain.effects import Param, register_effect`` still works.)
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Callable, Mapping, Sequence

from ..exceptions import ConfigError
from .params import Param, resolve_params
from .registry import (KINDS, EffectInfo, EffectKind, all_effects, describe_effect, effect_info,
                       effect_kind, get_effect, register, registered_effects,
                       registrations)
from .state import PatchState, SensorContext


def _decorator(kind: str, name: str, params: Mapping[str, Param] | None, replace: bool,
               main: str | None, neutral: Mapping[str, float] | None,
               depends_on: Sequence[str], tags: Sequence[str],
               inverse: Callable | None = None) -> Callable[[Callable], Callable]:
    def deco(fn: Callable) -> Callable:
        register(EffectInfo(name, kind, dict(params or {}), fn, (fn.__doc__ or "").strip(),
                            main or "", dict(neutral or {}), tuple(depends_on), tuple(tags),
                            inverse),
                 replace_existing=replace)
        return fn

    return deco


def register_effect(name: str, *, params: Mapping[str, Param] | None = None,
                    replace: bool = False, main: str | None = None,
                    neutral: Mapping[str, float] | None = None,
                    depends_on: Sequence[str] = (), tags: Sequence[str] = ()):
    """Decorator registering ``fn(o, s, p) -> (fx, fy, fz)`` [N] as terrain-force ``name``.

    Args:
        name: the effect's name (no whitespace, no ``/ : = ,``).
        params: its parameters by name.
        replace: replace an effect already registered under ``name``.
        main: its main coefficient (default: the first parameter).
        neutral: parameter values that switch it off (default: main = 0).
        depends_on: what it scales with, in words.
        tags: labels grouping it with others.
    """
    return _decorator("terrain_force", name, params, replace, main, neutral, depends_on, tags)


def register_joint_effect(name: str, *, params: Mapping[str, Param] | None = None,
                          replace: bool = False, main: str | None = None,
                          neutral: Mapping[str, float] | None = None,
                          depends_on: Sequence[str] = (), tags: Sequence[str] = ()):
    """Decorator registering ``fn(q_a, dq_a, p) -> tau_a`` [N·m] as a joint effect.

    ``q_a`` [rad], ``dq_a`` [rad/s] and the returned torque are NumPy arrays in actuator
    order; the torque is *added* to the actuator torques (friction returns a torque
    opposing ``dq_a``). It must be cheap: the plant calls it at every step. Arguments as
    for :func:`register_effect`.
    """
    return _decorator("joint", name, params, replace, main, neutral, depends_on, tags)


def register_sensor_effect(name: str, *, params: Mapping[str, Param] | None = None,
                           replace: bool = False, main: str | None = None,
                           neutral: Mapping[str, float] | None = None,
                           depends_on: Sequence[str] = (), tags: Sequence[str] = (),
                           inverse: Callable | None = None):
    """Decorator registering ``fn(cols, p, ctx) -> {column: values}`` as a sensor effect.

    ``cols`` maps format-v1 column names to NumPy arrays (one trial, or a replayed
    prediction of it); ``ctx`` is a :class:`SensorContext` (stance labels, time, joint
    names). Return the columns the sensor changes (new arrays; never modify ``cols``).

    A replay inverts the map on the columns it is driven by (``tau_*``, the initial
    ``q_*``/``dq_*``). Without ``inverse`` that is solved sample by sample (Newton), which
    works for maps of each sample on its own (offsets, gains, any smooth function of the
    sample's columns); a map that *mixes samples* — a time shift of one sample or more, a
    filter — cannot be solved so, and needs ``inverse(cols, p, ctx) -> {column: true
    values}`` (same signature; the measured columns in, the true ones out). Other arguments
    as for :func:`register_effect`.
    """
    return _decorator("sensor", name, params, replace, main, neutral, depends_on, tags,
                      inverse)


def register_geometry_effect(name: str, *, params: Mapping[str, Param] | None = None,
                             replace: bool = False, main: str | None = None,
                             neutral: Mapping[str, float] | None = None,
                             depends_on: Sequence[str] = (), tags: Sequence[str] = ()):
    """Decorator registering ``fn(p) -> {theta_name: value}`` as a geometry effect.

    The returned names are terrain parameters of the compiled contact function
    (:data:`granular_mpc.effects.geometry.GEOMETRY_THETA`); the plant's terrain uses
    these values. Arguments as for :func:`register_effect`.
    """
    return _decorator("geometry", name, params, replace, main, neutral, depends_on, tags)


def load_effect_file(path: str) -> list[str]:
    """Import a user Python file that registers effects.

    Args:
        path: the ``.py`` file.

    Returns:
        The names it registered (effects of every kind), sorted — also those it registered
        again with ``replace=True`` (a file loaded twice returns its names both times).

    Raises:
        ConfigError: the file does not exist.
    """
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"effect file not found: {p}", key="effects", value=str(p))
    before = registrations()
    spec = importlib.util.spec_from_file_location(f"granular_mpc_user_{p.stem}", p)
    module = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(module)
    return sorted(n for n, k in registrations().items() if before.get(n) != k)


#: what a user's effect file may import (the decorators are defined here, the rest re-exported)
__all__ = ["Param", "PatchState", "SensorContext", "EffectInfo", "EffectKind", "KINDS",
           "register_effect", "register_joint_effect", "register_sensor_effect",
           "register_geometry_effect", "describe_effect", "load_effect_file", "effect_info",
           "effect_kind", "get_effect", "all_effects", "registered_effects", "resolve_params"]
