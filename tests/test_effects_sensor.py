"""Sensor effects (granular_mpc.effects.sensor): the library's force-sensor bias applied to
the columns of a trial, stance rows only, input untouched."""
from __future__ import annotations

import numpy as np

from granular_mpc.effects import SensorContext, apply_sensor_effects, effect_info


def test_force_sensor_bias_shifts_stance_rows_only():
    info = effect_info("force_sensor_bias")
    stance = np.array(["left", "left", "none", "right"], dtype=object)
    cols = {f"grf_{a}": np.array([1.0, 2.0, 0.0, 3.0]) for a in "xyz"}
    ctx = SensorContext(stance, np.arange(4) * 0.002, ("a",))
    out = apply_sensor_effects(cols, [(info, {"bias_x": 1.0, "bias_y": 0.0, "bias_z": -2.0})], ctx)
    np.testing.assert_allclose(out["grf_x"], [2.0, 3.0, 0.0, 4.0])
    np.testing.assert_allclose(out["grf_z"], [-1.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(cols["grf_z"], [1.0, 2.0, 0.0, 3.0])        # input untouched


def test_check_sensor_effect_names_the_effect_and_the_missing_column():
    import pytest

    from granular_mpc.effects import EffectInfo, Param, check_sensor_effect
    from granular_mpc.exceptions import ConfigError

    def reads_torque(cols, p, ctx):
        return {"tau_a": np.asarray(cols["tau_a"]) * p["g"]}

    info = EffectInfo("_t_gain", "sensor", {"g": Param(1.0, 0.5, 2.0)}, reads_torque)
    ctx = SensorContext(np.array(["left"] * 3, dtype=object), np.arange(3) * 0.01, ("a",))
    assert check_sensor_effect(info, {"g": 1.1}, {"tau_a": np.ones(3)}, ctx) == ("tau_a",)
    with pytest.raises(ConfigError, match="_t_gain.*'tau_a'"):
        check_sensor_effect(info, {"g": 1.1}, {"q_a": np.ones(3)}, ctx)


def test_invert_sensor_effects_recovers_the_true_columns():
    from granular_mpc.effects import EffectInfo, Param, invert_sensor_effects

    def gain_offset(cols, p, ctx):
        return {"tau_a": p["g"] * np.asarray(cols["tau_a"]) + p["b"]}

    info = EffectInfo("_t_go", "sensor", {"g": Param(1.0, 0.5, 2.0), "b": Param(0.0, -5, 5)},
                      gain_offset)
    ctx = SensorContext(np.array(["left"] * 4, dtype=object), np.arange(4) * 0.01, ("a",))
    true = np.array([-2.0, 0.0, 0.5, 3.0])
    meas = apply_sensor_effects({"tau_a": true, "q_a": np.ones(4)},
                                [(info, {"g": 1.3, "b": 0.4})], ctx)
    back = invert_sensor_effects(meas, [(info, {"g": 1.3, "b": 0.4})], ctx, ["tau_a"])
    np.testing.assert_allclose(back["tau_a"], true, atol=1e-9)
    np.testing.assert_array_equal(back["q_a"], np.ones(4))
