"""Closed-form leg kinematics (granular_mpc.robot.kinematics) against Pinocchio's forward
kinematics of the same model, and the IK/FK round trip.

Frames: ``leg_fk`` gives the foot frame origin F (``robot.feet.<side>.frame``, the centre
of the sole arc; ``left_foot`` / ``right_foot``) in the trunk frame B. With the floating
base at the world origin and unrotated, B = W, so Pinocchio's ``data.oMf[foot_frame]`` is
the independent reference. Tolerances 1e-12 m / 1e-9 rad: the same chain of rotations and
translations evaluated two ways in double precision (a few ulps of 0.5 m), and acos/atan2
round-off near the limits for the angles.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from granular_mpc.exceptions import ModelError
from granular_mpc.robot.kinematics import (balanced_stance, leg_fk, leg_geometry, leg_ik,
                                           staggered_stance)
from granular_mpc.robot.model import SIDES
from granular_mpc.rotations import rot_x, rot_y


def _leg_slice(side: str) -> slice:
    return slice(0, 3) if side == "left" else slice(3, 6)


def _random_legs(biped, rng, n):
    """Joint angles uniformly inside the position limits with the foot below the abduction
    joint (in the abduction frame): the branch ``leg_ik`` returns (knee limits are > 0, so
    the knee branch is the model's own)."""
    lo, hi = biped.position_limits
    out = []
    while len(out) < n:
        q_a = rng.uniform(lo, hi)
        ok = True
        for side in SIDES:
            g = leg_geometry(biped, side)
            qa, qp, qk = q_a[_leg_slice(side)]
            z_abd = g.p_abd_pitch[2] - g.thigh * np.cos(qp) - g.calf * np.cos(qp + qk)
            ok &= z_abd < -0.02
        if ok:
            out.append(q_a)
    return out


def test_leg_fk_equals_pinocchio_forward_kinematics(biped):
    """Position of F and its orientation rot_x(abd)·rot_y(pitch + knee + mount) agree with
    Pinocchio's frame placement at 200 random joint configurations, both legs."""
    data = biped.create_data()
    rng = np.random.default_rng(11)
    for q_a in _random_legs(biped, rng, 200):
        q = biped.q_from_parts([0.0, 0.0, 0.0], [0, 0, 0, 1], q_a)
        pin.framesForwardKinematics(biped.model, data, q)
        for side in SIDES:
            g = leg_geometry(biped, side)
            q_leg = q_a[_leg_slice(side)]
            oMf = data.oMf[biped.foot_frame[side]]
            np.testing.assert_allclose(leg_fk(g, q_leg), oMf.translation, atol=1e-12)
            R = rot_x(q_leg[0]) @ rot_y(q_leg[1] + q_leg[2] + g.foot_mount_pitch)
            np.testing.assert_allclose(R, oMf.rotation, atol=1e-12)


def test_leg_fk_in_a_moved_trunk_frame(biped):
    """With the trunk translated and rotated, F in B is still leg_fk: B-frame positions
    are what the closed form promises (Pinocchio: oMb⁻¹ · oMf)."""
    data = biped.create_data()
    rng = np.random.default_rng(12)
    for q_a in _random_legs(biped, rng, 20):
        quat = rng.normal(size=4)
        q = biped.q_from_parts(rng.uniform(-1, 1, 3), quat / np.linalg.norm(quat), q_a)
        pin.framesForwardKinematics(biped.model, data, q)
        oMb = data.oMi[1]
        for side in SIDES:
            p_B = (oMb.inverse() * data.oMf[biped.foot_frame[side]]).translation
            np.testing.assert_allclose(leg_fk(leg_geometry(biped, side), q_a[_leg_slice(side)]),
                                       p_B, atol=1e-12)


def test_ik_inverts_fk_in_joint_space(biped):
    rng = np.random.default_rng(13)
    for q_a in _random_legs(biped, rng, 300):
        for side in SIDES:
            g = leg_geometry(biped, side)
            q_leg = q_a[_leg_slice(side)]
            np.testing.assert_allclose(leg_ik(g, leg_fk(g, q_leg)), q_leg, atol=1e-9)


def test_fk_of_ik_reaches_random_reachable_targets(biped):
    """Random targets in a box around the standing foot positions: every one IK accepts
    is reached exactly; the box is large enough that some are out of reach (ModelError)."""
    rng = np.random.default_rng(14)
    reached = refused = 0
    for side in SIDES:
        g = leg_geometry(biped, side)
        p_stand = leg_fk(g, np.array(biped.config.standing_joints)[_leg_slice(side)])
        for _ in range(400):
            target = p_stand + rng.uniform([-0.3, -0.15, -0.2], [0.3, 0.15, 0.25])
            try:
                q_leg = leg_ik(g, target)
            except ModelError as exc:
                assert "out of reach" in str(exc) or "inside the hip" in str(exc)
                refused += 1
                continue
            np.testing.assert_allclose(leg_fk(g, q_leg), target, atol=1e-12)
            assert q_leg[2] >= 0.0                       # the knee bends forward
            reached += 1
    assert reached > 300 and refused > 20, (reached, refused)


def test_out_of_reach_and_inside_the_hip_raise_model_error(biped):
    g = leg_geometry(biped, "left")
    with pytest.raises(ModelError, match="out of reach"):
        leg_ik(g, g.p_B_abd + np.array([0.0, g.p_abd_pitch[1], -(g.thigh + g.calf) - 0.1]))
    with pytest.raises(ModelError, match="inside the hip"):
        leg_ik(g, g.p_B_abd)                          # |(y, z)| < the hip's lateral offset


def test_leg_geometry_rejects_a_foot_frame_not_on_the_knee(biped):
    model = biped.model.copy()
    fid = biped.foot_frame["left"]
    frame = model.frames[fid]
    frame.parentJoint = model.getJointId("left_hip_pitch")
    model.frames[fid] = frame
    with pytest.raises(ModelError, match="must be carried by the knee joint left_knee"):
        leg_geometry(dataclasses.replace(biped, model=model), "left")


def test_staggered_stance_moves_the_feet_apart_at_the_same_height(biped):
    data = biped.create_data()
    q0 = staggered_stance(biped, 0.0)
    q = staggered_stance(biped, 0.08, clearance=0.01)
    pin.framesForwardKinematics(biped.model, data, q0)
    p0 = {s: data.oMf[biped.foot_frame[s]].translation.copy() for s in SIDES}
    pin.framesForwardKinematics(biped.model, data, q)
    p = {s: data.oMf[biped.foot_frame[s]].translation.copy() for s in SIDES}
    # the trunk is level and F moves ±stagger/2 in x relative to the trunk, same height
    np.testing.assert_allclose(q[3:7], [0, 0, 0, 1], atol=1e-15)
    dx = (p["left"] - q[0:3]) - (p0["left"] - q0[0:3])
    np.testing.assert_allclose(dx, [0.04, 0.0, 0.0], atol=1e-12)
    dx = (p["right"] - q[0:3]) - (p0["right"] - q0[0:3])
    np.testing.assert_allclose(dx, [-0.04, 0.0, 0.0], atol=1e-12)
    assert biped.lowest_sole_point(q).min() == pytest.approx(0.01, abs=1e-12)


def test_balanced_stance_puts_the_com_over_the_feet(biped):
    data = biped.create_data()
    q = balanced_stance(biped, clearance=0.002)
    com_x = biped.com(q, data)[0]
    pin.framesForwardKinematics(biped.model, data, q)
    feet_x = np.mean([data.oMf[biped.foot_frame[s]].translation[0] for s in SIDES])
    # the nominal pose is 2.0 mm off; the loop stops below a 1e-7 m shift, measured
    # residual 7.4e-8 m; bound 1e-6 m (13×, and 2000× below the nominal offset)
    assert abs(com_x - feet_x) < 1e-6
    assert biped.lowest_sole_point(q).min() == pytest.approx(0.002, abs=1e-12)
    np.testing.assert_allclose(q[3:7], [0, 0, 0, 1], atol=1e-15)
