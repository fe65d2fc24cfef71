"""Stage 6, verdict: what the diagnosis concludes, decided by an ordered list of rules.

Each rule looks at the :class:`VerdictInputs` and returns a :class:`~.result.Verdict` or
None; the first rule that answers decides (:func:`decide`). A new verdict is one new rule
function (in its own module if it needs more than a few lines) placed in
:data:`VERDICT_RULES` before the rules it should take precedence over.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Sequence

from .acceptance import cell_words, remaining_cells
from .acceptance_records import Acceptance, ForceLeftover, LawPreferred, force_leftover_sentence
from .localise import where_summary
from .localization_records import Localization
from .ranking_records import Ranked
from .result import IndistinguishablePair, RefinedHeldout, SelectionStep, Verdict
from .strength import StrengthTwin
from .thresholds import MAJOR_BIAS, MAX_DELTA_AICC, PRACTICAL_BIAS

#: cells named in a ``partially_explained`` verdict
LISTED_REMAINING = 4
#: a contender whose refined AICc is less than this above the added effect's, in the
#: contest that added it, is a near tie: the added effect is not called the answer. The
#: screening's "strong evidence" step (Burnham–Anderson: ΔAICc > 10, essentially no
#: support for the other model), not tuned (docs/validation.md §3.3)
DECISIVE_DELTA_AICC = -MAX_DELTA_AICC


@dataclass(frozen=True)
class VerdictInputs:
    """What the rules see.

    Attributes:
        selected: the added effects, in order.
        ranking: the final ranking.
        refined_heldout: held-out statistics of the refined model (None: nothing added).
        after: localisation of the final model.
        before: localisation of the calibrated model (None: not checked).
        acceptance: the acceptance decisions of the refined contenders.
        indistinguishable: candidate pairs the data cannot tell apart.
        channel_twins: (candidate that cannot be assessed, candidate that explains its
            signature) on the measured channels (:mod:`.identifiability`): an addition of
            the second is ambiguous.
        strength_twins: candidates not significant because a terrain-strength (φ_s)
            mismatch explains their evidence as well (:mod:`.strength`).
        force_left: force axes whose equation error while the sole sinks the additions
            leave unexplained (:mod:`.force_leftover`).
        steps: the selection's contests (:class:`~.result.SelectionStep`: the refined
            contenders and their AICc, the exchange included).
        law_preferred: added terrain forces whose own law fits the sinking-sample force
            worse than a single law of the proposal (:mod:`.sinking_law`).
    """

    selected: tuple[str, ...]
    ranking: tuple[Ranked, ...]
    refined_heldout: RefinedHeldout | None
    after: Localization
    before: Localization | None = None
    acceptance: tuple[Acceptance, ...] = ()
    indistinguishable: tuple[IndistinguishablePair, ...] = ()
    channel_twins: tuple[tuple[str, str], ...] = ()
    strength_twins: tuple[StrengthTwin, ...] = ()
    force_left: tuple[ForceLeftover, ...] = ()
    steps: tuple[SelectionStep, ...] = ()
    law_preferred: tuple[LawPreferred, ...] = ()

    def near_ties(self, name: str) -> tuple[tuple[str, float], ...]:
        """The contenders of the last contest ``name`` won that were not added and whose
        refined AICc is at or above its own by less than :data:`DECISIVE_DELTA_AICC`:
        (effect, ΔAICc), closest first. A contender *below* it lost on the acceptance, not
        on the fit; the verdict names it with its reasons (:func:`rejected_sentence`)."""
        step = next((s for s in reversed(self.steps) if s.added == name), None)
        if step is None:
            return ()
        aic = dict(zip(step.contenders, step.contender_aicc))
        ties = [(e, a - aic[name]) for e, a in aic.items()
                if e != name and e not in self.selected
                and 0.0 <= a - aic[name] < DECISIVE_DELTA_AICC]
        return tuple(sorted(ties, key=lambda t: t[1]))

    def twins_of(self, name: str) -> tuple[str, ...]:
        """The candidates the measured channels cannot tell from an addition of ``name``."""
        return tuple(sorted({a for a, b in self.channel_twins if b == name}))

    @property
    def remaining(self) -> tuple:
        """The calibrated model's major cells still major after the additions."""
        if self.before is None or not self.selected:
            return ()
        return remaining_cells(self.before, self.after)

    @property
    def leftover_evidence(self) -> tuple[Ranked, ...]:
        """The candidates that still pass every screening test on the residual of the
        final model (their conditional re-test given exactly the added effects is
        significant) and were not added: structure the screening still finds after the
        additions and that no candidate explains (its replays or its coefficients failed
        the acceptance). Empty when nothing was added."""
        if not self.selected:
            return ()
        sel = tuple(self.selected)
        return tuple(e for e in self.ranking if not e.added and any(
            c.significant and tuple(c.given) == sel for c in e.conditional))

    @property
    def left_after(self) -> tuple:
        """Every major cell of the final model after the additions, strongest first: the
        calibrated model's that remain (:attr:`remaining`) and any the additions did not
        explain although they were hidden before (a cell is major relative to its
        channel's stance-to-stance scatter, which a large misfit elsewhere in the stance
        inflates), or that the additions made."""
        if not self.selected:
            return ()
        return tuple(sorted((c for c in self.after.cells if c.major), key=lambda c: -abs(c.t)))


def error_change(reduction: float) -> str:
    """A held-out error change in words with one sign: reduction 0.53 → ``−53.0 %``,
    −0.008 → ``+0.8 %``."""
    return f"{'−' if reduction >= 0 else '+'}{abs(100.0 * reduction):.1f} %"


def effect_sentence(e: Ranked) -> str:
    """One added effect in words: kind, dominant coefficient, screening statistics."""
    main = e.dominant_param()
    p = e.value_of(main)
    est = e.params.get(main)
    unit = est.unit if est is not None else ""
    inc = e.inclusion_probability
    label = "refined" if e.refined_params and main in e.refined_params else "screening"
    return (f"{e.effect} ({e.kind}; {main} = {p:.4g} {unit} ({label}); screening: held-out "
            f"error {error_change(e.heldout_error_reduction)}, ΔAICc {e.delta_aicc:.0f}, "
            f"inclusion {'–' if inc is None else f'{inc:.2f}'})")


def missing_effect(v: VerdictInputs) -> Verdict | None:
    """Something was added: name it, with its refined held-out reduction, and say whether
    major structure is left."""
    if not v.selected:
        return None
    rh = v.refined_heldout
    red = rh.heldout_error_reduction if rh is not None else 0.0
    red_st = rh.heldout_error_reduction_stance if rh is not None else 0.0
    text = ("missing effect" + ("s" if len(v.selected) > 1 else "") + ": "
            + "; ".join(effect_sentence(e) for e in v.ranking if e.effect in v.selected)
            + f"; refined fit: held-out error {error_change(red)} (stance-averaged), "
              f"{error_change(red_st)} (stance by stance)")
    for name in v.selected:
        if v.twins_of(name):
            text += (f". AMBIGUOUS: {name} may be {' or '.join(v.twins_of(name))}'s doing — "
                     f"indistinguishable with the measured channels: {name}, "
                     f"{', '.join(v.twins_of(name))}")
    left = v.after.n_major_cells
    if left:
        text += (f". After adding {', '.join(v.selected)}, {left} channel × phase "
                 "cells still show structure (see localization.after)")
    return Verdict("missing_effect", text, v.selected)


def partially_explained(v: VerdictInputs) -> Verdict | None:
    """Something was added, but structure is left: the calibrated model's major cells
    that flagged the missing effect are not all gone, or the final model has major cells
    of its own (structure the additions did not explain), or the screening still finds a
    candidate that passes every test on the final model's residual and could not be added
    (:attr:`VerdictInputs.leftover_evidence`: structure no candidate explains), or the
    foot force while the sole sinks is not what the additions produce
    (:attr:`VerdictInputs.force_left`). Say what was added and what remains where."""
    left = v.remaining
    if not v.selected or not (left or v.left_after or v.leftover_evidence or v.force_left):
        return None
    parts = [missing_effect(v).text.split(". After adding")[0]]
    if left:
        parts.append(f"The structure that flagged it is only partly explained: "
                     f"{len(left)} of the calibrated model's major cells remain, e.g. "
                     + "; ".join(cell_words(c) for c in left[:LISTED_REMAINING]))
    elif v.left_after:
        new = v.left_after
        parts.append(f"Structure is left that the addition does not explain: {len(new)} "
                     "channel × phase cells of the final model are major, e.g. "
                     + "; ".join(cell_words(c) for c in new[:LISTED_REMAINING]))
    if v.leftover_evidence:
        parts.append(leftover_evidence_sentence(v, where=not (left or v.left_after)))
    if v.force_left:
        text = force_leftover_sentence(v.force_left)
        parts.append(text[0].upper() + text[1:])
    return Verdict("partially_explained", ". ".join(parts), v.selected)


def leftover_evidence_sentence(v: VerdictInputs, *, where: bool = True) -> str:
    """The structure the screening still finds after the additions, in words: which
    candidates pass every test on the final model's residual, why they were not added,
    and (``where``) the final model's strongest cells ("" if none)."""
    ev = v.leftover_evidence
    if not ev:
        return ""
    sel = tuple(v.selected)

    def one(e: Ranked) -> str:
        red = next(c.heldout_error_reduction for c in e.conditional
                   if c.significant and tuple(c.given) == sel)
        why = ("its replays or coefficients failed the acceptance" if e.not_added_because
               else "it was not refined as a contender")
        return (f"{e.effect} passes every test on the final model's residual (held-out "
                f"error {error_change(red)}) and was not added ({why})")

    text = (f"After adding {', '.join(v.selected)} the screening still finds significant "
            "structure that no candidate explains: " + "; ".join(one(e) for e in ev))
    cells = v.after.significant_cells[:LISTED_REMAINING] if where else ()
    if cells:
        text += ("; the final model's strongest cells: "
                 + "; ".join(cell_words(c) for c in cells))
    return text


def unexplained_structure(v: VerdictInputs) -> Verdict | None:
    """Nothing added, but major cells: say where."""
    if not v.after.n_major_cells:
        return None
    return Verdict("unexplained_structure",
                   "no candidate effect explains the residual structure; it is localised in: "
                   + " | ".join(where_summary(v.after, 4)), v.selected)


def refused_evidence(v: VerdictInputs) -> Verdict | None:
    """Nothing added and no major cell, but a candidate passed every screening test and
    was refused by the acceptance, or is a twin of a terrain-file parameter
    (:mod:`.strength`): the screening found structure that no candidate's replays
    confirm, or that a parameter of the terrain file explains as well. Saying "no
    significant missing effect" would deny the screening's own result (a surface tilt
    whose replays raise ``grf_x`` by 2.5 % while its held-out touchdown heights fall by
    24 %; a plant damping 3× the file's that a cohesion removes 15 % of)."""
    refused = [e for e in v.ranking if not e.added and e.significant and e.not_added_because]
    twins = [t for t in v.strength_twins if t.effect not in v.selected]
    if v.selected or not (refused or twins):
        return None

    def one(e: Ranked) -> str:
        inc = e.inclusion_probability
        return (f"{e.effect} passes the held-out, AICc and bootstrap tests (held-out error "
                f"{error_change(e.heldout_error_reduction)}, ΔAICc {e.delta_aicc:.0f}, "
                f"inclusion {'–' if inc is None else f'{inc:.2f}'}) but was not added")

    def twin(t: StrengthTwin) -> str:
        return (f"{t.effect} (held-out error {error_change(t.heldout_error_reduction)}) is "
                "explained as well by a parameter of the terrain file")

    text = ("the screening finds structure that no candidate's replays confirm: "
            + "; ".join([one(e) for e in refused] + [twin(t) for t in twins])
            + f"; no channel × phase cell shows a systematic residual larger than "
              f"{MAJOR_BIAS:g} × the stance-to-stance scatter")
    return Verdict("unexplained_structure", text, v.selected)


def no_significant_missing_effect(v: VerdictInputs) -> Verdict:
    """Nothing added and no major cell."""
    text = ("no significant missing effect: no candidate passes the held-out, AICc and "
            "bootstrap tests, and no channel × phase cell shows a systematic residual "
            f"larger than {MAJOR_BIAS:g} × the stance-to-stance scatter and "
            f"{PRACTICAL_BIAS:g} × the error of one sample of a correct model "
            "(that scatter and the sensor noise)")
    if v.after.n_significant_cells:
        text += (f" ({v.after.n_significant_cells} cells are statistically but not "
                 "practically significant, see localization)")
    return Verdict("no_significant_missing_effect", text, v.selected)


#: the rules, first answer wins; the last one always answers
VERDICT_RULES: Sequence[Callable[[VerdictInputs], Verdict | None]] = (
    partially_explained, missing_effect, unexplained_structure, refused_evidence,
    no_significant_missing_effect)


def rejected_sentence(v: VerdictInputs) -> str:
    """The refined contenders reported but not added, with why, and the candidates that
    are a terrain-strength mismatch in disguise ("" if none)."""
    out = [f"{a.effect} was {'added, then dropped' if a.dropped else 'reported, not added'}"
           f" ({'; '.join(a.reasons)})"
           + (f" — judged with {', '.join(a.given)} added" if a.given else "")
           for a in v.acceptance if not a.accepted and a.effect not in v.selected]
    out += [f"{t.sentence()}; not added" for t in v.strength_twins
            if t.effect not in v.selected]
    return ". ".join(out)


def best_candidate_statement(v: VerdictInputs) -> str:
    """Whether the best candidate is the answer or only the closest proxy, and why."""
    if not v.ranking:
        return ""
    best = v.ranking[0]
    name = best.effect
    twins = sorted({b for p in v.indistinguishable for b in p.effects
                    if name in p.effects and b != name})
    if best.added:
        why = []
        if v.remaining:
            why.append(f"{len(v.remaining)} of the major cells that flagged the structure "
                       "remain")
        elif v.left_after:
            why.append(f"{len(v.left_after)} major cells are left after the addition, e.g. "
                       + cell_words(v.left_after[0]))
        if v.leftover_evidence:
            why.append("the screening still finds structure after the addition that no "
                       "candidate explains (" + ", ".join(
                           f"{e.effect} passes every test on the final residual but was not "
                           "added" for e in v.leftover_evidence) + ")")
        if v.force_left:
            why.append(force_leftover_sentence(v.force_left))
        why += [lp.sentence() for lp in v.law_preferred if lp.effect == name]
        if twins:
            why.append(f"the data cannot tell it from {', '.join(twins)}")
        ties = v.near_ties(name)
        if ties:
            why.append("the replays barely prefer it to " + ", ".join(
                f"{e} (refined AICc {d:+.1f}; {DECISIVE_DELTA_AICC:g} would be decisive)"
                for e, d in ties))
        if v.twins_of(name):
            why.append("ambiguous: the measured channels cannot tell it from "
                       f"{', '.join(v.twins_of(name))}, which cannot be assessed without "
                       "the missing channels")
        acc = next((a for a in v.acceptance if a.effect == name and a.accepted), None)
        if acc is not None and acc.notes:
            why.append("; ".join(acc.notes))
        if not why:
            return (f"{name} is the answer: its replays improve the channels it is credited "
                    "with, its coefficients are physical and the structure it was added for "
                    "is explained")
        return f"{name} is only the closest proxy: " + "; ".join(why)
    twin = next((t for t in v.strength_twins if t.effect == name), None)
    if twin is not None:
        return (f"the best candidate, {name}, is only the closest proxy and was not added: "
                + twin.sentence())
    if best.not_added_because:
        return (f"the best candidate, {name}, is only the closest proxy and was not added: "
                + "; ".join(best.not_added_because))
    if v.after.n_major_cells:
        return (f"the best candidate, {name}, is only the closest proxy: it does not pass "
                "the tests, and the structure is not explained by any candidate")
    return f"no candidate is needed (the best, {name}, does not pass the tests)"


def decide(inputs: VerdictInputs) -> Verdict:
    """The first verdict of :data:`VERDICT_RULES` that answers, with the refined
    contenders that were reported but not added appended to its text."""
    for rule in VERDICT_RULES:
        v = rule(inputs)
        if v is not None:
            extra = rejected_sentence(inputs)
            return replace(v, text=f"{v.text}. {extra}") if extra else v
    raise AssertionError("the last verdict rule always answers")


__all__ = ["VerdictInputs", "Verdict", "decide", "VERDICT_RULES", "effect_sentence",
           "missing_effect", "partially_explained", "unexplained_structure",
           "no_significant_missing_effect", "refused_evidence", "error_change",
           "rejected_sentence",
           "best_candidate_statement", "leftover_evidence_sentence",
           "LISTED_REMAINING"]
