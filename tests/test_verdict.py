"""The verdict (``validation.diagnosis.verdict``): an addition of a candidate that explains
another, not assessable one's signature is reported as ambiguous (``channel_twins``); an
addition that leaves major cells, or after which the screening still finds a candidate it
cannot add (``leftover_evidence``), is only partially explained — in each case the added
term is only the closest proxy, not the answer."""
from __future__ import annotations

from granular_mpc.validation.diagnosis import ParamEstimate, Ranked
from granular_mpc.validation.diagnosis.ranking_records import ConditionalResult
from granular_mpc.validation.diagnosis.localization_records import Cell, Localization
from granular_mpc.validation.diagnosis.acceptance_records import Acceptance
from granular_mpc.validation.diagnosis.verdict import (VerdictInputs, best_candidate_statement,
                                                       decide, rejected_sentence)


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


def _conditional_ranked(effect: str, given: tuple[str, ...], significant: bool,
                        reasons: tuple[str, ...]) -> Ranked:
    """A candidate not added, re-tested on the residual of the model with ``given``."""
    est = ParamEstimate(1.3, 0.1, 1.1, 1.5, "-", 1.0, 0.3, 3.0, False, 1.1, 1.5)
    return Ranked(effect=effect, kind="terrain_force", heldout_error_reduction=0.2,
                  heldout_error_reduction_stance=0.1, delta_aicc=-30.0, folds_improved="3/3",
                  effect_size=1.2, params={"n": est}, main="n", depends_on=(), doc="",
                  inclusion_probability=0.9, significant=True, rank=2,
                  conditional=(ConditionalResult(given, 0.18, significant),),
                  not_added_because=reasons)


def test_structure_the_screening_still_finds_after_the_addition_is_not_explained():
    """After the addition no cell is major, but a candidate still passes every screening
    test on the final model's residual and could not be added (its replays fail): the
    structure is not explained by any candidate — partially explained, the added term only
    the closest proxy (a hard layer answered by elastic_unloading, depth_hardening still
    significant beside it)."""
    r = _ranked("elastic_unloading")
    reason = ("its replays make the channels it is credited with worse: grf_x +5.4 %",)
    sig = _cell("intrusion_z", "all", 10.0, 5.3, False)          # significant, not major
    clean = Localization((sig,), (sig,), 1, 0, {}, (), {}, {})
    left = _conditional_ranked("depth_hardening", ("elastic_unloading",), True, reason)
    v = VerdictInputs(("elastic_unloading",), (r, left), None, clean, clean)
    assert [e.effect for e in v.leftover_evidence] == ["depth_hardening"]
    assert v.remaining == () and v.left_after == ()
    d = decide(v)
    assert d.status == "partially_explained" and d.added == ("elastic_unloading",)
    assert "still finds significant structure that no candidate explains" in d.text
    assert ("depth_hardening passes every test on the final model's residual (held-out "
            "error −18.0 %) and was not added" in d.text)
    assert "depth_hardening was reported, not added" not in d.text   # no acceptance entry
    assert "intrusion_z at 10–20 % of stance" in d.text               # where it is left
    best = best_candidate_statement(v)
    assert best.startswith("elastic_unloading is only the closest proxy")
    assert "depth_hardening passes every test on the final residual" in best
    assert "is the answer" not in best
    # not significant on the final residual, or tested given another selection (a
    # contender judged before the added term was chosen): the rule does not apply
    for other in (_conditional_ranked("depth_hardening", ("elastic_unloading",), False, ()),
                  _conditional_ranked("depth_hardening", (), True, reason),
                  _conditional_ranked("depth_hardening", ("elastic_unloading", "cohesion"),
                                      True, reason)):
        w = VerdictInputs(("elastic_unloading",), (r, other), None, clean, clean)
        assert w.leftover_evidence == ()
        assert decide(w).status == "missing_effect"
        assert best_candidate_statement(w).startswith("elastic_unloading is the answer")
    # with a major cell left as well, both are named (the cells once)
    major = _cell("intrusion_z", "right", 10.0, 5.9, True)
    both = VerdictInputs(("elastic_unloading",), (r, left), None, _loc(major), clean)
    t = decide(both).text
    assert both.left_after == (major,) and "1 channel × phase cells of the final model" in t
    assert "still finds significant structure" in t and "strongest cells" not in t
    # nothing added: no leftover evidence (the candidate is simply not added)
    assert VerdictInputs((), (left,), None, clean, clean).leftover_evidence == ()


def test_a_candidate_added_after_an_earlier_rejection_is_not_reported_as_rejected():
    """Rejected against the calibrated model, added once another effect was: the verdict
    does not call it 'not added'; a rejection against the new model says which model; an
    addition dropped against the final model is called dropped."""
    worse = ("its replays make the channels it is credited with worse: grf_z +5.5 %",)
    acc = (Acceptance("knee_spring", False, {}, (), worse),
           Acceptance("force_sensor_bias", True, {}, ()),
           Acceptance("knee_spring", True, {}, (), (), (), ("force_sensor_bias",)),
           Acceptance("joint_friction", False, {}, (), worse, (), ("force_sensor_bias",
                                                                   "knee_spring")),
           Acceptance("inertial_drag", False, {}, (), worse, (), ("knee_spring",), True))
    v = VerdictInputs(("force_sensor_bias", "knee_spring"),
                      (_ranked("force_sensor_bias"), _ranked("knee_spring")), None, _empty(),
                      acceptance=acc)
    text = rejected_sentence(v)
    assert "knee_spring was reported" not in text
    assert ("joint_friction was reported, not added (" + worse[0]
            + ") — judged with force_sensor_bias, knee_spring added") in text
    assert "inertial_drag was added, then dropped (" + worse[0] in text


def test_a_significant_candidate_refused_by_its_replays_is_not_no_effect():
    """Nothing added and no major cell, but the screening found a candidate significant
    that the acceptance refused: the verdict says the screening found structure that no
    replay confirms (``unexplained_structure``), never "no candidate passes the tests";
    without the refusal (or with a candidate that was not significant) it is no effect."""
    from dataclasses import replace

    tilt = replace(_ranked("terrain_slope"), added=False, refined_params=None,
                   not_added_because=("its replays make the channels it is credited with "
                                      "worse: grf_x +2.5 % (rise t = 1.1)",))
    acc = Acceptance("terrain_slope", False, {}, (), tilt.not_added_because)
    v = decide(VerdictInputs((), (tilt,), None, _empty(), acceptance=(acc,)))
    assert v.status == "unexplained_structure" and v.added == ()
    assert "terrain_slope passes the held-out, AICc and bootstrap tests" in v.text
    assert "held-out error −35.0 %" in v.text and "ΔAICc -25" in v.text
    assert "grf_x +2.5 %" in v.text                   # the reason, from rejected_sentence
    assert "no candidate passes" not in v.text
    for quiet in (replace(tilt, not_added_because=()), replace(tilt, significant=False)):
        q = decide(VerdictInputs((), (quiet,), None, _empty()))
        assert q.status == "no_significant_missing_effect"
        assert "no candidate passes the held-out" in q.text


def test_an_addition_that_barely_won_its_contest_is_not_called_the_answer():
    """A contender not added whose refined AICc is less than DECISIVE_DELTA_AICC above the
    winner's, in the contest that added it, is a near tie: the winner is only the closest
    proxy, and the statement names the tie; a contender at the decisive margin, one added
    later, or one that fitted better but was refused by the acceptance is not a tie."""
    from granular_mpc.validation.diagnosis.result import SelectionStep
    from granular_mpc.validation.diagnosis.verdict import DECISIVE_DELTA_AICC

    r = _ranked("encoder_offset")
    close = 305.1 + DECISIVE_DELTA_AICC - 2.8

    def inputs(selected, aicc):
        step = SelectionStep("encoder_offset", ("encoder_offset", "joint_friction", "torque_gain"),
                             (305.1, aicc, 343.6), ())
        return VerdictInputs(selected, (r,), None, _empty(), steps=(step,))

    tie = inputs(("encoder_offset",), close)
    assert tie.near_ties("encoder_offset") == (("joint_friction", close - 305.1),)
    best = best_candidate_statement(tie)
    assert best.startswith("encoder_offset is only the closest proxy")
    assert "barely prefer it to joint_friction (refined AICc +7.2" in best
    assert "torque_gain" not in best
    decisive = inputs(("encoder_offset",), 305.1 + DECISIVE_DELTA_AICC)
    assert decisive.near_ties("encoder_offset") == ()
    assert best_candidate_statement(decisive).startswith("encoder_offset is the answer")
    both = inputs(("encoder_offset", "joint_friction"), close)
    assert both.near_ties("encoder_offset") == ()
    # a contender that fitted better lost on the acceptance, not on the fit: no tie
    refused = inputs(("encoder_offset",), 305.1 - 50.0)
    assert refused.near_ties("encoder_offset") == ()
    assert best_candidate_statement(refused).startswith("encoder_offset is the answer")
