"""Replay of one stance window under the paper's rigid-ground assumptions (``rigid``).

Paper Sec. IV: non-slip, non-sinkage; the stance foot's contact point is pinned with its
Jacobian J₀ frozen at touchdown; the GRF is the constraint force of
M v̇ + h = S τ + J₀ᵀ λ, J₀ v̇ = −k J₀ v (inverse dynamics of the constrained motion);
intrusion ≡ 0.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ...robot.model import SIDES
from ...rotations import skew
from ..prepare import StanceWindow, patch_points
from .measurement import true_window
from .model import ReplayModel, Variant
from .outputs import replay_outputs


def replay_rigid(model: ReplayModel, w: StanceWindow, variant: Variant | None = None, *,
                 stabilisation: float = 50.0) -> dict:
    """Constrained replay under the paper's rigid-ground assumptions (no slip, no sinkage).

    The stance foot's contact point is pinned with its Jacobian J₀ frozen at touchdown;
    the other foot, if it starts in contact, is pinned likewise (frozen J₁) until its
    constraint force would pull (λ_z < 0: lift-off). The initial velocity is projected onto
    the constraints (a plastic impact); then, per plant step, the KKT system
    [M −Jᵀ; J 0][v̇; λ] = [Sτ − h; −k J v] gives the acceleration and the ground forces λ
    (world axes, on the feet: the inverse dynamics of the constrained motion);
    semi-implicit Euler on the manifold. The intrusion is 0 by assumption.
    """
    biped = model.biped
    scored = w
    w = true_window(biped, w, variant)         # with sensor effects: the true start, torques
    mdl = biped.model
    data = mdl.createData()
    q = w.q0.copy()
    v = w.v0.copy()
    pin.forwardKinematics(mdl, data, q, v)
    pin.updateFramePlacements(mdl, data)
    pin.computeJointJacobians(mdl, data, q)

    def point_jacobian(side):
        fid = biped.foot_frame[side]
        JF = pin.getFrameJacobian(mdl, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        p_c = patch_points(biped, data.oMf[fid]).mean(axis=0)
        return JF[0:3] - skew(p_c - data.oMf[fid].translation) @ JF[3:6]

    Js = [point_jacobian(w.side)]
    other = w.feet[1 - w.foot]
    if other.in_contact:
        Js.append(point_jacobian(SIDES[1 - w.foot]))
    nv = mdl.nv
    M = pin.crba(mdl, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    Jc = np.vstack(Js)
    MiJt = np.linalg.solve(M, Jc.T)
    v = v - MiJt @ np.linalg.lstsq(Jc @ MiJt, Jc @ v, rcond=None)[0]
    J = biped.joint_names
    n = w.n
    qa = np.full((n, len(J)), np.nan)
    lam_out = np.full((n, 3), np.nan)
    dt = model.dt
    iv, iq = biped.idx_v, biped.idx_q
    lo, hi = biped.position_limits
    lam = np.zeros(3 * len(Js))
    diverged = False
    try:
        for k in range(n):
            tau_a = w.tau[k]
            for _ in range(model.steps_per_sample):
                Jc = np.vstack(Js)
                nc = Jc.shape[0]
                M = pin.crba(mdl, data, q)
                M = np.triu(M) + np.triu(M, 1).T
                h = pin.nonLinearEffects(mdl, data, q, v)
                tau = np.zeros(nv)
                tau[iv] = tau_a
                over = np.maximum(q[iq] - hi, 0.0) + np.minimum(q[iq] - lo, 0.0)
                if over.any():
                    tau[iv] += np.where(over != 0.0, -500.0 * over - 5.0 * v[iv], 0.0)
                K = np.zeros((nv + nc, nv + nc))
                K[:nv, :nv] = M
                K[:nv, nv:] = -Jc.T
                K[nv:, :nv] = Jc
                rhs = np.concatenate([tau - h, -stabilisation * (Jc @ v)])
                sol = np.linalg.solve(K, rhs)
                a, lam = sol[:nv], sol[nv:]
                if len(Js) > 1 and lam[5] < 0.0:       # the other foot lets go
                    Js = Js[:1]
                    continue_step = True
                else:
                    continue_step = False
                if continue_step:
                    Jc = Js[0]
                    K = np.zeros((nv + 3, nv + 3))
                    K[:nv, :nv] = M
                    K[:nv, nv:] = -Jc.T
                    K[nv:, :nv] = Jc
                    sol = np.linalg.solve(K, np.concatenate([tau - h, -stabilisation * (Jc @ v)]))
                    a, lam = sol[:nv], sol[nv:]
                v = v + dt * a
                q = pin.integrate(mdl, q, v * dt)
                if not (np.all(np.isfinite(q)) and np.abs(v).max() < 200.0):
                    raise FloatingPointError
            qa[k] = q[iq]
            lam_out[k] = lam[0:3]
    except (FloatingPointError, np.linalg.LinAlgError):
        diverged = True
    intr = np.where(np.isnan(qa[:, :1]), np.nan, np.zeros((n, 3)))    # pinned: no intrusion
    return replay_outputs(qa, lam_out, intr, np.zeros(n), diverged, variant, scored, J)


__all__ = ["replay_rigid"]
