"""Stage 6, verdict: what the diagnosis concludes, decided by an ordered list of rules.

Each rule looks at the :class:`VerdictInputs` and returns a :class:`~.result.Verdict` or
None; the first rule that answers decides (:func:`decide`). A new verdict is one new rule
function (in its own module if it needs more than a few lines) placed in
:data:`VERDICT_RULES` before the rules it should take precedence over.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

from .localise import where_summary
from .localization_records import Localization
from .ranking_records import Ranked
from .result import RefinedHeldout, Verdict
from .thresholds import MAJOR_BIAS


@dataclass(frozen=True)
class VerdictInputs:
    """What the rules see.

    Attributes:
        selected: the added effects, in order.
        ranking: the final ranking.
        refined_heldout: held-out statistics of the refined model (None: nothing added).
        after: localisation of the final model.
    """

    selected: tuple[str, ...]
    ranking: tuple[Ranked, ...]
    refined_heldout: RefinedHeldout | None
    after: Localization


def effect_sentence(e: Ranked) -> str:
    """One added effect in words: kind, dominant coefficient, screening statistics."""
    main = e.dominant_param()
    p = e.value_of(main)
    est = e.params.get(main)
    unit = est.unit if est is not None else ""
    inc = e.inclusion_probability
    return (f"{e.effect} ({e.kind}; {main} = {p:.4g} {unit}; screening: held-out "
            f"error −{100 * e.heldout_error_reduction:.1f} %, ΔAICc {e.delta_aicc:.0f}, "
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
            + f"; refined fit: held-out error −{100 * red:.1f} % (stance-averaged), "
              f"−{100 * red_st:.1f} % (stance by stance)")
    left = v.after.n_major_cells
    if left:
        text += (f". After adding {', '.join(v.selected)}, {left} channel × phase "
                 "cells still show structure (see localization.after)")
    return Verdict("missing_effect", text, v.selected)


def unexplained_structure(v: VerdictInputs) -> Verdict | None:
    """Nothing added, but major cells: say where."""
    if not v.after.n_major_cells:
        return None
    return Verdict("unexplained_structure",
                   "no candidate effect explains the residual structure; it is localised in: "
                   + " | ".join(where_summary(v.after, 4)), v.selected)


def no_significant_missing_effect(v: VerdictInputs) -> Verdict:
    """Nothing added and no major cell."""
    text = ("no significant missing effect: no candidate passes the held-out, AICc and "
            "bootstrap tests, and no channel × phase cell shows a systematic residual "
            f"larger than {MAJOR_BIAS:g} × the stance-to-stance scatter")
    if v.after.n_significant_cells:
        text += (f" ({v.after.n_significant_cells} cells are statistically but not "
                 "practically significant, see localization)")
    return Verdict("no_significant_missing_effect", text, v.selected)


#: the rules, first answer wins; the last one always answers
VERDICT_RULES: Sequence[Callable[[VerdictInputs], Verdict | None]] = (
    missing_effect, unexplained_structure, no_significant_missing_effect)


def decide(inputs: VerdictInputs) -> Verdict:
    """The first verdict of :data:`VERDICT_RULES` that answers."""
    for rule in VERDICT_RULES:
        v = rule(inputs)
        if v is not None:
            return v
    raise AssertionError("the last verdict rule always answers")


__all__ = ["VerdictInputs", "Verdict", "decide", "VERDICT_RULES", "effect_sentence",
           "missing_effect", "unexplained_structure", "no_significant_missing_effect"]
