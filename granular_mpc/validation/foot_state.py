"""A foot's contact state where a replay starts: :class:`FootInit` and how it is set
from a measured pose, depth, intrusion and force (:func:`foot_init`).

A replay starts each foot either out of contact above its free surface, or buried at a
measured depth with its touchdown points behind it by the measured intrusion and its
elastic displacement carrying the measured force (−F/(n K) per patch). ``prepare`` sets
the states at a window's first sample, :mod:`.restarts` at a restart within a stance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..robot.model import Biped
from .foot_geometry import patch_points


@dataclass(frozen=True)
class FootInit:
    """Initial contact state of one foot in the local frame.

    Attributes:
        in_contact: the foot starts in contact.
        surface: free-surface height under the foot [m] (local frame, plane through it).
        depth: depth of the contact point below that surface [m].
        point: contact point (mean over patches) at the window start [m] (local frame).
        c0: touchdown point per patch [m] (local frame), shape (n_patches, 3).
        e: elastic displacement per patch [m] (−F/(n K)), shape (n_patches, 3).
        force: measured force on the foot [N] (world axes); without foot force, the
            force estimated from the joint torques.
        depth_max: deepest depth since touchdown [m].
        t_stance: time since touchdown [s].
    """

    in_contact: bool
    surface: float
    depth: float
    point: np.ndarray
    c0: np.ndarray
    e: np.ndarray
    force: np.ndarray
    depth_max: float
    t_stance: float


def foot_init(biped: Biped, data: pin.Data, side: str, *, depth: float,
              intrusion: np.ndarray, force: np.ndarray, in_contact: bool, depth_max: float,
              t_stance: float, K: float, origin: np.ndarray) -> FootInit:
    """Foot ``side``'s state at the pose whose frame placements ``data`` holds.

    Args:
        depth: depth of its contact point below its free surface [m] (< 0: above it).
        intrusion: (x_s, y_s, z_s) of the contact point from its touchdown point [m].
        force: the force on it [N] (world axes); sets the elastic displacement.
        in_contact: buried (else the foot is in the air over that surface).
        depth_max: its deepest depth since touchdown [m]; t_stance: time since then [s].
        K: contact stiffness per patch [N/m].
        origin: world position of the local frame's origin [m].
    """
    oMf = data.oMf[biped.foot_frame[side]]
    pts = patch_points(biped, oMf) - origin          # local frame
    n = len(pts)
    point = pts.mean(axis=0)
    surface = float(point[2] + depth)            # depth < 0: the foot is above the surface
    depth = max(float(depth), 0.0)
    if not in_contact:
        return FootInit(False, surface, 0.0, point, np.zeros((n, 3)), np.zeros((n, 3)),
                        np.zeros(3), 0.0, 0.0)
    c0 = pts - np.array([intrusion[0], intrusion[1], -depth])
    e = np.tile(-np.asarray(force, dtype=float) / (n * K), (n, 1))
    return FootInit(True, surface, depth, point, c0, e, np.asarray(force, dtype=float),
                    max(float(depth_max), depth), float(t_stance))


__all__ = ["FootInit", "foot_init"]
