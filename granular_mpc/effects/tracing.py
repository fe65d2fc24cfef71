"""Trace a terrain-force effect symbolically, with one clear error when it cannot be.

A terrain force ``fn(o, s, p)`` is not called once per contact state: it is called once,
on CasADi symbols, when the terrain's contact law is compiled (``o`` is the CasADi
namespace, every field of the :class:`~.state.PatchState` an expression). Python control
flow on those expressions (``if s.foot < 0.5:``, ``and``/``or``, ``min``/``max``) cannot
decide anything then; CasADi stops with "Cannot compute the truth value of a CasADi SXElem
symbolic expression", which names neither the effect nor its file. :func:`trace_terrain_force`
turns that into an :class:`~granular_mpc.exceptions.EffectError` naming both and the fix,
turns CasADi's long notice about a NumPy function called on a symbol (``np.maximum``: it
works) into one short warning naming the effect, and refuses a force that came out as a
plain NaN (``math.sqrt`` / ``float()`` of a symbol give NaN without an error).
"""

from __future__ import annotations

import inspect
import math
import warnings
from typing import Any, Callable, Mapping

from ..exceptions import EffectError
from .registry import EffectInfo
from .state import PatchState

#: the fix, as every message below states it
SYMBOLIC_ADVICE = ("use o.if_else(cond, a, b) (and o.fmax / o.fmin, or multiply by 0/1 "
                   "indicators such as s.is_left, s.in_contact) instead of Python "
                   "if/and/or/min/max on the patch state — the force is traced symbolically "
                   "(once, on CasADi expressions), not called per contact state")
#: what CasADi says when Python asks for the truth value of an expression
_TRUTH_VALUE = "truth value"
#: the start of CasADi's notice about a NumPy function called on a CasADi value
_NUMPY_NOTICE = "a numpy function was called on a casadi value"
#: effects already warned about NumPy calls (one warning per effect and process)
_WARNED_NUMPY: set[str] = set()


def effect_source(fn: Callable) -> str:
    """The file defining ``fn`` (through ``__wrapped__`` wrappers), or ``""`` if unknown."""
    try:
        return inspect.getsourcefile(inspect.unwrap(fn)) or ""
    except (TypeError, ValueError):
        return ""


def trace_terrain_force(info: EffectInfo, o: Any, s: PatchState,
                        p: Mapping[str, Any]) -> Any:
    """``info.force(o, s, p)`` on symbolic values, with a clear error if it cannot trace.

    Args:
        info: a registered terrain-force effect.
        o: the CasADi operations namespace (``o.if_else``, ``o.fmax`` …).
        s: the patch state, fields CasADi expressions (world frame, SI units).
        p: the effect's parameters by name (expressions or floats).

    Returns:
        What ``info.force`` returned: the force ``(fx, fy, fz)`` on the foot [N], world
        frame, as expressions.

    Raises:
        EffectError: the function uses Python control flow on the patch state, or returns
            a plain NaN (``math``/``float`` of a symbol).
    """
    source = effect_source(info.force)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            force = info.force(o, s, p)
        except RuntimeError as exc:
            if _TRUTH_VALUE not in str(exc):
                raise
            raise EffectError(f"terrain force {info.name!r} uses Python control flow on "
                              f"the symbolic patch state: {SYMBOLIC_ADVICE} (CasADi: {exc})",
                              effect=info.name, source=source) from None
    for w in caught:
        if issubclass(w.category, FutureWarning) and _NUMPY_NOTICE in str(w.message):
            if info.name in _WARNED_NUMPY:
                continue
            _WARNED_NUMPY.add(info.name)
            where = f" ({source})" if source else ""
            warnings.warn(f"terrain force {info.name!r}{where} calls a NumPy function on the "
                          "symbolic patch state; it traces, but write the o namespace instead "
                          "(np.maximum → o.fmax, np.minimum → o.fmin, np.where → o.if_else)",
                          UserWarning, stacklevel=2)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    try:
        parts = [force[i] for i in range(3)]
    except (TypeError, IndexError, KeyError):
        parts = []
    if any(isinstance(c, float) and math.isnan(c) for c in parts):
        raise EffectError(f"terrain force {info.name!r} returned NaN when traced: math.* or "
                          "float() of a symbol gives NaN, not an expression; use o.sqrt, "
                          f"o.exp … and {SYMBOLIC_ADVICE}", effect=info.name, source=source)
    return force


__all__ = ["SYMBOLIC_ADVICE", "effect_source", "trace_terrain_force"]
