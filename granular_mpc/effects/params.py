"""Effect parameters: default value, physical bounds, unit and meaning; resolving given values.

Every effect, whatever its kind, declares its parameters as :class:`Param` by name. Values
given in YAML (``"cohesion:suction=3000"``), on the command line or by the diagnosis are
resolved against these specs by :func:`resolve_params`: unknown names are refused with a
did-you-mean, out-of-range values with the allowed interval and its unit.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Mapping

from ..exceptions import ConfigError


@dataclass(frozen=True)
class Param:
    """One effect parameter.

    Attributes:
        default: value used when none is given [``unit``].
        lower: smallest physically allowed value [``unit``].
        upper: largest physically allowed value [``unit``].
        unit: SI unit, in words or symbols (``"Pa"``, ``"N·m·s/rad"``, ``"-"``).
        doc: what the parameter means.
        physical: the interval the effect's physics allows, when narrower than the bounds
            a fit may explore (e.g. a *hardening* exponent n ≥ 1 within [0.3, 3]); None:
            the bounds. A diagnosis reports a fitted value outside it as such ("wrong
            sign" when it lies on the other side of the neutral value) and does not
            present the effect as the answer.
    """

    default: float
    lower: float
    upper: float
    unit: str = ""
    doc: str = ""
    physical: tuple[float, float] | None = None

    @property
    def physical_range(self) -> tuple[float, float]:
        """:attr:`physical`, or the bounds when it is not set."""
        return self.physical if self.physical is not None else (self.lower, self.upper)

    def check(self, effect: str, name: str, value: float) -> float:
        """``value`` as a float if it lies in ``[lower, upper]``.

        Raises:
            ConfigError: out of range (key ``effects.<effect>.<name>``, the value, the
                allowed interval with its unit).
        """
        value = float(value)
        if not (self.lower <= value <= self.upper):
            raise ConfigError(f"effect '{effect}': parameter {name} = {value} is out of range",
                              key=f"effects.{effect}.{name}", value=value,
                              allowed=f"[{self.lower}, {self.upper}] {self.unit}".strip())
        return value


def resolve_params(effect: str, params: Mapping[str, Param],
                   given: Mapping[str, float] | None) -> dict[str, float]:
    """Parameter values of ``effect``: ``params`` defaults overridden by ``given``.

    Args:
        effect: the effect's name (for messages and error keys).
        params: its parameter specs by name.
        given: values to use instead of the defaults (may be ``None``).

    Returns:
        Every parameter's value, in the order of ``params``.

    Raises:
        ConfigError: an unknown name (with a did-you-mean) or an out-of-range value.
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


__all__ = ["Param", "resolve_params"]
