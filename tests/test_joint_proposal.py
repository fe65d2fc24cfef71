"""Tests of the joint-axis proposal (granular_mpc.validation.diagnosis.joint_proposal):
the joint torque equation error recovers a hidden joint torque, is ~0 without one, and
the emitted effect file loads and reproduces the fitted torque."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pinocchio as pin
import pytest

from granular_mpc.columns import (BASE_ANGULAR_VELOCITY, BASE_LINEAR_VELOCITY,
                                  BASE_POSITION, BASE_QUATERNION, GRF_COLUMNS, STANCE, TIME,
                                  joint_columns)
from granular_mpc.effects import effect_info, load_effect_file
from granular_mpc.robot.model import load_biped
from granular_mpc.rotations import matrix_from_quat_xyzw
from granular_mpc.validation.diagnosis.held_torque import hold_delay
from granular_mpc.validation.diagnosis.joint_proposal import (
    MAX_SENSOR_GAIN, MIN_EXPLAINED_RMS, PROPOSED_JOINT, PROPOSED_SENSOR, SKIP_AFTER,
    SMOOTH_WINDOW, fit_joint_terms, footprint_exit, joint_effect_source, joint_passes,
    joint_samples, joint_torque, kept_rows, leg_pairs, sensor_gain)

RATE = 500.0
B_VISCOUS = 0.4          # hidden viscous joint torque −b·q̇ [N·m·s/rad]


@pytest.fixture(scope="module")
def biped():
    return load_biped("yobogo10s", with_visuals=False)


def _trial(biped, seed: int, hidden_b: float, gain: float = 0.0, hidden=None,
           lead: float = 0.0) -> pd.DataFrame:
    """A smooth floating-base motion (no foot force), its RNEA torques, and the measured
    torque = (1 + gain)·(RNEA − the hidden torque −b·q̇) (the actuators were asked for
    RNEA − hidden; a torque sensor with a gain error reads it). ``hidden(q_a, q̇_a)``:
    another hidden torque [N·m] instead of −b·q̇. ``lead`` [s]: the torque logged at t is
    the one acting at t + lead (a command held after its stamp acts later)."""
    rng = np.random.default_rng(seed)
    m, d = biped.model, biped.create_data()
    t = np.arange(0.0, 3.0, 1.0 / RATE)
    J = biped.joint_names
    nj = len(J)
    amp, freq, ph = rng.uniform(0.2, 0.5, nj), rng.uniform(1.2, 2.2, nj), rng.uniform(0, 6, nj)
    q0 = np.array([0.0, -0.5, 1.2, 0.0, -0.5, 1.2])
    rows = []
    for tk in t:
        row = _row(biped, m, d, tk, q0, amp, freq, ph, hidden_b, gain, hidden)
        if lead:
            later = _row(biped, m, d, tk + lead, q0, amp, freq, ph, hidden_b, gain, hidden)
            row.update({c: later[c] for c in joint_columns(J, "tau")})
        rows.append(row)
    return pd.DataFrame(rows)


def _row(biped, m, d, tk, q0, amp, freq, ph, hidden_b, gain, hidden) -> dict:
    """One row of :func:`_trial` at time ``tk``."""
    J = biped.joint_names
    qa = q0 + amp * np.sin(2 * np.pi * freq * tk + ph)
    dqa = amp * 2 * np.pi * freq * np.cos(2 * np.pi * freq * tk + ph)
    ddqa = -amp * (2 * np.pi * freq) ** 2 * np.sin(2 * np.pi * freq * tk + ph)
    # the trunk: a slow roll and forward motion; v, a in Pinocchio's local convention
    roll = 0.05 * np.sin(2 * np.pi * 0.7 * tk)
    wx = 0.05 * 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * tk)
    awx = -0.05 * (2 * np.pi * 0.7) ** 2 * np.sin(2 * np.pi * 0.7 * tk)
    quat = np.array([np.sin(roll / 2), 0.0, 0.0, np.cos(roll / 2)])     # x, y, z, w
    R = matrix_from_quat_xyzw(quat)
    v_w = np.array([0.2, 0.0, 0.0])
    q = biped.q_from_parts(np.array([0.2 * tk, 0.0, 0.5]), quat, qa)
    v = np.zeros(m.nv)
    v[0:3] = R.T @ v_w
    v[3] = wx
    v[biped.idx_v] = dqa
    a = np.zeros(m.nv)
    a[0:3] = -np.cross(v[3:6], v[0:3])           # d/dt(Rᵀ v_W) with v_W constant
    a[3] = awx
    a[biped.idx_v] = ddqa
    tau_rnea = pin.rnea(m, d, q, v, a)[biped.idx_v]
    extra = -hidden_b * dqa if hidden is None else hidden(qa, dqa)
    tau_meas = (1.0 + gain) * (tau_rnea - extra)
    stance = "left" if int(tk / 0.5) % 2 == 0 else "right"
    row = {TIME: tk, STANCE: stance}
    row.update(dict(zip(joint_columns(J, "q"), qa)))
    row.update(dict(zip(joint_columns(J, "dq"), dqa)))
    row.update(dict(zip(joint_columns(J, "tau"), tau_meas)))
    row.update(dict(zip(BASE_POSITION, q[0:3])))
    row.update(dict(zip(BASE_QUATERNION, (quat[3], quat[0], quat[1], quat[2]))))
    row.update(dict(zip(BASE_LINEAR_VELOCITY, v_w)))
    row.update(dict(zip(BASE_ANGULAR_VELOCITY, v[3:6])))
    row.update(dict(zip(GRF_COLUMNS, (0.0, 0.0, 0.0))))
    return row


def _samples(biped, hidden_b, gain=0.0, hidden=None):
    trials = {f"trial_{i}": _trial(biped, i, hidden_b, gain, hidden) for i in range(3)}
    return joint_samples(trials, biped, RATE)


@pytest.fixture(scope="module")
def damped(biped):
    """Samples of the motion with the hidden viscous torque, and their fit."""
    s = _samples(biped, B_VISCOUS)
    return s, fit_joint_terms(s, biped.joint_names, seed=0)


def test_equation_error_is_zero_without_a_hidden_torque(biped):
    s = _samples(biped, 0.0)
    assert s.n > 1000
    assert float(np.sqrt(np.mean(s.error ** 2))) < 0.02       # N·m (smoothing error only)
    terms, fits = fit_joint_terms(s, biped.joint_names, seed=0)
    assert terms == ()
    assert not any(f.proposed for f in fits)


def test_a_held_torque_is_paired_with_the_kinematics_half_its_hold_later(biped):
    """Torques logged 1 ms before they act (a command held 2 ms after its stamp): the
    equation error is τ̇·1 ms (≈ 0.01 N·m on this slow motion, 0.14 N·m on the gait's
    swing hip); with the declared delay (:func:`hold_delay` of the hold) it is the
    smoothing error of data logged at the instant the torque acts (< 1e-3 N·m)."""
    assert hold_delay(None) == 0.0 and hold_delay(0.002) == 0.001
    trials = {f"trial_{i}": _trial(biped, i, 0.0, lead=0.001) for i in range(3)}
    raw = joint_samples(trials, biped, RATE)
    paired = joint_samples(trials, biped, RATE, torque_delay=hold_delay(0.002))
    rms_raw = float(np.sqrt(np.mean(raw.error ** 2)))
    rms_paired = float(np.sqrt(np.mean(paired.error ** 2)))
    assert paired.torque_delay == 0.001 and raw.torque_delay == 0.0
    assert rms_raw > 0.005
    assert rms_paired < 1e-3 and rms_paired < 0.05 * rms_raw


def test_equation_error_recovers_a_hidden_viscous_torque(biped, damped):
    s, (terms, fits) = damped
    # the equation error is the hidden torque itself: −b·q̇
    expected = -B_VISCOUS * s.dq
    assert np.sqrt(np.mean((s.error - expected) ** 2)) < 0.05 * np.sqrt(np.mean(expected ** 2))
    dq_terms = {t.joint: t.coefficient for t in terms if t.feature == "dq"}
    assert set(dq_terms) == set(biped.joint_names)
    for c in dq_terms.values():
        assert c < 0                                              # sign of a damping
        assert abs(c + B_VISCOUS) < 0.1 * B_VISCOUS               # within 10 %
    assert all(f.proposed and f.heldout_error_reduction_selected > 0.9 for f in fits)


def test_emitted_effect_file_loads_and_reproduces_the_fit(biped, damped, tmp_path):
    _, (terms, fits) = damped
    path = tmp_path / "proposed_joint_file.py"
    path.write_text(joint_effect_source(terms, fits, biped.joint_names), encoding="utf-8")
    # (load_effect_file returns the names new to the registry: another test may have
    # registered the same effect already; replace=True makes this file's definition current)
    load_effect_file(str(path))
    info = effect_info(PROPOSED_JOINT)
    assert info.kind == "joint"
    p = info.resolve_params({})
    rng = np.random.default_rng(3)
    assert p["scale"] == 1.0 and info.neutral == {"scale": 0.0}
    for _ in range(5):
        qa, dqa = rng.normal(1.0, 0.3, 6), rng.normal(0.0, 1.0, 6)
        np.testing.assert_allclose(info.fn(qa, dqa, p),
                                   joint_torque(terms, biped.joint_names, qa, dqa), rtol=1e-5,
                                   atol=1e-9)
        assert not np.any(info.fn(qa, dqa, {**p, "scale": 0.0}))      # off at neutral


def test_a_torque_gain_is_proposed_as_a_sensor_effect(biped, tmp_path):
    gain = 0.3
    s = _samples(biped, 0.0, gain)
    terms, fits = fit_joint_terms(s, biped.joint_names, seed=0)
    tau_terms = {t.joint: t.coefficient for t in terms if t.feature == "tau"}
    assert len(tau_terms) >= 4                       # the joints whose swing torque varies
    for c in tau_terms.values():                     # e = −g/(1+g)·τ_meas
        assert abs(c + gain / (1 + gain)) < 0.15 * gain / (1 + gain)
    path = tmp_path / "proposed_sensor_file.py"
    path.write_text(joint_effect_source(terms, fits, biped.joint_names), encoding="utf-8")
    load_effect_file(str(path))                     # (see the test above)
    info = effect_info(PROPOSED_SENSOR)
    assert info.kind == "sensor"
    p = info.resolve_params({})
    j = next(iter(tau_terms))
    np.testing.assert_allclose(p[f"gain_{j}"], -tau_terms[j] / (1 + tau_terms[j]), rtol=1e-5)


def test_joint_rule_needs_torque_above_null_and_a_plausible_gain():
    """A joint is proposed when its held-out reductions pass, it explains more torque than
    null data (:data:`MIN_EXPLAINED_RMS`), and a ``tau`` term means a plausible gain."""
    strong = (0.6, 0.7, 0.5, 0.2)                   # explains √(0.25 − 0.04) = 0.46 N·m
    assert joint_passes(*strong) and joint_passes(*strong, tau_coefficient=-0.2)
    weak = (0.6, 0.7, 0.12, 0.8 * 0.12)             # explains 0.072 N·m: a null's knee
    assert MIN_EXPLAINED_RMS > 0.072 and not joint_passes(*weak)
    assert not joint_passes(0.05, 0.7, 0.5, 0.2)    # per-fold selection does not hold out
    # c = −1.02: the measured torque is not the joint's (g = −62), not a gain error
    assert sensor_gain(-0.2) == pytest.approx(0.25) and abs(sensor_gain(-1.02)) > 50
    assert not joint_passes(*strong, tau_coefficient=-1.02)
    assert not joint_passes(*strong, tau_coefficient=-0.5)      # g = 1 > MAX_SENSOR_GAIN
    assert abs(sensor_gain(-0.3)) <= MAX_SENSOR_GAIN and joint_passes(*strong, tau_coefficient=-0.3)


def test_each_joint_axis_effect_can_be_emitted_alone(biped, damped):
    _, (terms, fits) = damped
    text = joint_effect_source(terms, fits, biped.joint_names, effects=(PROPOSED_JOINT,))
    assert text.startswith('"""') and text.count("@register_") == 1
    assert f"--effect-file {PROPOSED_JOINT}.py" in text
    assert joint_effect_source(terms, fits, biped.joint_names, effects=(PROPOSED_SENSOR,)) == ""


def test_rows_wait_for_the_trailing_foot_to_leave_its_footprint():
    """After a stance change the trailing foot is held by the sand until its sole rises
    above the height it touched down at; those rows (and half a smoothing window) are
    dropped even when that takes longer than the fixed ``SKIP_AFTER``."""
    n = 600
    stance = np.array(["none"] * 20 + ["left"] * 180 + ["right"] * 200 + ["left"] * 200)
    sole_z = np.full((n, 2), 0.05)
    # the left foot touches down at row 20 at z = 0.01, sinks 30 mm, and after the change at
    # row 200 rises through its touchdown height at row 271 (142 ms later at 500 Hz)
    k = np.arange(20, 200)
    sole_z[20:200, 0] = 0.01 - 0.03 * np.clip((k - 22) / 50.0, 0.0, 1.0)
    sole_z[200:400, 0] = -0.02 + 0.03 * np.arange(200) / 70.5
    sole_z[200:400, 1] = 0.0                                # right: touches down at row 200
    sole_z[400:, 1] = -0.0105 + 0.001 * np.arange(200)      # ... and leaves at row 411
    assert footprint_exit(stance, sole_z, 200) == 271       # first row above 0.01 m
    assert footprint_exit(stance, sole_z, 400) == 411
    sole_z[400:, 1] = -0.01                                 # still in the sand at the end
    assert footprint_exit(stance, sole_z, 400) == n
    assert footprint_exit(stance, sole_z, 20) is None         # a change from "none"
    # a trial that starts in the left stance: its touchdown is not in the trial, the surface
    # is where the right foot touched down at the change (z = 0): out at row 248 (−0.02 +
    # 0.03·48/70.5 > 0), not at the fixed SKIP_AFTER
    assert footprint_exit(stance[20:], sole_z[20:], 180) == 248 - 20
    fixed = kept_rows(stance, RATE)
    waited = kept_rows(stance, RATE, sole_z)
    blur = int(round(0.5 * SMOOTH_WINDOW * RATE))
    assert fixed[200 + int(round(SKIP_AFTER * RATE))]            # the fixed rule keeps row 245
    assert not waited[200:271 + blur].any() and waited[271 + blur]
    np.testing.assert_array_equal(waited[:200], fixed[:200])


def _knee_spring(k_left: float, k_right: float, q0: float = 1.2):
    """A hidden parallel spring in the knees: τ = −k·(q − q0) (actuator order
    left_hip_abd, left_hip_pitch, left_knee, right_…)."""
    def torque(qa, dqa):
        tau = np.zeros_like(qa)
        tau[2], tau[5] = -k_left * (qa[2] - q0), -k_right * (qa[5] - q0)
        return tau
    return torque


def test_a_spring_in_both_knees_is_fitted_once_for_both_legs(biped):
    """The same spring in both knees: one fit of both legs' rows (half the coefficients on
    twice the rows), its k and rest angle those of the spring; the other joints, with
    nothing hidden, propose nothing."""
    assert leg_pairs(biped.joint_names) == [(0, 3), (1, 4), (2, 5)]
    s = _samples(biped, 0.0, hidden=_knee_spring(2.0, 2.0))
    terms, fits = fit_joint_terms(s, biped.joint_names, seed=0)
    knees = {f.joint: f for f in fits if f.joint.endswith("knee")}
    assert all(f.proposed and f.both_legs for f in knees.values())
    assert not any(f.proposed for f in fits if not f.joint.endswith("knee"))
    coef = {(t.joint, t.feature): t.coefficient for t in terms}
    for side in ("left", "right"):
        k = -coef[(f"{side}_knee", "q")]
        assert abs(k - 2.0) < 0.1 * 2.0
        assert abs(coef[(f"{side}_knee", "const")] / k - 1.2) < 0.05      # rest angle [rad]
    assert coef[("left_knee", "q")] == coef[("right_knee", "q")]


def test_a_spring_in_one_knee_stays_a_fit_of_that_knee(biped):
    """A spring in the left knee only: the fit of both legs would halve it on each, far
    worse held out than the two knees' own fits — the left knee gets its own term, the
    right none."""
    s = _samples(biped, 0.0, hidden=_knee_spring(2.0, 0.0))
    terms, fits = fit_joint_terms(s, biped.joint_names, seed=0)
    knees = {f.joint: f for f in fits if f.joint.endswith("knee")}
    assert not any(f.both_legs for f in knees.values())
    assert knees["left_knee"].proposed and not knees["right_knee"].proposed
    k = -next(t.coefficient for t in terms if (t.joint, t.feature) == ("left_knee", "q"))
    assert abs(k - 2.0) < 0.1 * 2.0
    assert not any(t.joint == "right_knee" for t in terms)
