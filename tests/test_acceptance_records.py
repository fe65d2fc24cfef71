"""The acceptance records' words (granular_mpc.validation.diagnosis.acceptance_records)."""
from __future__ import annotations

from granular_mpc.validation.diagnosis.acceptance_records import StrengthTwin


def _twin(fitted: float) -> StrengthTwin:
    return StrengthTwin("user_rate_sand", 0.30, -0.01, -2.0, 0.35, {"phi_s_deg": fitted},
                        {"phi_s_deg": 38.0})


def test_a_strength_twin_gives_both_readings_and_no_certainty():
    """A φ_s the data ask for is either the sand's or a missing effect's that strengthens
    the sand like it (a rate-dependent strength in a plant of the file's φ_s): both are
    said, with how to tell them apart; "not a missing effect" is never said."""
    text = _twin(50.0).sentence()
    assert "indistinguishable from a terrain-strength mismatch" in text
    assert ("EITHER the sand is stronger than the terrain file says (phi_s_deg ≈ 50.0; "
            "terrain file 38.0)") in text
    assert "check φ_s independently (a penetration test, or a calibration on other data)" in text
    assert "OR a missing effect strengthens the sand the same way a higher φ_s does" in text
    assert "not a missing effect" not in text and "calibration matter" not in text


def test_a_weaker_sand_reads_as_an_effect_that_weakens_it():
    text = _twin(33.0).sentence()
    assert "EITHER the sand is weaker than the terrain file says" in text
    assert "OR a missing effect weakens the sand" in text and "strengthens" not in text


def test_the_twin_keeps_its_record_fields():
    tw = _twin(50.0)
    assert tw.strength_values == {"phi_s_deg": 50.0} and tw.file_values == {"phi_s_deg": 38.0}
    assert tw.effect == "user_rate_sand" and tw.heldout_error_reduction == 0.30
