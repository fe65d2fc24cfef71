"""The ranking's records: one candidate's screening statistics and its final entry.

:class:`CandidateStats` is what the screening (:mod:`.screen`) computes for a candidate
against a model; :class:`Ranked` adds what the selection (:mod:`.refine`) decided. Both
are the entries of ``diagnosis.json`` → ``ranking`` (same keys); :class:`ForceStart`, those of
``force_starts`` (where the replays start a user's or proposed term).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

from .records import OMIT_EMPTY, OMIT_NONE, Record


@dataclass(frozen=True)
class ParamEstimate(Record):
    """A candidate parameter fitted by the linear screening (parameter units).

    Attributes:
        value: fitted value; se: its standard error (None: not estimable).
        ci_lo, ci_hi: value ± 1.96 se.
        unit, neutral, lower, upper: the parameter's unit, the value that switches the
            effect off, and its bounds.
        at_bound: the fit sits on a bound.
        boot_ci_lo, boot_ci_hi: 2.5 / 97.5 percentiles over the trial bootstrap (None
            without bootstrap).
    """

    value: float
    se: float | None
    ci_lo: float | None
    ci_hi: float | None
    unit: str
    neutral: float
    lower: float
    upper: float
    at_bound: bool
    boot_ci_lo: float | None = field(default=None, metadata=OMIT_NONE)
    boot_ci_hi: float | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class CandidateStats(Record):
    """Screening statistics of one candidate against a model (``docs/validation.md`` §3.3).

    Attributes:
        effect, kind: the candidate effect and its kind.
        heldout_error_reduction: 1 − SSE_CV(model + candidate) / SSE_CV(model),
            systematic rows; ``_stance``: the same fits scored on held-out stance rows.
        delta_aicc: AICc(with) − AICc(without).
        folds_improved: ``"k/K"`` folds whose held-out SSE fell.
        effect_size: largest change of a channel × phase mean, in σ_c.
        params: fitted parameters by name.
        main, depends_on, doc: the effect's main parameter, what it depends on, summary.
        inclusion_probability: share of bootstrap forward selections picking it (None:
            no bootstrap).
        significant: it passes every test.
        rank: 1-based, by held-out error reduction.
        inclusion_shared_with: candidates that passed every other test and split the
            bootstrap selections with it (together at least MIN_INCLUSION): the data
            cannot tell them apart (:func:`~.screen.inclusion_ties`).
    """

    effect: str
    kind: str
    heldout_error_reduction: float
    heldout_error_reduction_stance: float
    delta_aicc: float
    folds_improved: str
    effect_size: float
    params: Mapping[str, ParamEstimate]
    main: str
    depends_on: tuple[str, ...]
    doc: str
    inclusion_probability: float | None
    significant: bool
    rank: int
    inclusion_shared_with: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)


@dataclass(frozen=True)
class RefinedFit(Record):
    """One Gauss–Newton replay refinement of a contender, given the effects already added."""

    given: tuple[str, ...]
    aicc: float
    weighted_rss: float
    params: Mapping[str, float]


@dataclass(frozen=True)
class ConditionalResult(Record):
    """A candidate re-tested on the residual of the refined model with ``given`` added."""

    given: tuple[str, ...]
    heldout_error_reduction: float
    significant: bool


@dataclass(frozen=True)
class Ranked(CandidateStats):
    """A candidate's final ranking entry: its first screening plus the selection's outcome.

    Attributes:
        rank: final rank (the added effects first, in the order they were added).
        refined_fits: replay refinements as a contender.
        conditional: conditional re-tests after each addition.
        added: the effect was added to the model.
        linear_rank: rank of the first (linear) screening.
        refined_params: its refined parameter values when added.
        not_added_because: why a refined contender was reported, not added (honest
            acceptance, :mod:`.acceptance`).
    """

    refined_fits: tuple[RefinedFit, ...] = field(default=(), metadata=OMIT_EMPTY)
    conditional: tuple[ConditionalResult, ...] = field(default=(), metadata=OMIT_EMPTY)
    added: bool = False
    linear_rank: int = 0
    refined_params: Mapping[str, float] | None = field(default=None, metadata=OMIT_NONE)
    not_added_because: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)

    def dominant_param(self) -> str:
        """The fitted parameter furthest from its neutral value (relative to its range;
        refined values where there are)."""
        fit = self.refined_params or {}

        def dist(p: str) -> float:
            v = self.params[p]
            val = fit.get(p, v.value)
            return abs(val - v.neutral) / max(v.upper - v.lower, 1e-12)

        return max(self.params, key=dist) if self.params else self.main

    def value_of(self, param: str) -> float | None:
        """Refined value of ``param`` if added, else its screening value."""
        fit = self.refined_params or {}
        if param in fit:
            return fit[param]
        est = self.params.get(param)
        return None if est is None else est.value


@dataclass(frozen=True)
class ForceStart(Record):
    """A term's fit on the foot-force equation error, with ζ (:mod:`.force_start`): where
    the replays start it.

    Attributes:
        effect: the candidate; param: its main parameter.
        value: the fitted value of ``param`` (the others at their defaults).
        zeta: ζ fitted beside it on the vertical axis (its value there), within its bounds.
        axis: the axis fitted (``z`` vertical, ``h`` forward).
        rms_before, rms_after: RMS [N] of the equation error with ζ alone and with the term.
        heldout_reduction: trial-grouped held-out reduction of the equation error.
        passes: whether it meets the evidence rule (then the replays start from it).
        n_samples: sinking samples.
    """

    effect: str
    param: str
    value: float
    zeta: float
    axis: str
    rms_before: float
    rms_after: float
    heldout_reduction: float
    passes: bool
    n_samples: int

    @property
    def explained(self) -> float:
        """The force the term explains beyond ζ, √(RMS_before² − RMS_after²) [N]."""
        return math.sqrt(max(self.rms_before ** 2 - self.rms_after ** 2, 0.0))


__all__ = ["ParamEstimate", "CandidateStats", "RefinedFit", "ConditionalResult", "Ranked",
           "ForceStart"]
