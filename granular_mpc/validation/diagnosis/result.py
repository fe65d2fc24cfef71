"""The typed diagnosis: what :func:`~granular_mpc.validation.diagnose.diagnose` returns,
``diagnosis.json`` written from it (:meth:`Diagnosis.to_json`) and read back into it
(:func:`load_diagnosis`). The file's keys are the records' field names
(``docs/validation.md`` §3.5).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

from ...output import json_safe
from ..calibrate import Calibration
from .acceptance_records import (Acceptance, ChannelChange, CoefficientCheck, ForceLeftover,
                                 LawPreferred, StrengthTwin)
from .localization_records import Localization
from .proposal_records import Proposal
from .ranking_records import ForceStart, Ranked
from .records import NOT_JSON, OMIT_EMPTY, OMIT_NONE, Record
from .thresholds import (LARGE_HELDOUT_REDUCTION, MAX_DELTA_AICC, MIN_EFFECT_SIZE,
                         MIN_HELDOUT_REDUCTION, MIN_INCLUSION, MIN_STANCE_REDUCTION,
                         PRACTICAL_BIAS, T_CELL)

DIAGNOSIS_FILE = "diagnosis.json"
REPORT_FILE = "report.md"


@dataclass(frozen=True)
class Thresholds(Record):
    """The decision thresholds a verdict was reached with (:mod:`.thresholds`)."""

    min_heldout_error_reduction: float = MIN_HELDOUT_REDUCTION
    min_heldout_error_reduction_stance: float = MIN_STANCE_REDUCTION
    min_effect_size_sigma: float = MIN_EFFECT_SIZE
    or_min_heldout_error_reduction: float = LARGE_HELDOUT_REDUCTION
    max_delta_aicc: float = MAX_DELTA_AICC
    min_inclusion_probability: float = MIN_INCLUSION
    cell_t: float = T_CELL
    cell_practical_bias: float = PRACTICAL_BIAS


@dataclass(frozen=True)
class Verdict(Record):
    """``missing_effect``, ``partially_explained`` (something added, but structure that
    flagged it remains), ``unexplained_structure`` or ``no_significant_missing_effect``,
    the sentence that explains it and the effects added (in order)."""

    status: str
    text: str
    added: tuple[str, ...]
    thresholds: Thresholds = field(default_factory=Thresholds)


@dataclass(frozen=True)
class RefinedHeldout(Record):
    """Held-out statistics of the refined model (trial-grouped CV along the secant from
    the calibrated to the refined replay), total and per channel."""

    heldout_error_reduction: float
    heldout_error_reduction_stance: float
    by_channel: Mapping[str, ChannelChange]
    note: str


@dataclass(frozen=True)
class IndistinguishablePair(Record):
    """Two leading candidates whose fitted contributions are nearly collinear, and the
    experiment that would separate them."""

    effects: tuple[str, str]
    correlation: float
    heldout_error_reduction: tuple[float, float]
    experiment: str


REPLAY_REFIT_METHOD = (
    "the calibration's sensitivity columns (ζ, φ_s and the touchdown depth) are fitted with "
    "the candidates on the stance-averaged replay residuals; with added effects, jointly "
    "refined by Gauss–Newton replays")


def readable_values(values: Mapping[str, float]) -> dict[str, float]:
    """θ for people: ``phi_s`` [rad] → ``phi_s_deg``."""
    return {("phi_s_deg" if k == "phi_s" else k): (math.degrees(v) if k == "phi_s" else v)
            for k, v in values.items()}


@dataclass(frozen=True)
class CalibrationReport(Record):
    """The model's own parameters: the equation-error calibration, the same with φ_s free
    (reported only), and the values after the replay refit (the model's final θ).

    Attributes:
        equation_error: :func:`~granular_mpc.validation.calibrate.calibrate`'s result.
        free_phi_s: the same with ζ and φ_s free.
        values: final θ (``zeta``, ``phi_s`` [rad], ``touchdown_depth`` [m]).
        linear_values: θ of the linear refit on the stance-averaged replay residuals.
    """

    equation_error: Calibration
    free_phi_s: Calibration
    values: Mapping[str, float]
    linear_values: Mapping[str, float]

    def to_dict(self) -> dict:
        out = self.equation_error.to_json()
        out["values"] = dict(self.values)
        out["values_readable"] = readable_values(self.values)
        out["equation_error_values"] = dict(self.equation_error.values)
        out["free_phi_s"] = {k: v for k, v in self.free_phi_s.to_json().items() if k != "method"}
        out["replay_refined"] = {"values": dict(self.values),
                                 "linear_values": dict(self.linear_values),
                                 "method": REPLAY_REFIT_METHOD}
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "CalibrationReport":
        eq = dict(data)
        eq["values"] = data["equation_error_values"]
        free = dict(data["free_phi_s"])
        return cls(Calibration.from_json(eq), Calibration.from_json(free),
                   dict(data["values"]), dict(data["replay_refined"]["linear_values"]))


@dataclass(frozen=True)
class LocalizationReport(Record):
    """Localisation before (calibrated model) and after the added effects, with the
    strongest cells in words (``where``, ``unexplained_where``)."""

    where: tuple[str, ...]
    before: Localization
    after: Localization
    unexplained_where: tuple[str, ...]
    n_significant_cells_before: int
    n_significant_cells_after: int
    n_major_cells_before: int
    n_major_cells_after: int


@dataclass(frozen=True)
class RefineIteration(Record):
    """One Gauss–Newton replay iteration (or the ``final`` replay) of a refinement."""

    iteration: int | str
    weighted_rss_before: float | None = field(default=None, metadata=OMIT_NONE)
    weighted_rss_linear_after: float | None = field(default=None, metadata=OMIT_NONE)
    values: Mapping[str, float] = field(default_factory=dict)
    calibration: Mapping[str, float] | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class ConditionalRow(Record):
    """A remaining candidate re-tested after an addition (screening statistics)."""

    effect: str
    heldout_error_reduction: float
    heldout_error_reduction_stance: float
    delta_aicc: float
    inclusion_probability: float | None
    effect_size: float
    significant: bool


@dataclass(frozen=True)
class SelectionStep(Record):
    """One addition: the contenders refined by replays, their AICc, the winner's
    refinement log and the conditional re-test of the others (absent after the last)."""

    added: str
    contenders: tuple[str, ...]
    contender_aicc: tuple[float, ...]
    refine: tuple[RefineIteration, ...]
    conditional: tuple[ConditionalRow, ...] | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class NEffFactor(Record):
    """N_eff / N of the systematic and the stance rows (lag-1 autocorrelation)."""

    systematic: float
    stance: float


@dataclass(frozen=True)
class DesignSummary(Record):
    """The regression problem and the bookkeeping of the run (``diagnosis.json: design``)."""

    n_stances: int
    n_trials: int
    channels: tuple[str, ...]
    phase_bins: int
    rows_systematic: int
    rows_stance: int
    n_eff_factor: NEffFactor
    sigma: Mapping[str, float]
    cv_groups: str
    cv_folds: int
    diverged_stances: tuple[int, ...]
    sensitivity_jumps_replaced: Mapping[str, tuple[str, ...]]
    candidates: Mapping[str, str]
    replays: int
    steps: tuple[SelectionStep, ...]
    replay_segments: int = 1


@dataclass(frozen=True)
class Recommended(Record):
    """The next step: the effects with their fitted values and the ``validate`` command."""

    effects: tuple[str, ...]
    calibrated_params: Mapping[str, float]
    validate_command: str

    @classmethod
    def for_fit(cls, theta: Mapping[str, float],
                fitted: Mapping[str, Mapping[str, float]]) -> "Recommended":
        """From the final θ and the added effects' fitted parameters."""
        eff = tuple(f"{n}:" + ",".join(f"{k}={v:.6g}" for k, v in p.items())
                    for n, p in fitted.items())
        cmd = ("granular-mpc validate DATA --params DIAG_DIR/diagnosis.json "
               + " ".join(f"--effect {n}" for n in fitted)).strip()
        return cls(eff, dict(theta), cmd)


@dataclass(frozen=True)
class FittedParameters(Record):
    """What ``validate --params`` reads from a diagnosis: the calibrated θ
    (``calibration.values``) and the fitted effects (``fitted_effects``)."""

    calibration: Mapping[str, float]
    effects: Mapping[str, Mapping[str, float]]

    @staticmethod
    def is_diagnosis(data: Mapping[str, Any]) -> bool:
        """Whether a parsed JSON object is (a part of) a diagnosis."""
        return "calibration" in data or "fitted_effects" in data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "FittedParameters":
        cal = dict((data.get("calibration") or {}).get("values", {}))
        eff = {k: dict(v) for k, v in (data.get("fitted_effects") or {}).items()}
        return cls(cal, eff)


@dataclass(frozen=True)
class Diagnosis(Record):
    """What :func:`~granular_mpc.validation.diagnose.diagnose` found; ``diagnosis.json``
    is :meth:`to_json`.

    Attributes:
        data: the data set's folder.
        verdict: the verdict.
        calibration: the model's own parameters.
        ranking: every candidate, the added ones first.
        indistinguishable: candidate pairs the data cannot tell apart.
        fitted_effects: refined parameters of the added effects.
        heldout_reduction_by_channel: held-out RMS before/after per channel.
        refined_heldout: held-out statistics of the refined model (None: nothing added).
        replay_rmse_by_channel: in-sample replay RMSE before/after (empty: nothing added).
        localization: where the model fails, before and after.
        design: the regression problem and the run's bookkeeping.
        recommended: the next step.
        timing_s: seconds per stage.
        figures: figure file names (in ``out_dir``).
        warnings: what the user should know about the run (candidates that could not be
            ranked, …).
        acceptance: the honest-acceptance decision of every refined contender.
        best_candidate: for the best candidate, whether it is the answer or only the
            closest proxy, in words (empty: no candidate).
        out_dir: where it was written (None: not written).
        proposal: a term proposed from the force equation error (:mod:`.proposal`; its
            effect file is in ``out_dir``), None when not computed.
        strength_twins: candidates that passed every test but that a terrain-strength
            (φ_s) mismatch of the model file explains as well (:mod:`.strength`): not
            added; either φ_s differs from the file or an effect strengthens/weakens the
            sand like it (the data cannot tell).
        not_twins: candidates not tested as such twins: the torque side, when the joint
            torque equation error showed a discrepancy no φ_s can produce
            (:func:`.strength.not_twins`).
        force_left: force axes whose equation error while the sole sinks the additions
            leave unexplained (:mod:`.force_leftover`).
        force_starts: the user's and proposed terrain-force terms fitted on the foot-force
            equation error with ζ (:mod:`.force_start`); those that pass were also refined
            from there.
        law_preferred: added terrain forces whose own law fits the sinking-sample force
            worse than a single law of the proposal (:mod:`.sinking_law`).
    """

    data: str
    verdict: Verdict
    calibration: CalibrationReport
    ranking: tuple[Ranked, ...]
    indistinguishable: tuple[IndistinguishablePair, ...]
    fitted_effects: Mapping[str, Mapping[str, float]]
    heldout_reduction_by_channel: Mapping[str, ChannelChange]
    refined_heldout: RefinedHeldout | None
    replay_rmse_by_channel: Mapping[str, ChannelChange]
    localization: LocalizationReport
    design: DesignSummary
    recommended: Recommended
    timing_s: Mapping[str, float] = field(default_factory=dict)
    figures: tuple[str, ...] = ()
    warnings: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)
    acceptance: tuple[Acceptance, ...] = field(default=(), metadata=OMIT_EMPTY)
    best_candidate: str = ""
    out_dir: Path | None = field(default=None, metadata=NOT_JSON)
    proposal: Proposal | None = field(default=None, metadata=OMIT_NONE)
    strength_twins: tuple[StrengthTwin, ...] = field(default=(), metadata=OMIT_EMPTY)
    not_twins: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)
    force_left: tuple[ForceLeftover, ...] = field(default=(), metadata=OMIT_EMPTY)
    force_starts: tuple[ForceStart, ...] = field(default=(), metadata=OMIT_EMPTY)
    law_preferred: tuple[LawPreferred, ...] = field(default=(), metadata=OMIT_EMPTY)

    @property
    def added(self) -> list[str]:
        """The added effects, in the order they were added."""
        return list(self.verdict.added)

    @property
    def figure_paths(self) -> tuple[Path, ...]:
        """The figures' paths (empty when not written)."""
        return () if self.out_dir is None else tuple(self.out_dir / f for f in self.figures)

    @property
    def result(self) -> dict:
        """The content of ``diagnosis.json`` as a dict (:meth:`to_dict`)."""
        return self.to_dict()

    def to_dict(self) -> dict:
        out = super().to_dict()
        if out["refined_heldout"] is None:
            out["refined_heldout"] = {}
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], out_dir: Path | None = None) -> "Diagnosis":
        data = dict(data)
        if not data.get("refined_heldout"):
            data["refined_heldout"] = None
        d = super().from_dict(data)
        return d if out_dir is None else replace(d, out_dir=Path(out_dir))

    def to_json(self) -> str:
        """The text of ``diagnosis.json`` (NaN → null)."""
        return json.dumps(json_safe(self.to_dict()), indent=1)

    @classmethod
    def from_json(cls, text: str, out_dir: Path | None = None) -> "Diagnosis":
        """The diagnosis from the text of a ``diagnosis.json``."""
        return cls.from_dict(json.loads(text), out_dir)

    def fitted_parameters(self) -> FittedParameters:
        """The calibrated θ and the fitted effects (what ``validate --params`` uses)."""
        return FittedParameters(dict(self.calibration.values),
                                {k: dict(v) for k, v in self.fitted_effects.items()})


def load_diagnosis(path: str | Path) -> Diagnosis:
    """Read a ``diagnosis.json`` (or the folder holding it) into a :class:`Diagnosis`."""
    p = Path(path)
    if p.is_dir():
        p = p / DIAGNOSIS_FILE
    return Diagnosis.from_json(p.read_text(encoding="utf-8"), p.parent)


__all__ = ["Diagnosis", "Verdict", "Thresholds", "ChannelChange", "Acceptance",
           "CoefficientCheck", "RefinedHeldout",
           "IndistinguishablePair", "CalibrationReport", "LocalizationReport",
           "RefineIteration", "ConditionalRow", "SelectionStep", "NEffFactor", "DesignSummary",
           "Recommended", "FittedParameters", "load_diagnosis", "readable_values",
           "DIAGNOSIS_FILE", "REPORT_FILE", "REPLAY_REFIT_METHOD"]
