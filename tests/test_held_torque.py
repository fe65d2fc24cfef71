"""Tests of granular_mpc.validation.diagnosis.held_torque: the delay of a held torque and
the delayed torque rows, against closed forms."""

from __future__ import annotations

import numpy as np

from granular_mpc.validation.diagnosis.held_torque import delayed, hold_delay

RATE = 500.0


def test_a_held_command_acts_half_its_hold_late():
    """A zero-order hold of period T: the held signal's mean lag is T/2 — checked against
    a sinusoid held at 500 Hz and averaged over each 0.1 ms of its hold."""
    assert hold_delay(None) == 0.0 and hold_delay(0.0) == 0.0
    assert hold_delay(0.002) == 0.001
    f, T = 3.0, 0.002
    t = (np.arange(20000) + 0.5) * 1e-4          # mid-points: each hold sampled evenly
    held = np.sin(2 * np.pi * f * (np.floor(t / T) * T))
    # the held signal's best-fitting shift of the continuous one
    shifts = np.linspace(0.0, 0.002, 201)
    err = [np.mean((held - np.sin(2 * np.pi * f * (t - s))) ** 2) for s in shifts]
    assert abs(shifts[int(np.argmin(err))] - hold_delay(T)) < 2e-5


def test_delayed_rows_are_the_signal_earlier():
    """τ(t − d) by interpolation: for a ramp exact, for a slow sinusoid within the
    interpolation error; d = 0 returns a copy; the first row is held before the start."""
    t = np.arange(0.0, 1.0, 1.0 / RATE)
    ramp = np.column_stack([2.0 * t, -t])
    out = delayed(ramp, RATE, 0.001)
    np.testing.assert_allclose(out[1:], np.column_stack([2.0 * (t[1:] - 0.001), -(t[1:] - 0.001)]),
                               atol=1e-12)
    np.testing.assert_allclose(out[0], ramp[0])
    wave = np.sin(2 * np.pi * 2.0 * t)[:, None]
    np.testing.assert_allclose(delayed(wave, RATE, 0.003)[2:, 0],
                               np.sin(2 * np.pi * 2.0 * (t[2:] - 0.003)), atol=2e-4)
    same = delayed(ramp, RATE, 0.0)
    np.testing.assert_array_equal(same, ramp)
    assert same is not ramp
