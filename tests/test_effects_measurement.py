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
        "force_sensor_gain": ({"gain_z": 0.1}, {"grf_z"}),
        "torque_time_offset": ({"delay": 0.01}, {f"tau_{j}" for j in JOINTS}),
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
    # a 2-sample lag: the measured torque at t is the true one at t − 10 ms
    out, _ = _apply("torque_time_offset", {"delay": 0.01}, cols, ctx)
    assert np.allclose(out["tau_left_knee"][2:], cols["tau_left_knee"][:-2])


def test_replay_inversion_recovers_the_truth(cols, ctx):
    for name, values, targets in (
            ("torque_gain", {"gain_left_knee": 0.2, "gain_right_hip_abd": -0.1},
             ["tau_left_knee", "tau_right_hip_abd"]),
            ("torque_offset", {"offset_left_knee": 1.5}, ["tau_left_knee"]),
            ("encoder_offset", {"delta_right_knee": -0.04}, ["q_right_knee"])):
        meas, specs = _apply(name, values, cols, ctx)
        true = invert_sensor_effects(meas, specs, ctx, targets)
        for c in targets:
            assert np.allclose(true[c], cols[c], atol=1e-9), (name, c)
