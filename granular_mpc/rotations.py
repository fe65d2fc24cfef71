"""Rotations: quaternions, matrices, roll-pitch-yaw, in one place.

Conventions (``docs/notation.md``):

* Two quaternion component orders meet in this package. Pinocchio's configuration vector
  stores the trunk quaternion as ``(x, y, z, w)`` (``q[3:7]``); data format v1 stores it
  as ``(w, x, y, z)`` (``base_qw, base_qx, base_qy, base_qz``). Every function here names
  its order: ``..._xyzw`` or ``..._wxyz``. Quaternions are Hamilton, unit, active
  (``R_W_B`` maps trunk-frame vectors into the world frame).
* Roll-pitch-yaw are Z-Y-X Euler angles: ``R = Rz(yaw) Ry(pitch) Rx(roll)``, in rad.

Scalar functions take one quaternion (a length-4 sequence); the ``*_rows`` functions take
``(n, 4)`` arrays and return one result per row. This module imports nothing from the
package.
"""

from __future__ import annotations

import math

import numpy as np


def xyzw_from_wxyz(quat_wxyz: np.ndarray) -> np.ndarray:
    """Reorder ``(w, x, y, z)`` → ``(x, y, z, w)``; works on one quaternion or rows."""
    quat_wxyz = np.asarray(quat_wxyz, dtype=float)
    return quat_wxyz[..., [1, 2, 3, 0]]


def _components(quat) -> list:
    """The four components of one quaternion as Python floats (the values ``float(c)``
    gives per component; one ``tolist`` for a float64 array, the hot path)."""
    if type(quat) is np.ndarray and quat.dtype == np.float64 and quat.ndim == 1:
        return quat.tolist()
    return [float(c) for c in quat]


def wxyz_from_xyzw(quat_xyzw: np.ndarray) -> np.ndarray:
    """Reorder ``(x, y, z, w)`` → ``(w, x, y, z)``; works on one quaternion or rows."""
    quat_xyzw = np.asarray(quat_xyzw, dtype=float)
    return quat_xyzw[..., [3, 0, 1, 2]]


def matrix_from_quat_xyzw(quat_xyzw) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion ``(x, y, z, w)`` (not renormalised)."""
    x, y, z, w = _components(quat_xyzw)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_from_quat_wxyz(quat_wxyz) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion ``(w, x, y, z)`` (not renormalised)."""
    w, x, y, z = quat_wxyz
    return matrix_from_quat_xyzw((x, y, z, w))


def normalized_matrix_from_quat_xyzw(quat_xyzw) -> np.ndarray:
    """Like :func:`matrix_from_quat_xyzw`, after scaling the quaternion to unit norm."""
    qv = np.asarray(quat_xyzw, dtype=float)
    return matrix_from_quat_xyzw(qv / np.linalg.norm(qv))


def roll_pitch_from_quat_xyzw(quat_xyzw) -> tuple[float, float]:
    """Roll and pitch [rad] (Z-Y-X Euler) of a unit quaternion ``(x, y, z, w)``."""
    x, y, z, w = _components(quat_xyzw)
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return roll, pitch


def rpy_from_quat_xyzw(quat_xyzw) -> tuple[float, float, float]:
    """Roll, pitch, yaw [rad] (Z-Y-X Euler) of a unit quaternion ``(x, y, z, w)``."""
    x, y, z, w = _components(quat_xyzw)
    roll, pitch = roll_pitch_from_quat_xyzw((x, y, z, w))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def rpy_rows_from_quat_wxyz(quat_wxyz: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw [rad] per row (shape (n, 3)) of ``(n, 4)`` quaternions ``(w, x, y, z)``."""
    q = np.asarray(quat_wxyz, dtype=float)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.column_stack([roll, pitch, yaw])


def quat_mul_rows_wxyz(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` of ``(n, 4)`` arrays of ``(w, x, y, z)`` quaternions."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    w1, x1, y1, z1 = a.T
    w2, x2, y2, z2 = b.T
    return np.column_stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def quat_rows_wxyz_from_rotvec(rotvec: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(w, x, y, z)`` of ``(n, 3)`` rotation vectors [rad] (axis × angle)."""
    rv = np.asarray(rotvec, dtype=float)
    ang = np.linalg.norm(rv, axis=1)
    half = 0.5 * ang
    safe = np.where(ang > 1e-12, ang, 1.0)
    s = np.where(ang > 1e-12, np.sin(half) / safe, 0.5)
    return np.column_stack([np.cos(half), rv * s[:, None]])


def rot_x(angle: float) -> np.ndarray:
    """Rotation (3, 3) about x by ``angle`` [rad]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    """Rotation (3, 3) about y by ``angle`` [rad]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    """Rotation (3, 3) about z by ``angle`` [rad] (yaw)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def skew(r) -> np.ndarray:
    """Cross-product matrix: ``skew(r) @ v == np.cross(r, v)``."""
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def skew_rows(r: np.ndarray) -> np.ndarray:
    """Cross-product matrices (..., 3, 3) of stacked 3-vectors ``r`` (..., 3):
    ``skew_rows(r)[i] == skew(r[i])``."""
    r = np.asarray(r, dtype=float)
    out = np.zeros(r.shape + (3,))
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    out[..., 0, 1], out[..., 0, 2] = -z, y
    out[..., 1, 0], out[..., 1, 2] = z, -x
    out[..., 2, 0], out[..., 2, 1] = -y, x
    return out

