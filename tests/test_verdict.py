"""The verdict with candidates the measured channels cannot tell apart
(``validation.diagnosis.verdict``, ``VerdictInputs.channel_twins``): an addition of a
candidate that explains another, not assessable one's signature is reported as ambiguous,
not as the answer."""
from __future__ import annotations

from granular_mpc.validation.diagnosis import ParamEstimate, Ranked
from granular_mpc.validation.diagnosis.localization_records import Localization
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
