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
