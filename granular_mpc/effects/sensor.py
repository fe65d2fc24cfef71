"""Effects of kind ``sensor``: changes of the measurement only, after the plant has run.

Each is ``fn(cols, p, ctx) -> {column: values}``: ``cols`` maps format-v1 column names to
NumPy arrays of one trial (or a replayed prediction of it), ``ctx`` is a
:class:`~granular_mpc.effects.state.SensorContext`; it returns the columns it changes as
new arrays. :func:`apply_sensor_effects` applies several in order. Library:
``force_sensor_bias``.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from .api import register_sensor_effect
from .params import Param
from .registry import EffectInfo
from .state import SensorContext


@register_sensor_effect("force_sensor_bias", params={
    "bias_x": Param(0.0, -50.0, 50.0, "N", "offset of grf_x"),
    "bias_y": Param(0.0, -50.0, 50.0, "N", "offset of grf_y"),
    "bias_z": Param(6.0, -50.0, 50.0, "N", "offset of grf_z"),
}, main="bias_z", neutral={"bias_x": 0.0, "bias_y": 0.0, "bias_z": 0.0},
    depends_on=("nothing: constant on every stance sample",))
def force_sensor_bias(cols, p, ctx: SensorContext):
    """Constant offset of the foot force sensor (zero drift), world axes.

    grf_i ← grf_i + b_i on every row with a stance foot (rows without one stay 0).
    """
    on = ctx.in_stance
    return {f"grf_{ax}": np.asarray(cols[f"grf_{ax}"], dtype=float) + p[f"bias_{ax}"] * on
            for ax in "xyz"}


def apply_sensor_effects(cols: Mapping[str, np.ndarray],
                         specs: Sequence[tuple[EffectInfo, Mapping[str, float]]],
                         ctx: SensorContext) -> dict[str, np.ndarray]:
    """The columns after the sensor effects of ``specs`` (in order; other kinds skipped);
    columns they do not return are unchanged, ``cols`` itself is not modified.

    Args:
        cols: format-v1 columns of one trial.
        specs: ``(EffectInfo, parameter values)`` per effect.
        ctx: stance labels, time, joint names of the trial.
    """
    out = dict(cols)
    for info, p in specs:
        if info.kind != "sensor":
            continue
        changed = info.fn(out, dict(p), ctx)
        for k, v in changed.items():
            out[k] = np.asarray(v, dtype=float)
    return out


__all__ = ["force_sensor_bias", "apply_sensor_effects"]
