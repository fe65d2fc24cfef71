"""Foot forces from the foot frame to the world frame, through the leg kinematics and the
trunk orientation.

A six-axis sensor in the foot measures the force in its own frame. With the sensor frame
equal to the robot's foot frame ``F`` (``docs/notation.md``)::

    f_W = R_WB(q_base) · R_BF(q_leg) · f_F

where R_WB is the trunk orientation (``base_q*``, w, x, y, z) and R_BF the foot frame's
orientation in the trunk frame from the robot's forward kinematics (Pinocchio, trunk at
the origin). Both the ``joint_angles`` and the ``trunk_orientation`` channels are needed.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..columns import BASE_QUATERNION, joint_columns
from ..robot.model import Biped
from ..rotations import matrix_from_quat_wxyz


def foot_rotations(biped: Biped, side: str, q_joints: np.ndarray) -> np.ndarray:
    """R_BF of ``side``'s foot frame for each row of actuated joint angles, shape (n, 3, 3)."""
    data = biped.create_data()
    out = np.empty((len(q_joints), 3, 3))
    for k, q_a in enumerate(q_joints):
        q = biped.q_from_parts([0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], q_a)
        pin.framesForwardKinematics(biped.model, data, q)
        out[k] = data.oMf[biped.foot_frame[side]].rotation
    return out


def foot_force_to_world(biped: Biped, side: str, values: dict[str, np.ndarray],
                        force: np.ndarray) -> np.ndarray:
    """f_W = R_WB R_BF f_F per row [N].

    Args:
        biped: the robot.
        side: ``"left"`` or ``"right"``.
        values: the aligned columns (``q_*`` and ``base_q*`` are read).
        force: (n, 3) force in the foot frame F [N].
    """
    q_a = np.column_stack([values[c] for c in joint_columns(biped.joint_names, "q")])
    r_bf = foot_rotations(biped, side, q_a)
    quat = np.column_stack([values[c] for c in BASE_QUATERNION])
    r_wb = np.array([matrix_from_quat_wxyz(row / np.linalg.norm(row)) for row in quat])
    return np.einsum("nij,njk,nk->ni", r_wb, r_bf, force)


__all__ = ["foot_rotations", "foot_force_to_world"]
