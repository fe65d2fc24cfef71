"""What a diagnosis did not test: the opt-in candidate families (the measurement model,
the per-foot and layered variants of the terrain law) named in the verdict when it is not
a clean answer, with the option that adds them (``docs/validation.md`` §3.7).

A verdict that says ``unexplained_structure``, ``partially_explained`` or "only the closest
proxy" is only as wide as its candidate set: on a real robot the missing piece is often
sensing (a torque gain, an encoder offset, a stream delay), which the default library does
not contain. The sentence says so, instead of letting the proxy stand as the whole story.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Iterable, Mapping

from ...effects.variants import LAYERED_TAG, PER_FOOT_TAG
from .proposal import not_a_clean_answer
from .result import Verdict

#: :data:`granular_mpc.effects.measurement.TAG` (not imported: importing that module
#: registers the family)
MEASUREMENT_TAG = "measurement"
#: (tags of the family's effects, what it is and how to add it), in the order named
OPT_IN_FAMILIES: tuple[tuple[tuple[str, ...], str], ...] = (
    ((MEASUREMENT_TAG,), "the measurement model (torque gain and offset, encoder offset and "
                         "gain, force-sensor gain, torque delay, trunk attitude bias: "
                         "--measurement)"),
    ((PER_FOOT_TAG, LAYERED_TAG), "the per-foot and layered variants of the terrain law (one "
                                  "foot's track or sole, a harder layer: --variants)"),
)


def untested_families(tags: Iterable[Iterable[str]]) -> tuple[str, ...]:
    """The descriptions of :data:`OPT_IN_FAMILIES` none of whose tags any candidate has
    (``tags``: each candidate's tags)."""
    present = {t for ts in tags for t in ts}
    return tuple(words for fam, words in OPT_IN_FAMILIES if not present.intersection(fam))


def untested_sentence(infos: Mapping[str, object]) -> str:
    """"Not among the candidates: …" for the candidates ``infos`` (name → EffectInfo);
    empty when every family was tested."""
    missing = untested_families(getattr(i, "tags", ()) for i in infos.values())
    return ("Not among the candidates: " + "; ".join(missing)) if missing else ""


def with_untested(verdict: Verdict, best_candidate: str, infos: Mapping[str, object]) -> Verdict:
    """``verdict`` with :func:`untested_sentence` appended when it is not a clean answer
    (:func:`~.proposal.not_a_clean_answer`)."""
    if not not_a_clean_answer(verdict, best_candidate):
        return verdict
    sentence = untested_sentence(infos)
    if not sentence:
        return verdict
    return replace(verdict, text=f"{verdict.text}. {sentence}")


__all__ = ["MEASUREMENT_TAG", "OPT_IN_FAMILIES", "untested_families", "untested_sentence", "with_untested"]
