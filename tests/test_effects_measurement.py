"""The measurement-model family (granular_mpc.effects.measurement): each map changes only
its columns, by the stated law, and the replay's inversion recovers the true values."""

from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.effects import (SensorContext, apply_sensor_effects, effect_info,
                                  invert_sensor_effects, registered_names)
from granular_mpc.effects.measurement import JOINTS, MEASUREMENT, TAG, register_measurement

N = 50


@pytest.fixture(scope="module")
def cols():
    t = np.arange(N) * 0.005
    out = {"time": t}
    for i, j in enumerate(JOINTS):
        out[f"q_{j}"] = 0.5 + 0.1 * i + 0.2 * np.sin(7 * t + i)
        out[f"dq_{j}"] = 1.4 * np.cos(7 * t + i)
        out[f"tau_{j}"] = 3.0 * np.sin(11 * t + i) + i
    out |= {f"grf_{a}": 10.0 + 90.0 * (a == "z") + np.sin(5 * t) for a in "xyz"}
    half = 0.5 * (0.05 * np.sin(3 * t) + 0.02)          # a trunk pitching about y
    out |= {"base_qw": np.cos(half), "base_qx": 0.0 * t, "base_qy": np.sin(half),
            "base_qz": 0.0 * t}
    return out


@pytest.fixture(scope="module")
def ctx():
    return SensorContext(np.array(["left"] * N), np.arange(N) * 0.005, JOINTS)


def _apply(name, values, cols, ctx):
    info = effect_info(name)
    p = info.neutral_params() | values
    return apply_sensor_effects(cols, [(info, p)], ctx), [(info, p)]


def test_family_registered_once_with_tag_and_neutral():
    assert register_measurement() == MEASUREMENT
    assert len(set(registered_names())) == len(registered_names())
    for name in MEASUREMENT:
        info = effect_info(name)
        assert info.kind == "sensor" and TAG in info.tags
        assert set(info.neutral) == set(info.params)          # every parameter switches off


def test_each_map_changes_only_its_columns(cols, ctx):
    cases = {
        "torque_gain": ({"gain_left_knee": 0.1}, {"tau_left_knee"}),
        "torque_offset": ({"offset_right_hip_pitch": 0.5}, {"tau_right_hip_pitch"}),
        "encoder_offset": ({"delta_left_knee": 0.03}, {"q_left_knee"}),
        "encoder_gain": ({"scale_left_knee": 0.05}, {"q_left_knee", "dq_left_knee"}),
        "force_sensor_gain": ({"gain_z": 0.1}, {"grf_z"}),
        "torque_time_offset": ({"delay": 0.01}, {f"tau_{j}" for j in JOINTS}),
        "trunk_attitude_bias": ({"pitch": 0.02}, {"base_qw", "base_qy"}),
    }
    for name, (values, expect) in cases.items():
        out, _ = _apply(name, values, cols, ctx)
        changed = {c for c in cols if not np.allclose(out[c], cols[c])}
        assert changed == expect, name
        off, _ = _apply(name, {}, cols, ctx)
        assert all(np.allclose(off[c], cols[c]) for c in cols), name


def test_laws(cols, ctx):
    out, _ = _apply("torque_gain", {"gain_left_knee": 0.1}, cols, ctx)
    assert np.allclose(out["tau_left_knee"], 1.1 * cols["tau_left_knee"])
    out, _ = _apply("encoder_offset", {"delta_left_knee": 0.03}, cols, ctx)
    assert np.allclose(out["q_left_knee"] - cols["q_left_knee"], 0.03)
    out, _ = _apply("encoder_gain", {"scale_left_knee": 0.05}, cols, ctx)
    assert np.allclose(out["q_left_knee"], 1.05 * cols["q_left_knee"])
    assert np.allclose(out["dq_left_knee"], 1.05 * cols["dq_left_knee"])
    # a 2-sample lag: the measured torque at t is the true one at t − 10 ms
    out, _ = _apply("torque_time_offset", {"delay": 0.01}, cols, ctx)
    assert np.allclose(out["tau_left_knee"][2:], cols["tau_left_knee"][:-2])


def test_replay_inversion_recovers_the_truth(cols, ctx):
    for name, values, targets in (
            ("torque_gain", {"gain_left_knee": 0.2, "gain_right_hip_abd": -0.1},
             ["tau_left_knee", "tau_right_hip_abd"]),
            ("torque_offset", {"offset_left_knee": 1.5}, ["tau_left_knee"]),
            ("encoder_offset", {"delta_right_knee": -0.04}, ["q_right_knee"]),
            ("encoder_gain", {"scale_right_knee": 0.05, "scale_left_hip_pitch": -0.03},
             ["q_right_knee", "dq_right_knee", "q_left_hip_pitch", "dq_left_hip_pitch"])):
        meas, specs = _apply(name, values, cols, ctx)
        true = invert_sensor_effects(meas, specs, ctx, targets)
        for c in targets:
            assert np.allclose(true[c], cols[c], atol=1e-9), (name, c)


@pytest.mark.parametrize("delay", [0.005, 0.0125, 0.02])
def test_a_torque_delay_of_a_sample_or_more_is_inverted(cols, ctx, delay):
    """The delay mixes samples: solved sample by sample it cannot be inverted (zero slope
    on its own sample: the numerical solve refuses, naming the effect); its own inverse
    recovers the true torques — exactly for a whole number of samples, to the smoothing of
    the interpolation otherwise — away from the ends (the stream is held there)."""
    import dataclasses

    from granular_mpc.exceptions import ConfigError

    meas, specs = _apply("torque_time_offset", {"delay": delay}, cols, ctx)
    c = "tau_left_knee"
    true = invert_sensor_effects(meas, specs, ctx, [c])
    k = int(np.ceil(delay / 0.005))
    inner = slice(k + 1, N - k - 1)
    err = np.abs(true[c] - cols[c])[inner]
    whole = abs(delay / 0.005 - round(delay / 0.005)) < 1e-9
    assert err.max() < (1e-9 if whole else 0.02 * np.ptp(cols[c]))
    # the sample-by-sample solve of the same map without its inverse
    bare = [(dataclasses.replace(specs[0][0], inverse=None), specs[0][1])]
    with pytest.raises(ConfigError, match="torque_time_offset.*cannot be inverted"):
        invert_sensor_effects(meas, bare, ctx, [c])
    loose = invert_sensor_effects(meas, bare, ctx, [c], strict=False)
    assert np.abs(loose[c] - cols[c])[inner].max() > 0.1 * np.ptp(cols[c])


def test_a_trunk_attitude_bias_tilts_the_trunk_and_is_inverted(cols, ctx):
    """A pitch bias adds to the trunk's pitch angle (a rotation about the trunk's y axis
    composes with one about the same axis); a roll bias as well; the inverse recovers the
    measured quaternion exactly."""
    from granular_mpc.rotations import rpy_rows_from_quat_wxyz

    q = np.column_stack([cols[c] for c in ("base_qw", "base_qx", "base_qy", "base_qz")])
    out, specs = _apply("trunk_attitude_bias", {"pitch": 0.03}, cols, ctx)
    qm = np.column_stack([out[c] for c in ("base_qw", "base_qx", "base_qy", "base_qz")])
    np.testing.assert_allclose(rpy_rows_from_quat_wxyz(qm)[:, 1] - rpy_rows_from_quat_wxyz(q)[:, 1],
                               0.03, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(qm, axis=1), 1.0, atol=1e-12)
    out, specs = _apply("trunk_attitude_bias", {"roll": -0.02, "pitch": 0.01}, cols, ctx)
    targets = ["base_qw", "base_qx", "base_qy", "base_qz"]
    true = invert_sensor_effects(out, specs, ctx, targets)
    for c in targets:
        np.testing.assert_allclose(true[c], cols[c], atol=1e-12)
