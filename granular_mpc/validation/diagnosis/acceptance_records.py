"""The records of honest acceptance (:mod:`.acceptance`) and the per-channel error change
they share with the rest of the diagnosis (``diagnosis.json`` → ``acceptance``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

from .records import OMIT_EMPTY, Record


@dataclass(frozen=True)
class ChannelChange(Record):
    """One channel's error before and after the added effects (channel units)."""

    before: float
    after: float
    reduction: float
    unit: str


@dataclass(frozen=True)
class CoefficientCheck(Record):
    """One fitted parameter against its range: ``status`` is ``ok``, ``at_bound``,
    ``outside_physical_range`` or ``wrong_sign``; ``text`` says it in words."""

    param: str
    value: float
    status: str
    text: str


@dataclass(frozen=True)
class Acceptance(Record):
    """Whether a refined candidate was added, and why (not).

    Attributes:
        effect: the candidate.
        accepted: it was added.
        credited_channels: replay RMSE of its credited channels before (model without it)
            and after (with it), channel units.
        coefficients: the checks of its fitted parameters.
        reasons: why it was not added (empty when accepted).
        notes: flags that did not block it (a secondary parameter at a bound …).
    """

    effect: str
    accepted: bool
    credited_channels: Mapping[str, ChannelChange]
    coefficients: tuple[CoefficientCheck, ...]
    reasons: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)
    notes: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)


__all__ = ["ChannelChange", "CoefficientCheck", "Acceptance"]
