"""Trunk attitude of a log: roll, pitch, yaw per row.

The one place that turns a log's trunk quaternions into attitude angles (summaries, CoT,
plots and replays use it rather than converting them again).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..columns import BASE_QUATERNION
from ..rotations import rpy_rows_from_quat_wxyz


def trunk_rpy(log: pd.DataFrame) -> np.ndarray:
    """Trunk roll, pitch, yaw [rad] per row, R_W_B = Rz(yaw) Ry(pitch) Rx(roll).

    From the columns ``base_qw, base_qx, base_qy, base_qz``
    (:data:`~granular_mpc.columns.BASE_QUATERNION`), each row scaled to unit norm first
    (:func:`~granular_mpc.rotations.rpy_rows_from_quat_wxyz`); shape (n, 3).
    """
    quat = log[list(BASE_QUATERNION)].to_numpy(dtype=float)
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return rpy_rows_from_quat_wxyz(quat)


__all__ = ["trunk_rpy"]
