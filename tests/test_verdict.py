"""The verdict with candidates the measured channels cannot tell apart
(``validation.diagnosis.verdict``, ``VerdictInputs.channel_twins``): an addition of a
candidate that explains another, not assessable one's signature is reported as ambiguous,
not as the answer."""
from __future__ import annotations

from granular_mpc.validation.diagnosis import ParamEstimate, Ranked
from granular_mpc.validation.diagnosis.localization_records import Cell, Localization
from granular_mpc.validation.diagnosis.verdict import (VerdictInputs, best_candidate_statement,
                                                       decide)


def _ranked(effect: str) -> Ranked:
    est = ParamEstimate(0.06, 0.01, 0.05, 0.07, "N·m", 0.0, 0.0, 5.0, False, 0.05, 0.07)
    return Ranked(effect=effect, kind="joint", heldout_error_reduction=0.35,
                  heldout_error_reduction_stance=0.3, delta_aicc=-25.0, folds_improved="3/3",
                  effect_size=1.5, params={"coulomb": est}, main="coulomb", depends_on=(),
                  doc="", inclusion_probability=0.8, significant=True, rank=1, added=True,
                  refined_params={"coulomb": 0.06})


def _empty() -> Localization:
    return Localization((), (), 0, 0, {}, (), {}, {})


def test_an_addition_that_may_be_a_not_assessable_candidate_is_ambiguous():
    r = _ranked("joint_friction")
    plain = VerdictInputs(("joint_friction",), (r,), None, _empty())
    assert "AMBIGUOUS" not in decide(plain).text
    assert best_candidate_statement(plain).startswith("joint_friction is the answer")
    twin = VerdictInputs(("joint_friction",), (r,), None, _empty(),
                         channel_twins=(("inertial_drag", "joint_friction"),))
    assert twin.twins_of("joint_friction") == ("inertial_drag",)
    assert twin.twins_of("inertial_drag") == ()
    v = decide(twin)
    assert v.status == "missing_effect" and v.added == ("joint_friction",)
    assert ("AMBIGUOUS" in v.text and "indistinguishable with the measured channels: "
            "joint_friction, inertial_drag" in v.text)
    best = best_candidate_statement(twin)
    assert best.startswith("joint_friction is only the closest proxy")
    assert "cannot tell it from inertial_drag" in best and "is the answer" not in best


def _loc(*cells) -> Localization:
    major = sum(1 for c in cells if c.major)
    return Localization(tuple(cells), tuple(c for c in cells if c.major), major, major, {}, (),
                        {}, {})


def _cell(channel: str, side: str, phase_lo: float, t: float, major: bool) -> Cell:
    return Cell(channel, side, phase_lo, phase_lo + 10.0, 1.4e-3, 1e-3, 1.4e-3, t, 20, "m",
                2.0, True if major else None)


def test_structure_the_addition_leaves_is_not_called_explained():
    """The calibrated model's flagged cells are gone after the addition, but the final
    model has a major cell of its own (hidden before under a large misfit elsewhere, e.g.
    a hard layer answered by elastic_unloading): partially explained, the best candidate
    only the closest proxy; with no major cell left it is the answer."""
    r = _ranked("elastic_unloading")
    before = _loc(_cell("q_left_knee", "all", 80.0, 9.0, True),
                  _cell("intrusion_z", "right", 10.0, 3.0, False))
    left = _loc(_cell("q_left_knee", "all", 80.0, 1.0, False),
                _cell("intrusion_z", "right", 10.0, 5.9, True))
    clean = _loc(_cell("q_left_knee", "all", 80.0, 1.0, False),
                 _cell("intrusion_z", "right", 10.0, 3.5, False))
    v_left = VerdictInputs(("elastic_unloading",), (r,), None, left, before)
    assert v_left.remaining == ()                    # no flagged cell remains …
    assert [c.channel for c in v_left.left_after] == ["intrusion_z"]   # … but one is left
    v = decide(v_left)
    assert v.status == "partially_explained" and v.added == ("elastic_unloading",)
    assert "intrusion_z (right stance) at 10–20 % of stance" in v.text
    best = best_candidate_statement(v_left)
    assert best.startswith("elastic_unloading is only the closest proxy")
    assert "1 major cells are left" in best and "is the answer" not in best
    v_clean = VerdictInputs(("elastic_unloading",), (r,), None, clean, before)
    assert v_clean.left_after == ()
    assert decide(v_clean).status == "missing_effect"
    assert best_candidate_statement(v_clean).startswith("elastic_unloading is the answer")
    # nothing added: the rule does not apply (the structure is unexplained instead)
    assert VerdictInputs((), (r,), None, left, before).left_after == ()
    assert decide(VerdictInputs((), (r,), None, left, before)).status == "unexplained_structure"
