"""Leg odometry (granular_mpc.validation.estimation) against the plant's truth.

The synthetic data sets of ``conftest.workbench_data`` carry the plant's true trunk state
(``base_*``) and the true stance-foot intrusion; the estimator sees only the joint angles,
the trunk orientation and angular velocity and the stance labels.

Error budget at a window start (one sample before a touchdown, where the replays start):
the estimator assumes the anchor (the old stance foot) does not move, so its error is
bounded by (a) the anchor's true speed, the rate of its measured intrusion (it sinks and
slips on sand), plus (b) what smoothing costs: the same Savitzky–Golay window applied to
the true trunk velocity, plus with noise (c) the sensor noise carried through the leg:
the encoder noise σ_q = 1e-3 rad through the 15-sample derivative (gain
‖savgol_coeffs(15, 2, deriv=1)‖/Δt) and the lever arm of the three stance-leg joints
(≤ the leg length L), √3 L g σ_q.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import savgol_coeffs

from granular_mpc.columns import (BASE_ANGULAR_VELOCITY, BASE_LINEAR_VELOCITY,
                                  INTRUSION_COLUMNS, STANCE)
from granular_mpc.validation.dataformat import load_dataset
from granular_mpc.validation.dataformat.channels import ChannelGroup, ChannelSet
from granular_mpc.validation.estimation import anchor_sides, estimate_trunk, touchdown_row
from granular_mpc.validation.prepare import TrialStates

WINDOW = 15
PROPRIO = ChannelSet.of([ChannelGroup.JOINT_ANGLES, ChannelGroup.JOINT_VELOCITIES,
                         ChannelGroup.JOINT_TORQUES, ChannelGroup.TRUNK_ORIENTATION,
                         ChannelGroup.TRUNK_ANGULAR_VELOCITY])


def _savgol(x, w=WINDOW):
    from scipy.signal import savgol_filter
    return savgol_filter(x, w, 2, axis=0, mode="interp")


def _window_starts(df):
    """Rows one sample before each touchdown after the first (labels of the plant)."""
    lab = df[STANCE].astype(str).to_numpy()
    change = np.flatnonzero(lab[1:] != lab[:-1]) + 1
    return [int(k) - 1 for k in change[1:] if lab[k] in ("left", "right")
            and lab[k - 1] in ("left", "right")], lab


def _anchor_speed(df, lab, k, fs):
    """Speed of the old stance foot at row k: the rate of its intrusion over its run."""
    a = k
    while a > 0 and lab[a - 1] == lab[k]:
        a -= 1
    intr = df[list(INTRUSION_COLUMNS)].to_numpy()[a:k + 1]
    return float(np.linalg.norm(np.gradient(intr, 1.0 / fs, axis=0)[-1]))


def _errors(ds, truth, biped):
    fs = ds.meta.sample_rate_hz
    err, budget = [], []
    for name, df in ds.trials.items():
        true = truth.trials[name]
        st = TrialStates(biped, df, ds.joint_names, fs, WINDOW, channels=PROPRIO)
        assert st.trunk_source == "leg odometry"
        v_true = true[list(BASE_LINEAR_VELOCITY)].to_numpy()
        smooth_err = np.linalg.norm(_savgol(v_true) - v_true, axis=1)
        starts, lab = _window_starts(true)
        for k in starts:
            err.append(float(np.linalg.norm(st.v_W[k] - v_true[k])))
            budget.append(_anchor_speed(true, lab, k, fs) + float(smooth_err[k]))
    return np.array(err), np.array(budget)


@pytest.fixture(scope="module")
def truth(workbench_data):
    return load_dataset(workbench_data("null", noisy=False))


def test_velocity_at_window_starts_within_the_anchor_motion_budget(truth, biped):
    """Noise-free: at every window start ‖v̂ − v‖ ≤ anchor speed + smoothing error
    (measured 2–5 mm/s against budgets of 9–30 mm/s)."""
    err, budget = _errors(truth, truth, biped)
    assert err.size >= 15
    assert np.all(err <= budget), np.c_[err, budget]


def test_velocity_with_sensor_noise_within_the_propagated_budget(truth, workbench_data, biped):
    """Noise level 1 (IMU quaternion 0.5°, encoders 1e-3 rad, gyro 0.01 rad/s): the RMS
    error over the window starts ≤ RMS of the noise-free budget + √3 L g σ_q (module
    docstring; measured ≈ 0.02 m/s against ≈ 0.05 m/s)."""
    noisy = load_dataset(workbench_data("null", noisy=True))
    err, budget = _errors(noisy, truth, biped)
    g = np.linalg.norm(savgol_coeffs(WINDOW, 2, deriv=1, delta=1.0 / noisy.meta.sample_rate_hz))
    leg = 0.5                                               # m, ≥ hip-to-sole distance
    sigma_v = np.sqrt(3.0) * leg * g * 1e-3
    rms = float(np.sqrt(np.mean(err ** 2)))
    assert rms <= float(np.sqrt(np.mean(budget ** 2))) + sigma_v, (rms, sigma_v)


def test_height_drifts_by_the_sinkage_the_anchor_ignores(truth, biped):
    """The documented bias: between two touchdowns the estimated height gains what the
    old stance foot sank (the anchor does not sink), while the true trunk does not;
    within 20 % (the rolling-sole model and the pull-out before the switch)."""
    df = truth.trials[truth.trial_names[0]]
    quat = df[["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy()
    est = estimate_trunk(biped, quat, df[truth.joint_columns("q")].to_numpy(),
                         df[STANCE].astype(str).to_numpy(), truth.meta.sample_rate_hz,
                         dq_a=df[truth.joint_columns("dq")].to_numpy(),
                         w_B=df[list(BASE_ANGULAR_VELOCITY)].to_numpy())
    starts, _ = _window_starts(df)
    z_err = est.position[:, 2] - df["base_z"].to_numpy()
    sink = df["intrusion_z"].to_numpy()
    gains = np.diff(z_err[starts])
    sunk = sink[starts][1:]           # the anchor's depth when the next foot lands
    assert np.all(np.abs(gains - sunk) <= 0.2 * sunk), np.c_[gains, sunk]


def test_touchdown_row_finds_the_kink_of_a_landing_foot():
    """A foot descending at 1 m/s that lands at row 60 and then sinks at 0.2 m/s, with
    0.3 mm of noise: found within one sample from a label 8 rows late."""
    rng = np.random.default_rng(0)
    t = np.arange(120) * 0.002
    dz = np.where(t < t[60], 0.03 - 1.0 * (t - t[60]), 0.03 - 0.2 * (t - t[60]))
    dz = dz + rng.normal(0.0, 3e-4, t.size)
    assert abs(touchdown_row(dz, 68) - 60) <= 1
    assert abs(touchdown_row(dz, 57) - 60) <= 1


def test_anchor_sides_hold_the_last_stance_through_none():
    out = anchor_sides(["none", "right", "none", "left", "left", "none"])
    assert list(out) == ["right", "right", "right", "left", "left", "left"]
