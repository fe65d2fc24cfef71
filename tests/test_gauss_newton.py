"""The replay Gauss–Newton's continuation rule (``diagnosis.gauss_newton.still_moving``): a
fit whose last step still moved a column by more than MOVING_SHARE of its distance from
neutral is not converged; small steps, or steps below 1 % of the range near neutral, are."""

from granular_mpc.validation.diagnosis.candidates import Column
from granular_mpc.validation.diagnosis.gauss_newton import (MAX_EXTRA_ITERATIONS, MOVING_SHARE,
                                                            still_moving)


def _col(neutral=0.0, lower=0.0, upper=5000.0) -> Column:
    return Column("user_v2drag", "c", neutral, 100.0, lower, upper)


def test_a_fit_growing_by_secant_steps_is_still_moving():
    c = _col()
    # the quadratic shear drag of bench/out_of_library.py: 91 → 127 → 188 (truth 400)
    assert still_moving([c], {c.key: 127.0}, {c.key: 188.0})
    assert still_moving([c], {c.key: 91.0}, {c.key: 127.0})


def test_small_steps_are_converged():
    c = _col()
    assert not still_moving([c], {c.key: 390.0}, {c.key: 400.0})      # 2.5 %
    step = 0.9 * MOVING_SHARE * 400.0
    assert not still_moving([c], {c.key: 400.0}, {c.key: 400.0 + step})
    assert still_moving([c], {c.key: 400.0}, {c.key: 400.0 + 1.2 * MOVING_SHARE * 400.0})
    # near neutral a step below MOVING_SHARE × 1 % of the range is no movement
    assert not still_moving([c], {c.key: 0.0}, {c.key: 0.9 * MOVING_SHARE * 50.0})


def test_any_moving_column_counts_and_signs_do_not_matter():
    a, b = _col(), Column("user_knee_spring", "k", 0.0, 1.0, -20.0, 20.0)
    before = {a.key: 400.0, b.key: -2.0}
    assert not still_moving([a, b], before, {a.key: 401.0, b.key: -2.05})
    assert still_moving([a, b], before, {a.key: 401.0, b.key: -3.0})
    assert MAX_EXTRA_ITERATIONS >= 1
