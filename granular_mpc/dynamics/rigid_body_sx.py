"""Floating-base rigid-body algorithms written in CasADi SX over a Pinocchio model's tree.

The compiled plant step (:mod:`granular_mpc.dynamics.compiled`) needs the forward dynamics
of the biped as a symbolic expression so that rigid-body dynamics, the terrain law of both
feet and the integrator become one straight-line C function. This module rewrites, for
the joint types of the project's robots, exactly the Pinocchio algorithms the reference
:class:`~granular_mpc.dynamics.plant.Plant` calls:

* :func:`placements` — ``pinocchio.forwardKinematics`` (placements only): ``liMi`` (joint
  in parent) and ``oMi`` (joint in W) per joint;
* :func:`velocities` — the joint spatial velocities, local frames;
* :func:`frame_kinematics` — ``updateFramePlacement`` + ``getFrameVelocity(…,
  LOCAL_WORLD_ALIGNED)`` of a frame fixed on a joint;
* :func:`aba` — ``pinocchio.aba`` with external forces (Featherstone's articulated-body
  algorithm as Pinocchio implements it: spatial quantities in the joint frames, motion
  ``(linear, angular)``, gravity as the acceleration ``−g`` of the universe, external
  forces in the local joint frames), also used with zero velocity, gravity and external
  forces to apply ``M(q)⁻¹`` to a torque (what ``computeMinverse(q) @ τ`` gives);
* :func:`integrate` — ``pinocchio.integrate`` (free flyer: ``M₁ = M₀ · exp6(v)``, written
  with quaternions; Pinocchio's Taylor thresholds and first-order renormalisation).

Supported joints: the free flyer (root), revolute about a placement axis (``RX``, ``RY``,
``RZ``) and prismatic (``PX``, ``PY``, ``PZ``); anything else raises
:class:`~granular_mpc.exceptions.ModelError`. Conventions are Pinocchio's: ``q = [p_W_B,
quat (x, y, z, w), q_a]``, ``v = [v_B, ω_B, q̇_a]`` (base twist in the trunk frame B).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
import pinocchio as pin

from ..exceptions import ModelError

#: Pinocchio's TaylorSeriesExpansion<double>::precision<3>() = ε^(1/4), below which exp6
#: switches to its Taylor expansions
_TAYLOR3 = float(np.finfo(float).eps) ** 0.25

_AXES = {"X": 0, "Y": 1, "Z": 2}


@dataclass(frozen=True)
class TreeJoint:
    """One joint of the kinematic tree (Pinocchio indices; SI units, parent-joint frame).

    Attributes:
        kind: ``"free"``, ``"revolute"`` or ``"prismatic"``.
        axis: 0, 1, 2 for x, y, z (revolute/prismatic), -1 for the free flyer.
        parent: parent joint index (0 = universe).
        idx_q, idx_v: first index in q and v.
        R_place, p_place: joint placement in the parent joint frame.
        mass [kg], com [m] (in the joint frame), inertia_com [kg·m²] (about the CoM).
    """

    kind: str
    axis: int
    parent: int
    idx_q: int
    idx_v: int
    R_place: np.ndarray
    p_place: np.ndarray
    mass: float
    com: np.ndarray
    inertia_com: np.ndarray


def tree_from_model(model: pin.Model) -> tuple[TreeJoint, ...]:
    """The joints 1 … njoints-1 of ``model`` as :class:`TreeJoint` (index i-1 ↔ joint i)."""
    if np.any(np.asarray(model.armature) != 0.0):
        raise ModelError("rotor inertia (model.armature) is not supported by the compiled "
                         "plant")
    joints = []
    for j in range(1, model.njoints):
        short = model.joints[j].shortname()
        if short == "JointModelFreeFlyer":
            if model.parents[j] != 0:
                raise ModelError("the free flyer must be the root joint")
            kind, axis = "free", -1
        elif short[:-1] in ("JointModelR", "JointModelP") and short[-1] in _AXES:
            kind = "revolute" if short[:-1] == "JointModelR" else "prismatic"
            axis = _AXES[short[-1]]
        else:
            raise ModelError(f"joint {model.names[j]!r}: type {short} is not supported by the "
                             "compiled plant (free flyer, RX/RY/RZ, PX/PY/PZ)")
        M, Y = model.jointPlacements[j], model.inertias[j]
        joints.append(TreeJoint(kind, axis, int(model.parents[j]), int(model.idx_qs[j]),
                                int(model.idx_vs[j]), np.array(M.rotation), np.array(M.translation),
                                float(Y.mass), np.array(Y.lever), np.array(Y.inertia)))
    return tuple(joints)


# ------------------------------------------------------------------ small SX algebra
def skew(r) -> ca.SX:
    """Cross-product matrix of a 3-vector (SX): ``skew(r) @ v == r × v``."""
    return ca.vertcat(ca.horzcat(0, -r[2], r[1]), ca.horzcat(r[2], 0, -r[0]),
                      ca.horzcat(-r[1], r[0], 0))


def quat_matrix(x, y, z, w) -> ca.SX:
    """Rotation matrix of a unit quaternion (x, y, z, w) (Eigen's formula, not renormalised)."""
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
        ca.horzcat(2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
        ca.horzcat(2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)))


def _axis_rotation(axis: int, angle) -> ca.SX:
    c, s = ca.cos(angle), ca.sin(angle)
    if axis == 0:
        return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))
    if axis == 1:
        return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))


def _unit(axis: int) -> ca.SX:
    e = [0.0, 0.0, 0.0]
    e[axis] = 1.0
    return ca.SX(ca.DM(e))


def _spatial_inertia(j: TreeJoint) -> ca.SX:
    """Pinocchio's 6×6 inertia (linear, angular): [[m I, −m[c]×], [m[c]×, I_c − m[c]×²]]."""
    m, C = j.mass, np.array([[0.0, -j.com[2], j.com[1]], [j.com[2], 0.0, -j.com[0]],
                             [-j.com[1], j.com[0], 0.0]])
    top = np.hstack([m * np.eye(3), -m * C])
    bottom = np.hstack([m * C, j.inertia_com - m * C @ C])
    return ca.SX(ca.DM(np.vstack([top, bottom])))


# ------------------------------------------------------------------ kinematics
@dataclass
class Placements:
    """Joint placements at one configuration (SX): per joint (index j-1) R, p in parent and W."""

    R_li: list
    p_li: list
    R_o: list
    p_o: list


def placements(tree, q) -> Placements:
    """Forward kinematics (placements) at configuration ``q`` (SX, nq)."""
    out = Placements([], [], [], [])
    for j in tree:
        if j.kind == "free":
            R_J = quat_matrix(q[j.idx_q + 3], q[j.idx_q + 4], q[j.idx_q + 5], q[j.idx_q + 6])
            p_J = q[j.idx_q: j.idx_q + 3]
        elif j.kind == "revolute":
            R_J, p_J = _axis_rotation(j.axis, q[j.idx_q]), None
        else:
            R_J, p_J = ca.SX.eye(3), _unit(j.axis) * q[j.idx_q]
        Rp = ca.SX(ca.DM(j.R_place))
        R = R_J if np.allclose(j.R_place, np.eye(3), atol=0.0) else Rp @ R_J
        p = ca.SX(ca.DM(j.p_place))
        if p_J is not None:
            p = p + Rp @ p_J
        out.R_li.append(R)
        out.p_li.append(p)
        if j.parent == 0:
            out.R_o.append(R)
            out.p_o.append(p)
        else:
            Rpar, ppar = out.R_o[j.parent - 1], out.p_o[j.parent - 1]
            out.R_o.append(Rpar @ R)
            out.p_o.append(ppar + Rpar @ p)
    return out


def _joint_motion(j: TreeJoint, v):
    """Joint velocity (linear, angular) in the joint frame, and the motion subspace S (6×k)."""
    if j.kind == "free":
        return v[j.idx_v: j.idx_v + 3], v[j.idx_v + 3: j.idx_v + 6], ca.SX.eye(6)
    e = _unit(j.axis)
    zero = ca.SX.zeros(3, 1)
    if j.kind == "revolute":
        return zero, e * v[j.idx_v], ca.vertcat(zero, e)
    return e * v[j.idx_v], zero, ca.vertcat(e, zero)


def _act_inv_motion(R, p, lin, ang):
    """Parent-frame motion → child frame: ω = Rᵀω', v = Rᵀ(v' − p × ω')."""
    return R.T @ (lin - ca.cross(p, ang)), R.T @ ang


def velocities(tree, pl: Placements, v) -> list:
    """Spatial velocity (linear, angular) of every joint in its own frame (SX)."""
    out = []
    for j, R, p in zip(tree, pl.R_li, pl.p_li):
        lin, ang, _ = _joint_motion(j, v)
        if j.parent > 0:
            plin, pang = _act_inv_motion(R, p, *out[j.parent - 1])
            lin, ang = lin + plin, ang + pang
        out.append((lin, ang))
    return out


def frame_kinematics(pl: Placements, vel: list, joint: int, R_frame: np.ndarray,
                     p_frame: np.ndarray):
    """Placement and LOCAL_WORLD_ALIGNED velocity of a frame fixed on joint ``joint``.

    Returns:
        ``(p_W [m], R_W (3×3), v_W [m/s] of the frame origin, ω_W [rad/s])`` as SX.
    """
    R_o, p_o = pl.R_o[joint - 1], pl.p_o[joint - 1]
    pf = ca.SX(ca.DM(p_frame))
    lin, ang = vel[joint - 1]
    return (p_o + R_o @ pf, R_o @ ca.SX(ca.DM(R_frame)), R_o @ (lin + ca.cross(ang, pf)),
            R_o @ ang)


# ------------------------------------------------------------------ dynamics
def _force_transform(R, p) -> ca.SX:
    """X* (6×6) taking a force (linear, angular) from a joint frame to its parent frame."""
    PR = skew(p) @ R
    return ca.vertcat(ca.horzcat(R, ca.SX.zeros(3, 3)), ca.horzcat(PR, R))


def _spd_solve(A, b):
    """Solve A x = b for a symmetric positive definite SX matrix A (Cholesky, unrolled)."""
    n = A.shape[0]
    L = [[None] * n for _ in range(n)]
    for i in range(n):
        for k in range(i + 1):
            s = A[i, k]
            for m in range(k):
                s = s - L[i][m] * L[k][m]
            L[i][k] = ca.sqrt(s) if i == k else s / L[k][k]
    y = [None] * n
    for i in range(n):
        s = b[i]
        for m in range(i):
            s = s - L[i][m] * y[m]
        y[i] = s / L[i][i]
    x = [None] * n
    for i in reversed(range(n)):
        s = y[i]
        for m in range(i + 1, n):
            s = s - L[m][i] * x[m]
        x[i] = s / L[i][i]
    return ca.vertcat(*x)


def aba(tree, pl: Placements, nv: int, tau, *, v=None, fext=None, gravity=None):
    """Generalised acceleration ``a = M(q)⁻¹ (τ + Σ J_iᵀ f_i − h(q, v))`` (Pinocchio's ABA).

    Args:
        tree: :func:`tree_from_model`.
        pl: :func:`placements` at q.
        nv: size of v.
        tau: generalised forces (SX, nv) [N, N·m].
        v: generalised velocity (SX, nv), or None for zero (no velocity terms).
        fext: per joint (index j-1) an external force (SX 6: linear, angular) in the local
            joint frame, or None.
        gravity: gravity vector in W [m/s²] (3 floats), or None for none.

    Returns:
        SX (nv) generalised acceleration; with ``v``, ``fext`` and ``gravity`` None this is
        ``M(q)⁻¹ τ``.
    """
    n = len(tree)
    S, c, Ia, pA = [], [], [], []
    vel = velocities(tree, pl, v) if v is not None else None
    for i, j in enumerate(tree):
        I6 = _spatial_inertia(j)
        _, _, Sj = _joint_motion(j, ca.SX.zeros(nv, 1))
        S.append(Sj)
        Ia.append(I6)
        if vel is None:
            c.append(None)
            f = ca.SX.zeros(6, 1)
        else:
            lin, ang = vel[i]
            if j.kind == "free":
                c.append(None)           # v × v_J = v × v = 0 for the root
            else:
                jl, ja, _ = _joint_motion(j, v)
                # c = v × v_J (motion cross product)
                c.append(ca.vertcat(ca.cross(ang, jl) + ca.cross(lin, ja), ca.cross(ang, ja)))
            h = I6 @ ca.vertcat(lin, ang)
            hl, ha = h[0:3], h[3:6]
            # f = v ×* h (force cross product)
            f = ca.vertcat(ca.cross(ang, hl), ca.cross(ang, ha) + ca.cross(lin, hl))
        if fext is not None and fext[i] is not None:
            f = f - fext[i]
        pA.append(f)
    U, Dinv, u = [None] * n, [None] * n, [None] * n
    for i in reversed(range(n)):
        j = tree[i]
        tau_j = tau[j.idx_v: j.idx_v + S[i].shape[1]]
        if j.kind == "free":
            u[i] = tau_j - pA[i]
            continue
        U[i] = Ia[i] @ S[i]
        Dinv[i] = 1.0 / (S[i].T @ U[i])
        u[i] = tau_j - S[i].T @ pA[i]
        if j.parent > 0:
            Ia_A = Ia[i] - U[i] @ Dinv[i] @ U[i].T
            pa = pA[i] + U[i] @ (Dinv[i] * u[i])
            if c[i] is not None:
                pa = pa + Ia_A @ c[i]
            X = _force_transform(pl.R_li[i], pl.p_li[i])
            Ia[j.parent - 1] = Ia[j.parent - 1] + X @ Ia_A @ X.T
            pA[j.parent - 1] = pA[j.parent - 1] + X @ pa
    acc = [None] * n
    out = [None] * nv
    for i, j in enumerate(tree):
        if j.parent == 0:
            g = ca.SX.zeros(3, 1) if gravity is None else ca.SX(ca.DM(gravity))
            # a_0 = −g in W, seen in the root joint frame (no angular part)
            alin, aang = _act_inv_motion(pl.R_li[i], pl.p_li[i], -g, ca.SX.zeros(3, 1))
        else:
            alin, aang = _act_inv_motion(pl.R_li[i], pl.p_li[i], *acc[j.parent - 1])
        a = ca.vertcat(alin, aang)
        if c[i] is not None:
            a = a + c[i]
        if j.kind == "free":
            qdd = _spd_solve(Ia[i], u[i] - Ia[i] @ a)
        else:
            qdd = Dinv[i] * (u[i] - U[i].T @ a)
        a = a + S[i] @ qdd
        acc[i] = (a[0:3], a[3:6])
        for k in range(qdd.shape[0]):
            out[j.idx_v + k] = qdd[k]
    return ca.vertcat(*out)


# ------------------------------------------------------------------ integration
def _quat_mul(a, b):
    """Hamilton product of quaternions given as (x, y, z, w) tuples."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def integrate(tree, q, dv):
    """``pinocchio.integrate(model, q, dv)`` (SX): joints' configuration moved by ``dv``.

    The free flyer follows ``M₁ = M₀ · exp6(dv)``: the translation uses Pinocchio's exp6
    coefficients (Taylor expansions below ε^(1/4)), the rotation the quaternion product
    ``quat₀ ⊗ exp(ω/2)`` followed by Pinocchio's first-order renormalisation.
    """
    parts = [None] * q.shape[0]
    for j in tree:
        if j.kind != "free":
            parts[j.idx_q] = q[j.idx_q] + dv[j.idx_v]
            continue
        iq, iv = j.idx_q, j.idx_v
        p0 = q[iq: iq + 3]
        quat0 = tuple(q[iq + 3 + k] for k in range(4))
        lin, w = dv[iv: iv + 3], dv[iv + 3: iv + 6]
        t2 = ca.dot(w, w)
        t = ca.sqrt(t2)
        small = t < _TAYLOR3
        safe_t = ca.if_else(small, 1.0, t)
        st, ct = ca.sin(safe_t), ca.cos(safe_t)
        alpha_wxv = ca.if_else(small, 0.5 - t2 / 24.0, (1.0 - ct) / (safe_t * safe_t))
        alpha_v = ca.if_else(small, 1.0 - t2 / 6.0, st / safe_t)
        alpha_w = ca.if_else(small, 1.0 / 6.0 - t2 / 120.0, (1.0 - alpha_v) / (safe_t * safe_t))
        trans = alpha_v * lin + alpha_w * ca.dot(w, lin) * w + alpha_wxv * ca.cross(w, lin)
        R0 = quat_matrix(*quat0)
        p1 = p0 + R0 @ trans
        half = 0.5 * t
        sinc_half = ca.if_else(small, 0.5 - t2 / 48.0, ca.sin(half) / safe_t)
        dq = (sinc_half * w[0], sinc_half * w[1], sinc_half * w[2], ca.cos(half))
        quat1 = _quat_mul(quat0, dq)
        n2 = sum(c * c for c in quat1)
        alpha = (3.0 - n2) / 2.0
        for k in range(3):
            parts[iq + k] = p1[k]
        for k in range(4):
            parts[iq + 3 + k] = alpha * quat1[k]
    return ca.vertcat(*parts)


__all__ = ["TreeJoint", "tree_from_model", "Placements", "placements", "velocities",
           "frame_kinematics", "aba", "integrate", "skew", "quat_matrix"]
