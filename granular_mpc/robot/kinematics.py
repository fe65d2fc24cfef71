"""Closed-form leg kinematics of the 3-DoF legs (hip abduction about x, hip pitch and knee
about y, foot frame fixed on the calf), with the geometry read from the Pinocchio model.

Frames: positions are of the foot frame origin ``F`` (centre of the sole arc), expressed
in the trunk frame ``B`` [m]. The knee bends forward (q_knee > 0), as in the standing pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exceptions import ModelError
from .model import SIDES, Biped


@dataclass(frozen=True)
class LegGeometry:
    """Offsets of one leg, read from the model's joint placements [m]."""

    p_B_abd: np.ndarray      # abduction joint in the trunk frame
    p_abd_pitch: np.ndarray  # hip-pitch joint in the abduction frame
    thigh: float             # hip pitch → knee, along −z
    calf: float              # knee → foot frame origin, along −z of the calf
    foot_mount_pitch: float  # foot frame pitch relative to the calf [rad]


def leg_geometry(biped: Biped, side: str) -> LegGeometry:
    model = biped.model
    names = biped.joint_names[:3] if side == "left" else biped.joint_names[3:]
    jids = [model.getJointId(n) for n in names]
    pl = [model.jointPlacements[j] for j in jids]
    foot = model.frames[biped.foot_frame[side]]
    if foot.parentJoint != jids[2]:
        raise ModelError(f"{side} foot frame must be carried by the knee joint {names[2]}")
    for p in (pl[1], pl[2], foot.placement):
        if abs(p.translation[0]) > 1e-9:
            raise ModelError("leg kinematics expects no fore-aft joint offsets")
    rot = foot.placement.rotation
    mount = math.atan2(rot[0, 2], rot[0, 0])
    return LegGeometry(np.array(pl[0].translation), np.array(pl[1].translation),
                       float(-pl[2].translation[2]), float(-foot.placement.translation[2]), mount)


def leg_ik(geom: LegGeometry, p_B_foot: np.ndarray) -> np.ndarray:
    """Joint angles (abd, hip pitch, knee) [rad] placing the foot frame origin at ``p_B_foot``.

    Raises:
        ModelError: if the point is out of reach.
    """
    r = np.asarray(p_B_foot, dtype=float) - geom.p_B_abd
    y_off = geom.p_abd_pitch[1]
    rho2 = r[1] ** 2 + r[2] ** 2 - y_off ** 2
    if rho2 <= 0.0:
        raise ModelError(f"foot target {p_B_foot} is inside the hip")
    z_p = -math.sqrt(rho2)
    q_abd = math.atan2(r[2], r[1]) - math.atan2(z_p, y_off)
    X = r[0]
    Z = z_p - geom.p_abd_pitch[2]
    L1, L2 = geom.thigh, geom.calf
    D2 = X * X + Z * Z
    c = (D2 - L1 * L1 - L2 * L2) / (2.0 * L1 * L2)
    if not -1.0 <= c <= 1.0:
        raise ModelError(f"foot target {p_B_foot} is out of reach (distance {math.sqrt(D2):.3f} m)")
    q_knee = math.acos(c)
    psi = math.atan2(-X, -Z)
    q_pitch = psi - math.atan2(L2 * math.sin(q_knee), L1 + L2 * math.cos(q_knee))
    q_abd = (q_abd + math.pi) % (2.0 * math.pi) - math.pi
    return np.array([q_abd, q_pitch, q_knee])


def leg_fk(geom: LegGeometry, q_leg: np.ndarray) -> np.ndarray:
    """Foot frame origin in the trunk frame for joint angles (abd, pitch, knee) [m]."""
    qa, qp, qk = q_leg
    L1, L2 = geom.thigh, geom.calf
    x = -L1 * math.sin(qp) - L2 * math.sin(qp + qk)
    z = geom.p_abd_pitch[2] - L1 * math.cos(qp) - L2 * math.cos(qp + qk)
    y = geom.p_abd_pitch[1]
    ca, sa = math.cos(qa), math.sin(qa)
    return geom.p_B_abd + np.array([x, ca * y - sa * z, sa * y + ca * z])


def staggered_stance(biped: Biped, stagger: float, *, clearance: float = 0.0) -> np.ndarray:
    """Standing configuration with the left foot ``stagger/2`` ahead of its hip and the right
    foot as far behind, same height as the nominal pose; trunk level; lowest sole point
    ``clearance`` [m] above z = 0. Statically stable in pitch on rolling soles."""
    q_nom = biped.standing_configuration(0.0)
    q_a = np.array(biped.config.standing_joints, dtype=float)
    for k, side in enumerate(SIDES):
        g = leg_geometry(biped, side)
        p = leg_fk(g, q_a[3 * k: 3 * k + 3])
        p[0] += stagger / 2.0 if side == "left" else -stagger / 2.0
        q_a[3 * k: 3 * k + 3] = leg_ik(g, p)
    q = biped.q_from_parts(q_nom[0:3], [0, 0, 0, 1], q_a)
    q[2] = 0.0
    # level the soles' lowest points at the requested clearance
    low = biped.lowest_sole_point(q).min()
    q[2] = clearance - low
    return q


def balanced_stance(biped: Biped, *, clearance: float = 0.0, iterations: int = 4) -> np.ndarray:
    """Standing configuration with the whole-body CoM exactly above the soles' contact line.

    The semi-cylindrical soles roll, so a standing robot is an inverted pendulum on its
    contact line: any fore-aft CoM offset grows as e^{ωt}. Starting from the nominal pose,
    both feet are moved (leg IK, trunk level) until CoM x equals the contact x. Lowest sole
    point ``clearance`` [m] above z = 0.
    """
    q = biped.standing_configuration(clearance)
    q_a = q[biped.idx_q].copy()
    geoms = [leg_geometry(biped, side) for side in SIDES]
    data = biped.create_data()
    for _ in range(iterations):
        q = biped.q_from_parts(q[0:3], [0, 0, 0, 1], q_a)
        com_x = biped.com(q, data)[0]
        pin_fk = biped.lowest_sole_point(q, data)   # refreshes frame placements
        _ = pin_fk
        feet_x = np.mean([data.oMf[biped.foot_frame[s]].translation[0] for s in SIDES])
        shift = com_x - feet_x
        if abs(shift) < 1e-7:
            break
        for k, g in enumerate(geoms):
            p = leg_fk(g, q_a[3 * k: 3 * k + 3])
            p[0] += shift
            q_a[3 * k: 3 * k + 3] = leg_ik(g, p)
    q = biped.q_from_parts([0.0, 0.0, 0.0], [0, 0, 0, 1], q_a)
    q[2] = clearance - biped.lowest_sole_point(q).min()
    return q


__all__ = ["LegGeometry", "leg_geometry", "leg_ik", "leg_fk", "staggered_stance", "balanced_stance"]
