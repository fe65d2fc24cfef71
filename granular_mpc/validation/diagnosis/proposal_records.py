"""Frozen records of a proposed term (:mod:`.proposal`), part of ``diagnosis.json``."""

from __future__ import annotations

from dataclasses import dataclass, field

from .records import OMIT_EMPTY, Record


def change_text(reduction: float) -> str:
    """A held-out error reduction as the signed change of the error: 0.83 → "−83 %",
    −0.12 → "+12 %" (never "−-12 %")."""
    v = -100.0 * float(reduction)
    return f"{'−' if round(v) < 0 else '+'}{abs(v):.0f} %"


@dataclass(frozen=True)
class ProposedTerm(Record):
    """One selected feature of a proposed force.

    Attributes:
        axis: ``z`` (vertical, up) or ``h`` (forward, along the sole's heading).
        feature: the feature's name (:data:`~.features.FEATURES`).
        description: what the feature is, in words.
        coefficient_foot: coefficient on the whole foot [N per feature unit].
        coefficient_patch: the same per contact patch (the effect file's value).
        std_error: standard error of ``coefficient_foot`` (OLS on the selected features).
        unit: the coefficient's unit.
        selection_frequency: share of the stability resamples that selected it.
        expressible: whether a terrain-force effect can read the feature.
    """

    axis: str
    feature: str
    description: str
    coefficient_foot: float
    coefficient_patch: float
    std_error: float
    unit: str
    selection_frequency: float
    expressible: bool


@dataclass(frozen=True)
class AxisFit(Record):
    """The sparse fit of one force axis.

    Attributes:
        axis: ``z`` or ``h``.
        heldout_error_reduction: 1 − SSE_CV(ζ + sparse) / SSE_CV(ζ), trial-grouped, the
            selection redone in each fold.
        heldout_error_reduction_selected: the same for a refit on the stable features.
        rms_before, rms_after: in-sample RMS equation error [N] (ζ refitted; with the terms).
        threshold: the STLSQ threshold chosen by cross-validation (standardised).
        proposed: whether this axis contributes terms.
        stage: ``law`` (the physical velocity laws alone, :data:`~.proposal.LAW_FEATURES`),
            ``layer`` (one depth-layer law alone, :data:`~.proposal.LAYER_FEATURES`),
            ``per_foot`` (the right foot's share of the law's force alone,
            :data:`~.proposal.PER_FOOT_FEATURES`) or ``library`` (the whole feature library).
    """

    axis: str
    heldout_error_reduction: float
    heldout_error_reduction_selected: float
    rms_before: float
    rms_after: float
    threshold: float
    proposed: bool
    stage: str = "library"

    @property
    def explained_rms(self) -> float:
        """The force the terms explain, √(rms_before² − rms_after²) [N]."""
        return float(max(self.rms_before ** 2 - self.rms_after ** 2, 0.0) ** 0.5)


@dataclass(frozen=True)
class JointTerm(Record):
    """One selected feature of a proposed joint torque or torque-sensor term.

    Attributes:
        joint: the actuated joint (actuator order name).
        feature: ``const``, ``q``, ``dq``, ``sign_dq`` (joint effect) or ``tau``
            (torque-sensor gain: a sensor effect).
        coefficient: N·m per feature unit (``tau``: dimensionless, on the measured torque).
        std_error: its standard error (OLS on the selected features).
        unit: the coefficient's unit.
        selection_frequency: share of the stability resamples that selected it.
    """

    joint: str
    feature: str
    coefficient: float
    std_error: float
    unit: str
    selection_frequency: float


@dataclass(frozen=True)
class JointFit(Record):
    """The sparse fit of one joint's torque equation error.

    Attributes:
        joint: the actuated joint.
        heldout_error_reduction, heldout_error_reduction_selected: as :class:`AxisFit`.
        rms_before, rms_after: in-sample RMS equation error [N·m] (nuisance fitted; with
            the terms).
        proposed: whether this joint contributes terms.
        both_legs: the fit is of this joint and the same joint of the other leg together
            (one set of coefficients; the statistics are that fit's, over both joints'
            rows).
    """

    joint: str
    heldout_error_reduction: float
    heldout_error_reduction_selected: float
    rms_before: float
    rms_after: float
    proposed: bool
    both_legs: bool = False


@dataclass(frozen=True)
class Proposal(Record):
    """A term proposed from the force equation error when no library term may fit.

    Attributes:
        effect: the proposed force effect's name (as registered by its file).
        file: the effect file with every proposed effect, written into the diagnosis
            folder (empty: none written).
        terms: the selected features (empty: nothing proposed).
        axes: per force axis, the fit's statistics.
        n_samples, n_stances: sinking samples and stances used.
        pointed_to: whether the verdict points the user to it.
        note: how it was found and what it is not.
        not_expressible: selected force features a terrain force cannot read.
        joint_terms: selected features of the joint-torque equation error
            (:mod:`.joint_proposal`).
        joint_fits: per joint, that fit's statistics.
        joint_note: how the joint proposal was found (or why it was not available).
        files: one effect file per proposed effect (``<effect>.py``, in the same folder):
            each met its evidence rule and can be passed back alone.
    """

    effect: str
    file: str
    terms: tuple[ProposedTerm, ...]
    axes: tuple[AxisFit, ...]
    n_samples: int
    n_stances: int
    pointed_to: bool = False
    note: str = ""
    not_expressible: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)
    joint_terms: tuple[JointTerm, ...] = field(default=(), metadata=OMIT_EMPTY)
    joint_fits: tuple[JointFit, ...] = field(default=(), metadata=OMIT_EMPTY)
    joint_note: str = field(default="", metadata=OMIT_EMPTY)
    files: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)

    @property
    def proposed(self) -> bool:
        """Whether any term is proposed (foot force, joint torque or torque sensor)."""
        return bool(self.terms) or bool(self.joint_terms)


__all__ = ["change_text", "ProposedTerm", "AxisFit", "Proposal", "JointTerm", "JointFit"]
