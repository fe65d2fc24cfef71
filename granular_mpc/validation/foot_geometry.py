"""Where a curved foot touches the ground: its lowest sole point per slice and its pitch.

The foot's sole is a circular arc (``robot.foot``: radius R, half angle α) around the
foot frame's origin F, split across its width into ``slices`` (contact patches). Its
lowest point lies at the arc angle ψ = atan2(−e_x,z, e_z,z) from the foot's −z axis,
clamped to ±α (beyond that the foot stands on the toe or heel edge). Shared by the
stance windows (:mod:`.prepare`) and the trunk-state estimator (:mod:`.estimation`).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..robot.model import Biped


def sole_angle(biped: Biped, oMf: pin.SE3) -> float:
    """Arc angle ψ of the lowest sole point, clamped to the sole's half angle [rad]
    (positive: toward the foot's +x, the toe)."""
    R = oMf.rotation
    half = biped.config.foot.half_angle
    psi = math.atan2(-R[2, 0], R[2, 2])
    return min(max(psi, -half), half)


def patch_points(biped: Biped, oMf: pin.SE3) -> np.ndarray:
    """Lowest sole point of each slice (patch) of a foot at placement ``oMf`` [m] (W),
    shape (n_slices, 3) — the float twin of :func:`granular_mpc.terrain.contact.slice_geometry`."""
    foot = biped.config.foot
    R = oMf.rotation
    e_x, e_y, e_z = R[:, 0], R[:, 1], R[:, 2]
    psi = sole_angle(biped, oMf)
    base = oMf.translation + foot.radius * math.sin(psi) * e_x - foot.radius * math.cos(psi) * e_z
    return np.array([base + y * e_y for y in biped.slice_offsets])


def foot_pitch(oMf: pin.SE3) -> float:
    """ψ_c: angle from world-down to the foot's −z axis, positive toward its heading [rad]."""
    R = oMf.rotation
    return -math.atan2(-R[2, 0], R[2, 2])


def foot_pitch_rows(rot: np.ndarray) -> np.ndarray:
    """:func:`foot_pitch` of the placements' rotations ``rot`` (n, 3, 3), per row [rad]."""
    return -np.arctan2(-rot[:, 2, 0], rot[:, 2, 2])


def contact_point_rows(biped: Biped, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """``patch_points(...).mean(axis=0)`` — the mean lowest sole point over the slices,
    the contact point C — for placements given as rows: translations ``pos`` (n, 3) [m]
    and rotations ``rot`` (n, 3, 3), W; returns (n, 3) [m]."""
    foot = biped.config.foot
    psi = np.clip(np.arctan2(-rot[:, 2, 0], rot[:, 2, 2]), -foot.half_angle, foot.half_angle)
    base = (pos + (foot.radius * np.sin(psi))[:, None] * rot[:, :, 0]
            - (foot.radius * np.cos(psi))[:, None] * rot[:, :, 2])
    return base + float(np.mean(biped.slice_offsets)) * rot[:, :, 1]


__all__ = ["sole_angle", "patch_points", "foot_pitch", "foot_pitch_rows", "contact_point_rows"]
