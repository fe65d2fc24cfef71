"""What every replay returns: the predicted channels through the sensor effects, and the
initial patch state every replayer sets from a window."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ...columns import GRF_COLUMNS, INTRUSION_COLUMNS, joint_columns
from ...effects import SensorContext, apply_sensor_effects
from ..prepare import FootInit, StanceWindow
from .model import Variant


def replay_outputs(qa: np.ndarray, grf: np.ndarray, intr: np.ndarray, other_grf_z: np.ndarray,
                   diverged: bool, variant: Variant | None, w: StanceWindow,
                   J: Sequence[str]) -> dict:
    """A replay's predicted channels (format v1 names, through the variant's sensor
    effects), the other foot's vertical force and the divergence flag.

    Args:
        qa: joint angles [rad], (n, len(J)); grf: stance-foot force [N] (world axes),
            (n, 3); intr: stance-foot intrusion [m], (n, 3); other_grf_z: the other
            foot's vertical force [N], (n,).
        diverged: the replay stopped early.
        variant: its sensor effects are applied to the channels.
        w: the replayed window; J: joint names (actuator order).
    """
    out = {col: qa[:, c] for c, col in enumerate(joint_columns(J, "q"))}
    for c, (g, i) in enumerate(zip(GRF_COLUMNS, INTRUSION_COLUMNS)):
        out[g] = grf[:, c]
        out[i] = intr[:, c]
    out = apply_variant_sensors(out, variant, w, J)
    out["other_grf_z"] = other_grf_z
    out["diverged"] = diverged
    return out


def set_foot_state(buf, fi: FootInit, vel: np.ndarray) -> None:
    """Initial contact state of one foot's patches (touchdown point, elastic displacement,
    in contact, patch velocities [m/s], deepest depth [m], time in stance [s]) from the
    window's :class:`~..prepare.FootInit`."""
    st = buf.state
    st[:, 0:3] = fi.e
    st[:, 3:6] = fi.c0
    st[:, 6] = 1.0
    st[:, 7:10] = vel
    st[:, 10] = fi.depth_max
    st[:, 11] = fi.t_stance


def apply_variant_sensors(out: dict, variant: Variant | None, w: StanceWindow,
                          J: Sequence[str]) -> dict:
    """``out`` through the variant's sensor effects (unchanged without any).

    The effects see every column of the data format: the replayed channels of ``out``
    and, for the others (``tau_*``, ``dq_*``, ``base_*``, ``time``), the window's measured
    columns; only the keys of ``out`` are returned."""
    if variant is None or not variant.sensors:
        return out
    ctx = SensorContext(np.full(w.n, w.side, dtype=object), w.time, tuple(J))
    cols = {c: np.asarray(v, dtype=float) for c, v in w.columns.items()}
    cols.update(out)                         # the replayed channels replace the measured
    changed = apply_sensor_effects(cols, list(variant.sensors), ctx)
    return {c: changed[c] for c in out}


__all__ = ["replay_outputs", "set_foot_state", "apply_variant_sensors"]
