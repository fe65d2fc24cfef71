"""The one registry of effects, keyed by name, each entry typed by its kind.

An *effect* is a small, parameterised physical term that a model may be missing. Its
**kind** says where it acts and therefore how it is injected:

==================  ================================================================
kind                acts on … / injected as …
==================  ================================================================
``terrain_force``   the foot–terrain force: ``fn(o, s: PatchState, p) -> (fx, fy, fz)``
                    [N] in W, compiled into the plant's CasADi contact function
``joint``           the joints: ``fn(q_a, dq_a, p) -> tau_a`` [N·m] (actuator order),
                    added to the actuator torques inside ``Plant.forward``; the
                    measured torque stays the commanded one
``sensor``          the measurement only: ``fn(cols, p, ctx) -> {column: values}``
                    replaces columns of a trial (format v1 names) after the plant ran
``geometry``        the terrain geometry: ``fn(p) -> {theta_name: value}`` sets terrain
                    parameters of the plant (``surface_height``, ``surface_slope_x`` …)
==================  ================================================================

Every registered effect is one frozen :class:`EffectInfo` (name, kind, parameter specs,
callable, docstring, diagnosis metadata), stored in one table. Register through the
decorators of :mod:`granular_mpc.effects.api`; look up with :func:`effect_info` (any kind),
:func:`get_effect` (terrain forces only, what a terrain model compiles), list with
:func:`all_effects` / :func:`registered_effects`.

Diagnosis metadata: the **main coefficient** (the magnitude a diagnosis reports; default
the first parameter), the **neutral** values that switch the effect off (default: main at
0, or at the bound nearest 0), ``depends_on`` (what the term scales with, in words: used to
propose the experiment that separates two candidates) and free ``tags`` (families such as
a measurement model, variants such as per-foot terms). Lookups return the entry with these
defaults filled in.

Names are used in ``NAME:k=v,…`` strings, as parameter prefixes (``NAME.param``) and in
file names, so a name must be non-empty and free of whitespace and of ``/ : = ,``.

A new kind is one entry in :data:`EffectKind`/:data:`KINDS`, one decorator in
:mod:`.api` and one file holding its library and the function that applies it; what the
callables read (:class:`~granular_mpc.effects.state.PatchState`, ``SensorContext``) grows
by fields with defaults, so that effects written before keep working.
"""

from __future__ import annotations

import difflib
import itertools
from dataclasses import dataclass, field, replace
from typing import Callable, Literal, Mapping, Sequence

from ..exceptions import ConfigError
from .params import Param, resolve_params

EffectKind = Literal["terrain_force", "joint", "sensor", "geometry"]
#: every kind, in the order the library lists them
KINDS: tuple[EffectKind, ...] = ("terrain_force", "joint", "sensor", "geometry")
#: characters a name may not contain (besides whitespace)
FORBIDDEN_NAME_CHARS = "/:=,"
#: the allowed form of effect and parameter names, as error messages state it
NAME_FORM = "a non-empty name without whitespace or any of / : = , (e.g. 'sole_adhesion')"


@dataclass(frozen=True)
class EffectInfo:
    """One registered effect of any kind.

    Attributes:
        name: registered name.
        kind: ``terrain_force``, ``joint``, ``sensor`` or ``geometry``.
        params: parameter specs (default, bounds, unit, meaning) by name.
        fn: the function (signature depends on ``kind``, see the module docstring).
        doc: the function's docstring.
        main: name of the main coefficient (the reported magnitude).
        neutral: parameter values that switch the effect off.
        depends_on: what the term scales with, in words (e.g. ``"sole speed²"``).
        tags: free labels grouping effects (a family, a variant).
        inverse: a sensor effect's inverse ``inverse(cols, p, ctx) -> {column: true values}``
            on the columns it changes (None: solved numerically,
            :func:`~granular_mpc.effects.sensor.invert_sensor_effects`).
    """

    name: str
    kind: str
    params: Mapping[str, Param]
    fn: Callable
    doc: str = ""
    main: str = ""
    neutral: Mapping[str, float] = field(default_factory=dict)
    depends_on: tuple[str, ...] = ()
    tags: tuple[str, ...] = ()
    inverse: Callable | None = None

    def resolve_params(self, given: Mapping[str, float] | None = None) -> dict[str, float]:
        """Defaults overridden by ``given``; unknown names and out-of-range values rejected."""
        return resolve_params(self.name, self.params, given)

    def neutral_params(self) -> dict[str, float]:
        """Parameters with the effect switched off (shape parameters at their defaults)."""
        out = {k: spec.default for k, spec in self.params.items()}
        out.update(self.neutral)
        return out

    @property
    def force(self) -> Callable:
        """The force function ``fn(o, s, p) -> (fx, fy, fz)`` of a terrain-force effect
        (the name terrain models use; same object as :attr:`fn`)."""
        return self.fn

    @property
    def summary(self) -> str:
        """First paragraph of :attr:`doc`, on one line."""
        return self.doc.split("\n\n")[0].replace("\n", " ").strip()


#: the former name of a terrain-force entry (``granular_mpc.terrain.effects.Effect``)
Effect = EffectInfo

_ENTRIES: dict[str, EffectInfo] = {}      # as declared (metadata defaults not filled in)
_REGISTRATIONS: dict[str, int] = {}        # name → serial number of its latest register()
_SERIAL = itertools.count(1)


def check_name(name: str, what: str = "effect") -> str:
    """``name`` if it is a valid effect (or parameter) name.

    Raises:
        ConfigError: empty, or containing whitespace or one of ``/ : = ,``; the error
            names the allowed form.
    """
    bad = (not isinstance(name, str) or not name or any(c.isspace() for c in name)
           or any(c in FORBIDDEN_NAME_CHARS for c in name))
    if bad:
        raise ConfigError(f"invalid {what} name {name!r}: use {NAME_FORM}", key="effects",
                          value=name, allowed=NAME_FORM)
    return name


def _default_neutral(params: Mapping[str, Param], main: str) -> dict[str, float]:
    if not main:
        return {}
    spec = params[main]
    if spec.lower <= 0.0 <= spec.upper:
        return {main: 0.0}
    return {main: spec.lower if abs(spec.lower) < abs(spec.upper) else spec.upper}


def _check_metadata(entry: EffectInfo) -> None:
    if entry.main and entry.main not in entry.params:
        raise ConfigError(f"effect '{entry.name}': main coefficient '{entry.main}' is not one "
                          "of its parameters", key=f"effects.{entry.name}", value=entry.main,
                          allowed=", ".join(entry.params) or "none")
    extra = sorted(set(entry.neutral) - set(entry.params))
    if extra:
        raise ConfigError(f"effect '{entry.name}': neutral value for unknown parameter "
                          f"'{extra[0]}'", key=f"effects.{entry.name}", value=extra[0],
                          allowed=", ".join(entry.params) or "none")


def register(entry: EffectInfo, *, replace_existing: bool = False) -> EffectInfo:
    """Add ``entry`` to the registry (the decorators of :mod:`.api` call this).

    Args:
        entry: the effect as declared (``main``/``neutral`` may be left empty: defaults).
        replace_existing: replace an effect of the same name (of any kind).

    Returns:
        ``entry``.

    Raises:
        ConfigError: an invalid name or parameter name, an unknown kind, a ``main`` or
            ``neutral`` naming no parameter, or a name already registered.
    """
    check_name(entry.name)
    for p in entry.params:
        check_name(p, what=f"parameter (of effect '{entry.name}')")
    if entry.kind not in KINDS:
        raise ConfigError(f"effect '{entry.name}': unknown kind {entry.kind!r}",
                          key=f"effects.{entry.name}", value=entry.kind, allowed=", ".join(KINDS))
    _check_metadata(entry)
    if entry.name in _ENTRIES and not replace_existing:
        raise ConfigError(f"effect '{entry.name}' is already registered (pass replace=True)")
    _ENTRIES[entry.name] = entry
    _REGISTRATIONS[entry.name] = next(_SERIAL)
    return entry


def describe_effect(name: str, *, main: str | None = None,
                    neutral: Mapping[str, float] | None = None,
                    depends_on: Sequence[str] = (), tags: Sequence[str] = ()) -> None:
    """Attach diagnosis metadata to a registered effect (of any kind).

    Args:
        name: the effect.
        main: its main coefficient (default: the first parameter).
        neutral: parameter values that switch it off (default: main = 0).
        depends_on: what it scales with, in words.
        tags: labels grouping it with others (a family, a variant).

    Raises:
        ConfigError: unknown effect, or ``main``/``neutral`` naming no parameter.
    """
    entry = _declared(name)
    changes: dict = {}
    if main is not None:
        changes["main"] = main
    if neutral is not None:
        changes["neutral"] = dict(neutral)
    if depends_on:
        changes["depends_on"] = tuple(depends_on)
    if tags:
        changes["tags"] = tuple(tags)
    new = replace(entry, **changes)
    _check_metadata(new)
    _ENTRIES[name] = new


def _unknown(name: str, known: Sequence[str], what: str = "effect") -> ConfigError:
    close = difflib.get_close_matches(name, list(known), n=1)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    return ConfigError(f"unknown {what} '{name}'{hint}", key="effects", value=name,
                       allowed=", ".join(sorted(known)))


def _declared(name: str) -> EffectInfo:
    try:
        return _ENTRIES[name]
    except KeyError:
        raise _unknown(name, list(_ENTRIES)) from None


def _resolved(entry: EffectInfo) -> EffectInfo:
    main = entry.main or (next(iter(entry.params)) if entry.params else "")
    neutral = _default_neutral(entry.params, main)
    neutral.update(entry.neutral)
    return replace(entry, main=main, neutral=neutral)


def effect_info(name: str) -> EffectInfo:
    """The :class:`EffectInfo` of any registered effect, metadata defaults filled in.

    Raises:
        ConfigError: unknown name (with a did-you-mean and the registered names).
    """
    return _resolved(_declared(name))


def get_effect(name: str) -> EffectInfo:
    """The registered *terrain-force* effect ``name`` (what a terrain model compiles).

    Raises:
        ConfigError: unknown name (with a did-you-mean among the terrain forces), or an
            effect of another kind.
    """
    terrain = [n for n, e in _ENTRIES.items() if e.kind == "terrain_force"]
    if name in _ENTRIES and name not in terrain:
        raise ConfigError(f"effect '{name}' is a {_ENTRIES[name].kind} effect, not a terrain "
                          "force", key="effects", value=name, allowed=", ".join(sorted(terrain)))
    if name not in terrain:
        raise _unknown(name, terrain)
    return effect_info(name)


def effect_kind(name: str) -> str:
    """``terrain_force``, ``joint``, ``sensor`` or ``geometry``."""
    return _declared(name).kind


def all_effects(kinds: Sequence[str] = KINDS) -> dict[str, EffectInfo]:
    """Every registered effect of ``kinds`` (all by default), by name, sorted by name."""
    return {n: effect_info(n) for n in sorted(_ENTRIES) if _ENTRIES[n].kind in kinds}


def registered_effects(kinds: Sequence[str] = ("terrain_force",)) -> dict[str, EffectInfo]:
    """The registered effects of ``kinds`` in registration order.

    The default, terrain forces only, is what this function always listed (the effects a
    terrain config's ``effects:`` may name); pass ``kinds=KINDS`` for every kind.
    """
    return {n: effect_info(n) for n, e in _ENTRIES.items() if e.kind in kinds}


def registered_names() -> tuple[str, ...]:
    """Names of every registered effect (all kinds), in registration order."""
    return tuple(_ENTRIES)


def registrations() -> dict[str, int]:
    """Name → serial number of its latest registration (a re-registration with
    ``replace=True`` gets a new one): which names a piece of code (re)registered is what
    changed between two calls."""
    return dict(_REGISTRATIONS)


__all__ = ["EffectKind", "KINDS", "FORBIDDEN_NAME_CHARS", "NAME_FORM", "EffectInfo", "Effect",
           "check_name", "register", "describe_effect", "effect_info", "get_effect",
           "effect_kind", "all_effects", "registered_effects", "registered_names",
           "registrations"]
