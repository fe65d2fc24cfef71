"""The records of honest acceptance (:mod:`.acceptance`) and the per-channel error change
they share with the rest of the diagnosis (``diagnosis.json`` → ``acceptance``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

from .records import OMIT_EMPTY, OMIT_NONE, Record


@dataclass(frozen=True)
class ChannelChange(Record):
    """One channel's error before and after the added effects (channel units).

    ``rise_t`` (acceptance only): the paired t-statistic of the rise of the stance-by-stance
    squared error, after − before (positive: worse); None where not computed."""

    before: float
    after: float
    reduction: float
    unit: str
    rise_t: float | None = field(default=None, metadata=OMIT_EMPTY)


@dataclass(frozen=True)
class CoefficientCheck(Record):
    """One fitted parameter against its range: ``status`` is ``ok``, ``at_bound``,
    ``outside_physical_range`` or ``wrong_sign``; ``text`` says it in words."""

    param: str
    value: float
    status: str
    text: str


@dataclass(frozen=True)
class TorqueEvidence(Record):
    """Whether the measured joint torques hold a joint term's torque
    (:mod:`.torque_evidence`).

    Attributes:
        rms_torque: the term's torque on the swing-leg rows of the joint-torque equation
            error, at its fitted values [N·m RMS, all joints].
        held_share: the share of it the equation error holds: the least-squares slope of
            the error on the term's torque, pooled over the joints, each joint's mean
            removed (1: the torques hold all of it; 0: none).
        ci: the stance-grouped bootstrap 95 % interval of ``held_share``.
        n_rows, n_stances: the rows (row × joint) and stance segments of the fit.
        min_reach: the share the interval must reach (:data:`.torque_evidence.MIN_REACH`).
    """

    rms_torque: float
    held_share: float
    ci: tuple[float, float]
    n_rows: int
    n_stances: int
    min_reach: float = 0.5

    @property
    def holds(self) -> bool:
        """The torques may hold ``min_reach`` of the term's torque (the interval reaches
        it): False only when they hold significantly less — evidence against the term,
        not the absence of evidence for it."""
        return self.ci[1] >= self.min_reach

    def text(self) -> str:
        """The refusal in words."""
        lo, hi = self.ci
        return (f"the measured joint torques hold less than {100 * self.min_reach:.0f} % of "
                f"its torque: on the swing-leg rows of the joint-torque equation error it "
                f"adds {self.rms_torque:.3g} N·m RMS, of which the error holds "
                f"{100 * self.held_share:+.0f} % (95 % CI {100 * lo:+.0f} … {100 * hi:+.0f} "
                f"%; a joint term of the robot is held there, docs/validation.md §3.3)")


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
        given: the effects already added when it was judged (empty: judged against the
            calibrated model). A rejection holds against that model only: after a later
            addition the candidate may be refined and judged again.
        dropped: it had been added, and was dropped when judged again against the final
            model (``given``: the others).
        torque: for a joint term on data that measure the joint torques and the trunk
            motion, the share of its torque they hold (None: not tested).
    """

    effect: str
    accepted: bool
    credited_channels: Mapping[str, ChannelChange]
    coefficients: tuple[CoefficientCheck, ...]
    reasons: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)
    notes: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)
    given: tuple[str, ...] = field(default=(), metadata=OMIT_EMPTY)
    dropped: bool = field(default=False, metadata=OMIT_EMPTY)
    torque: TorqueEvidence | None = field(default=None, metadata=OMIT_NONE)


#: the contact regime's terrain-file parameters in words (:meth:`StrengthTwin.sentence`)
CONTACT_WORDS = {"contact_damping": "elastic-regime contact damping",
                 "added_mass_scale": "added mass of the solidified wedge"}


@dataclass(frozen=True)
class StrengthTwin(Record):
    """A candidate whose evidence a mismatch of the terrain file's own parameters — the
    strength φ_s or the contact regime (damping, added mass) — explains as well.

    Attributes:
        effect: the candidate.
        heldout_error_reduction: its held-out error reduction against the model.
        given_strength_heldout_error_reduction: the same with the terrain-file
            parameters free in the model.
        given_strength_delta_aicc: its ΔAICc against the model with them free.
        strength_heldout_error_reduction: what they alone remove.
        strength_values: the values the linear fit asks for, in readable units
            (``phi_s_deg`` [deg], ``contact_damping`` [N·s/m], ``added_mass_scale`` [-]).
        file_values: the same in the terrain file.
        parameter: the one the fit moves furthest from the file, in steps of its column
            (``phi_s_deg``, ``contact_damping``, ``added_mass_scale``): the reading the
            sentence gives.
    """

    effect: str
    heldout_error_reduction: float
    given_strength_heldout_error_reduction: float
    given_strength_delta_aicc: float
    strength_heldout_error_reduction: float
    strength_values: Mapping[str, float]
    file_values: Mapping[str, float]
    parameter: str = "phi_s_deg"

    def sentence(self) -> str:
        """The twin in words (signed changes of the held-out error: −26 % is a reduction).

        The data cannot tell a sand of another strength (contact regime) from a missing
        effect that acts on the sole as a different φ_s (damping, added mass) does, so the
        sentence gives both readings and how to decide: measure the parameter
        independently.
        """
        free = " and ".join({"phi_s_deg": "φ_s", "contact_damping": "the contact damping",
                             "added_mass_scale": "the added mass"}.get(k, k)
                            for k in self.file_values) or "φ_s"
        evidence = (f"{free} free {'changes' if free == 'φ_s' else 'change'} the held-out error by "
                    f"{_signed(self.strength_heldout_error_reduction)}, {self.effect} alone by "
                    f"{_signed(self.heldout_error_reduction)}, {self.effect} beside "
                    f"{'φ_s' if free == 'φ_s' else 'them'} by "
                    f"{_signed(self.given_strength_heldout_error_reduction)} (ΔAICc "
                    f"{self.given_strength_delta_aicc:.0f}). The data cannot tell which of two "
                    "readings holds: EITHER ")
        if self.parameter in CONTACT_WORDS:
            what = CONTACT_WORDS[self.parameter]
            keys = [self.parameter] + [k for k in self.strength_values if k != self.parameter]
            return (f"{self.effect} is indistinguishable from a contact-regime mismatch: "
                    + evidence + f"the sand's {what} differs from the terrain file's"
                    f"{self._values(*keys)} — check it independently (a drop or "
                    "load–unload test of the sole) and correct the terrain file only if that "
                    f"confirms it — OR a missing effect acts on the sole as a different {what} "
                    f"does ({self.effect} is one such proxy)")
        sign = self._direction()
        sand = {1: "stronger than", -1: "weaker than"}.get(sign, "of another strength than")
        verb = {1: "strengthens", -1: "weakens"}.get(sign, "strengthens or weakens")
        phi = {1: "a higher", -1: "a lower"}.get(sign, "another")
        return (f"{self.effect} is indistinguishable from a terrain-strength mismatch: "
                + evidence + f"the sand is {sand} the terrain file says"
                f"{self._values('phi_s_deg')} — check φ_s independently (a penetration test, "
                "or a calibration on other data) and correct the terrain file only if that "
                f"confirms it — OR a missing effect {verb} the sand the same way {phi} φ_s "
                f"does ({self.effect} is one such proxy)")

    def _values(self, *keys: str) -> str:
        """`` (phi_s_deg ≈ 33.4; terrain file 38.0)`` for ``keys`` (the fitted ones; ''
        when none is). Several: ``(contact_damping ≈ 290.0, added_mass_scale ≈ 1.1;
        terrain file 100.0, 1.0)`` — a group's parameters trade off against each other,
        so the reading gives them all, the one the fit moves furthest first."""
        keys = [k for k in keys if k in self.strength_values and k in self.file_values]
        if not keys:
            return ""
        fitted = ", ".join(f"{k} ≈ {self.strength_values[k]:.1f}" for k in keys)
        filed = ", ".join(f"{self.file_values[k]:.1f}" for k in keys)
        return f" ({fitted}; terrain file {filed})"

    def _direction(self) -> int:
        """+1 / −1 when the fitted φ_s is above / below the file's, 0 if unknown or equal."""
        if "phi_s_deg" not in self.strength_values or "phi_s_deg" not in self.file_values:
            return 0
        diff = self.strength_values["phi_s_deg"] - self.file_values["phi_s_deg"]
        return int(diff > 0) - int(diff < 0)


def _signed(reduction: float) -> str:
    """A held-out error reduction as a signed change: 0.26 → ``−26.2 %``."""
    return f"{'−' if reduction >= 0 else '+'}{abs(100.0 * reduction):.1f} %"


#: the stages of :data:`.force_leftover.STAGES` in words
FORCE_STAGE_WORDS = {"library": "the feature library", "law": "a velocity law",
                     "per_foot": "one foot's share of the law"}


@dataclass(frozen=True)
class ForceLeftover(Record):
    """One force axis whose equation error while the sole sinks holds a missing force the
    additions do not produce (:mod:`.force_leftover`).

    Attributes:
        axis: ``z`` (vertical) or ``h`` (forward, along the heading).
        explained: what the proposal's stage explains of it beyond ζ on the calibrated
            model [N RMS, foot level].
        footprint: the added effects' combined force on the same samples [N RMS, both
            axes].
        threshold: the stage's least explained force on the axis (null data) [N].
        effects: the added effects (terrain forces evaluated; joint effects and torque
            sensors produce no foot force at the measured state).
        n_samples: sinking samples.
        stage: the proposal's stage that explains it (``library``, ``law``, ``per_foot``:
            :data:`.force_leftover.STAGES`).
    """

    axis: str
    explained: float
    footprint: float
    threshold: float
    effects: tuple[str, ...]
    n_samples: int
    stage: str = "library"

    def words(self) -> str:
        """``a vertical force of 9.5 N RMS (the feature library; data without a missing
        foot force < 5 N)``."""
        axis = "vertical" if self.axis == "z" else "forward"
        return (f"a {axis} force of {self.explained:.1f} N RMS "
                f"({FORCE_STAGE_WORDS[self.stage]}; data without a missing foot force "
                f"< {self.threshold:g} N)")


@dataclass(frozen=True)
class LawPreferred(Record):
    """An added terrain force whose own law fits the force the foot meets while it sinks
    worse than a single law the proposal found there (:mod:`.sinking_law`).

    Attributes:
        effect: the added effect.
        axis: ``z`` (vertical) or ``h`` (forward).
        term_explained: what the effect's own law explains of the equation error beyond ζ,
            its main parameter fitted there [N RMS, foot level].
        law: the proposal's features on the axis (one law).
        law_explained: what that law explains beyond ζ [N RMS].
        share: the least share of ``law_explained`` the effect must explain.
    """

    effect: str
    axis: str
    term_explained: float
    law: tuple[str, ...]
    law_explained: float
    share: float

    def sentence(self) -> str:
        axis = "vertical" if self.axis == "z" else "forward"
        return (f"the {axis} foot force while the sole sinks follows a simpler law of the "
                f"proposal better ({', '.join(self.law)}: it explains "
                f"{self.law_explained:.1f} N RMS beyond ζ, {self.effect}'s own law fitted "
                f"there {self.term_explained:.1f} N — "
                f"{100 * self.term_explained / max(self.law_explained, 1e-12):.0f} %, "
                f"{100 * self.share:.0f} % would match it; docs/validation.md §3.7)")


def force_leftover_sentence(items: Sequence[ForceLeftover]) -> str:
    """The axes the additions leave unexplained, in one sentence ("" for none)."""
    if not items:
        return ""
    effects = items[0].effects
    by = ", ".join(effects) if effects else "the additions"
    one = len(effects) == 1
    return (f"the foot force while the sole sinks is not what {by} produce"
            f"{'s' if one else ''}: the foot-force equation error on those samples holds "
            + " and ".join(f.words() for f in items)
            + f", {'it produces' if one else 'they produce'} {items[0].footprint:.1f} N RMS "
            "there (docs/validation.md §3.7)")


__all__ = ["ForceLeftover", "LawPreferred", "force_leftover_sentence", "FORCE_STAGE_WORDS", "ChannelChange",
           "CoefficientCheck", "Acceptance", "StrengthTwin", "TorqueEvidence"]
