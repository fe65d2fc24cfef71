"""Gait schedule, Ruckig speed ramp and the capture-point foothold rule."""

import math

import numpy as np
import pytest

from granular_mpc.config import CommandConfig, FootholdConfig, GaitConfig
from granular_mpc.control.gait import (LEFT, RIGHT, CommandRamp, GaitSchedule, foothold,
                                       predict_com, predict_dcm)


def test_paper_gait_is_alternating_single_support_after_the_weight_shift():
    g = GaitSchedule(GaitConfig(period=0.4, swing_fraction=0.5, weight_shift=0.3))
    assert g.contacts(0.1) == (True, True)          # weight shift
    ts = np.arange(0.3, 5.0, 0.0005)
    n_feet = np.array([sum(g.contacts(t)) for t in ts])
    assert np.all(n_feet == 1)
    # each leg: stance 0.2 s then swing 0.2 s
    left = np.array([g.in_stance(t, LEFT) for t in ts])
    switches = np.flatnonzero(np.diff(left.astype(int)))
    # switch times are seen on the 0.5 ms grid: ±2 grid steps
    assert np.allclose(np.diff(ts[switches]), 0.2, atol=1e-3)


def test_double_support_share_matches_swing_fraction():
    g = GaitSchedule(GaitConfig(period=0.4, swing_fraction=0.4, weight_shift=0.0))
    ts = np.arange(0.0, 4.0, 0.0005)
    both = np.mean([all(g.contacts(t)) for t in ts])
    # 20 double-support intervals on a 0.5 ms grid over 4 s: quantisation ≤ 2·20·0.5 ms/4 s
    # = 0.005; bound 0.01
    assert both == pytest.approx(1.0 - 2 * 0.4, abs=0.01)


def test_phases_and_timers_are_consistent():
    g = GaitSchedule(GaitConfig())
    for t in np.arange(g.start, g.start + 2.0, 0.013):
        for foot in (LEFT, RIGHT):
            if g.in_stance(t, foot):
                assert 0.0 <= g.stance_phase(t, foot) <= 1.0
                assert g.time_to_touchdown(t, foot) == 0.0
                assert g.time_to_liftoff(t, foot) == pytest.approx(
                    (1.0 - g.stance_phase(t, foot)) * g.stance_duration, abs=1e-6)
            else:
                ttd = g.time_to_touchdown(t, foot)
                assert g.in_stance(t + ttd + 1e-6, foot)
                assert not g.in_stance(t + max(ttd - 1e-3, 0.0), foot) or ttd < 1e-3


def test_schedule_lookups_equal_the_cycle_formula_bit_for_bit():
    """The cached constants give the numbers of the defining formulas exactly."""
    cfg = GaitConfig(period=0.4, swing_fraction=0.43, weight_shift=0.3)
    g = GaitSchedule(cfg)
    period = cfg.period
    swing = cfg.period * cfg.swing_fraction
    stance = cfg.period - swing

    def local(t, foot):
        return (t - cfg.weight_shift - foot * 0.5 * period + 1e-9) % period - 1e-9

    for t in np.arange(0.0, 3.0, 0.00071).tolist() + [0.3 - 1e-12, 0.3, 0.7, 0.9]:
        standing = t < cfg.weight_shift - 1e-12
        assert g.standing(t) == standing
        want = tuple(True if standing else local(t, f) < stance - 1e-12 for f in (LEFT, RIGHT))
        assert g.contacts(t) == want
        for foot in (LEFT, RIGHT):
            assert g.in_stance(t, foot) == want[foot]
            phase = min(max((local(t, foot) - stance) / swing, 0.0), 1.0)
            assert g.swing_phase(t, foot) == phase
            ttd = 0.0 if want[foot] else period - local(t, foot)
            assert g.time_to_touchdown(t, foot) == ttd
            assert g.swing_timing(t, foot) == (ttd, phase)


def test_speed_ramp_respects_acceleration_and_jerk_limits():
    cfg = CommandConfig(speed=0.5, max_acceleration=0.4, max_jerk=1.5, start_delay=0.5)
    ramp = CommandRamp(cfg, 0.002)
    ts = np.arange(0.0, cfg.start_delay + ramp.ramp_duration + 1.0, 0.001)
    v = np.array([ramp.reference(t)[1][0] for t in ts])
    p = np.array([ramp.reference(t)[0][0] for t in ts])
    assert np.all(v[ts < cfg.start_delay] == 0.0)
    assert v[-1] == pytest.approx(0.5, abs=1e-9)
    acc = np.diff(v) / 0.001
    jerk = np.diff(acc) / 0.001
    # finite differences of a piecewise polynomial never exceed its bound (mean value
    # theorem); the margins cover round-off amplified by 1/dt and 1/dt² (1e-13 m/s → 1e-7)
    assert acc.max() <= 0.4 + 1e-6
    assert np.abs(jerk).max() <= 1.5 + 1e-3
    np.testing.assert_allclose(np.diff(p) / 0.001, 0.5 * (v[1:] + v[:-1]), atol=1e-4)


def lip_walk(rule_cfg, v_cmd, omega, T, steps, y0=0.0, vy0=0.0):
    """Independent LIP simulation (fine Euler) with instantaneous support exchange at each
    touchdown and footholds from the rule under test."""
    com = np.array([0.0, y0])
    vel = np.array([0.0, vy0])
    foot = np.array([0.0, 0.5 * rule_cfg.step_width])       # start on the left foot
    side = -1.0                                               # the right leg lands next
    feet = [foot.copy()]
    h = 1e-4
    for _ in range(steps):
        for _ in range(int(round(T / h))):
            acc = omega ** 2 * (com - foot)
            vel = vel + h * acc
            com = com + h * vel
        dcm = com + vel / omega
        foot = foothold(rule_cfg, dcm=dcm, v_cmd=np.array([v_cmd, 0.0, 0.0]),
                        stance_duration=T, omega=omega, lateral_sign=side, y_error=com[1])
        feet.append(foot.copy())
        side = -side
    return np.array(feet), com, vel


def test_dcm_foothold_gives_the_commanded_speed_and_step_width_in_a_lip():
    cfg = FootholdConfig(step_width=0.16, k_position=0.0)
    omega, T, v = math.sqrt(9.81 / 0.41), 0.2, 0.35
    feet, com, vel = lip_walk(cfg, v, omega, T, steps=60)
    # the LIP converges geometrically to the periodic gait: after 60 steps the stride and
    # width errors measured 3.1e-5 / 3.2e-5 m; bound 2e-4 m (6×; was 2e-3)
    strides = np.diff(feet[-20:, 0])
    assert np.allclose(strides, v * T, atol=2e-4)          # speed = stride / T
    widths = np.abs(np.diff(feet[-20:, 1]))
    assert np.allclose(widths, 0.16, atol=2e-4)


def test_walking_line_feedback_removes_lateral_drift():
    omega, T = math.sqrt(9.81 / 0.41), 0.2
    _, com_free, _ = lip_walk(FootholdConfig(step_width=0.16, k_position=0.0), 0.3, omega, T, 80)
    _, com_fb, _ = lip_walk(FootholdConfig(step_width=0.16, k_position=0.5), 0.3, omega, T, 80)
    # measured: 0.096 m without the line term, 8.9e-6 m with it (was < 0.02)
    assert abs(com_free[1]) > 0.05          # the DCM rule alone lets the mean wander
    assert abs(com_fb[1]) < 1e-3            # the line term brings it back


def test_dcm_foothold_recovers_from_a_lateral_push():
    cfg = FootholdConfig(step_width=0.16)
    omega, T = math.sqrt(9.81 / 0.41), 0.2
    feet, com, vel = lip_walk(cfg, 0.2, omega, T, steps=40, vy0=0.4)
    # measured: |v_y| 0.18 m/s at the end (0.4 at the push), widths back to 0.16 m within
    # 5e-5 m; bounds 0.3 m/s (was 0.5: a diverging LIP grows past it within a step) and
    # 1e-3 m (was 0.01)
    assert abs(vel[1]) < 0.3                                # not diverging
    widths = np.abs(np.diff(feet[-10:, 1]))
    assert np.allclose(widths, 0.16, atol=1e-3)


def test_lateral_clip_keeps_the_foot_within_reach_of_the_ground_force():
    cfg = FootholdConfig(step_width=0.19)
    p = foothold(cfg, dcm=np.array([0.0, -0.3]), v_cmd=np.zeros(3), stance_duration=0.2,
                 omega=4.9, lateral_sign=-1.0, com_y=0.0, max_lateral=0.12)
    assert p[1] == pytest.approx(-0.12)


def test_lip_predictions_match_numerical_integration():
    omega, dt = 4.9, 0.17
    com, vel, p = np.array([0.02, -0.03]), np.array([0.3, 0.1]), np.array([0.0, 0.05])
    c, v = com.copy(), vel.copy()
    h = 1e-5
    for _ in range(int(round(dt / h))):
        v = v + h * omega ** 2 * (c - p)
        c = c + h * v
    # semi-implicit Euler with h = 1e-5 s: O(h) error, measured 1.8e-6 / 2.3e-6 m; bound
    # 2e-5 (was 1e-4)
    np.testing.assert_allclose(predict_com(com, vel, p, omega, dt), c, atol=2e-5)
    np.testing.assert_allclose(predict_dcm(com + vel / omega, p, omega, dt), c + v / omega,
                               atol=2e-5)
