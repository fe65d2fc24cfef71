"""Replay of one stance window under the paper's rigid-ground assumptions (``rigid``).

Paper Sec. IV: non-slip, non-sinkage; the stance foot's contact point is pinned with its
Jacobian J₀ frozen at touchdown; the GRF is the constraint force of
M v̇ + h = S τ + J₀ᵀ λ, J₀ v̇ = −k J₀ v (inverse dynamics of the constrained motion);
intrusion ≡ 0.

Opt-in ablations of that model (``bench/paper_gaps.py``; the defaults are the paper's
model): ``contact`` — how the stance foot is held (``"pin"`` the paper's frozen-Jacobian
pin, ``"pin_current"`` the same material point with its Jacobian updated every step,
``"rolling"`` the sole rolling without slip — the constrained point is the sole's current
lowest point, ``"measured"`` the contact point made to follow its measured path, sinking
and slip included, ``"measured_sink"`` only its measured sinking, x and y pinned);
``impact`` — ``"project"`` (plastic impact: the initial velocity projected onto the
constraints, an impulse outside the sampled forces) or ``"soft"`` (no
projection: the constraint feedback absorbs the foot's velocity over ≈ 1/k, so that
impulse is in the sampled forces); ``diagnostics`` adds the CoM height and vertical
velocity [m, m/s] per sample, the other foot's force and the projected impact impulse.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from scipy.signal import savgol_filter

from ...columns import BASE_POSITION, BASE_QUATERNION, joint_columns
from ...robot.model import SIDES
from ...rotations import skew, xyzw_from_wxyz
from ..prepare import StanceWindow, patch_points
from .measurement import true_window
from .model import ReplayModel, Variant
from .outputs import replay_outputs

#: the ``contact`` options of :func:`replay_rigid`
CONTACT_MODES = ("pin", "pin_current", "rolling", "measured", "measured_sink")
#: the ``impact`` options of :func:`replay_rigid`
IMPACT_MODES = ("project", "soft")


def measured_configurations(biped, w: StanceWindow) -> np.ndarray:
    """The measured configuration q (Pinocchio conventions, local frame of the window) of
    every scored sample, shape (n, nq): base position and quaternion and joint angles as
    measured."""
    qcols = joint_columns(biped.joint_names, "q")
    pos = np.column_stack([w.columns[c] for c in BASE_POSITION]) - w.origin
    quat = xyzw_from_wxyz(np.column_stack([w.columns[c] for c in BASE_QUATERNION]))
    out = np.tile(w.q0, (w.n, 1))
    out[:, 0:3] = pos
    out[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    out[:, biped.idx_q] = np.column_stack([w.columns[c] for c in qcols])
    return out


def measured_contact_path(biped, w: StanceWindow) -> np.ndarray:
    """The stance foot's contact point (mean of the sole's lowest points) on the measured
    configuration of every scored sample [m] (local frame of the window), shape (n, 3)."""
    data = biped.model.createData()
    out = np.empty((w.n, 3))
    for k, q in enumerate(measured_configurations(biped, w)):
        pin.framesForwardKinematics(biped.model, data, q)
        out[k] = patch_points(biped, data.oMf[biped.foot_frame[w.side]]).mean(axis=0)
    return out


def smoothed_path(path: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration of a sampled path (Savitzky–Golay, 11 samples,
    cubic; fewer samples for short windows)."""
    n = path.shape[0]
    win = min(11, n if n % 2 else n - 1)
    if win < 5:
        z = np.zeros_like(path)
        return path, np.gradient(path, dt_s, axis=0) if n > 1 else z, z
    return (savgol_filter(path, win, 3, axis=0), savgol_filter(path, win, 3, deriv=1,
            delta=dt_s, axis=0), savgol_filter(path, win, 3, deriv=2, delta=dt_s, axis=0))


def replay_rigid(model: ReplayModel, w: StanceWindow, variant: Variant | None = None, *,
                 stabilisation: float = 50.0, contact: str = "pin", impact: str = "project",
                 diagnostics: bool = False) -> dict:
    """Constrained replay under the paper's rigid-ground assumptions (no slip, no sinkage).

    The stance foot's contact point is pinned with its Jacobian J₀ frozen at touchdown;
    the other foot, if it starts in contact, is pinned likewise (frozen J₁) until its
    constraint force would pull (λ_z < 0: lift-off). The initial velocity is projected onto
    the constraints (a plastic impact); then, per plant step, the KKT system
    [M −Jᵀ; J 0][v̇; λ] = [Sτ − h; −k J v] gives the acceleration and the ground forces λ
    (world axes, on the feet: the inverse dynamics of the constrained motion);
    semi-implicit Euler on the manifold. The intrusion is 0 by assumption.

    Args:
        model, w, variant: the replay model, the window, the sensor variant.
        stabilisation: constraint drift feedback k [1/s].
        contact: how the stance foot is held (:data:`CONTACT_MODES`, module docstring);
            ``"pin"`` is the paper's model.
        impact: :data:`IMPACT_MODES`; ``"project"`` is the paper's model.
        diagnostics: add ``com_z`` [m], ``com_vz`` [m/s] (per sample), ``other_force``
            [N] (n, 3) and ``impact_impulse`` [N·s] (3,) to the result.
    """
    if contact not in CONTACT_MODES or impact not in IMPACT_MODES:
        raise ValueError(f"contact must be one of {CONTACT_MODES}, impact one of "
                         f"{IMPACT_MODES}; got {contact!r}, {impact!r}")
    biped = model.biped
    scored = w
    w = true_window(biped, w, variant)         # with sensor effects: the true start, torques
    mdl = biped.model
    data = mdl.createData()
    q = w.q0.copy()
    v = w.v0.copy()

    def kinematics(q_, v_):
        pin.forwardKinematics(mdl, data, q_, v_)
        pin.updateFramePlacements(mdl, data)
        pin.computeJointJacobians(mdl, data, q_)

    def point_jacobian(side, p_c=None):
        fid = biped.foot_frame[side]
        JF = pin.getFrameJacobian(mdl, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        if p_c is None:
            p_c = patch_points(biped, data.oMf[fid]).mean(axis=0)
        return JF[0:3] - skew(p_c - data.oMf[fid].translation) @ JF[3:6]

    kinematics(q, v)
    fid = biped.foot_frame[w.side]
    # the stance foot's pinned material point, in the foot frame (pin_current)
    pin_local = data.oMf[fid].actInv(patch_points(biped, data.oMf[fid]).mean(axis=0))
    Js = [point_jacobian(w.side)]
    other = w.feet[1 - w.foot]
    if other.in_contact:
        Js.append(point_jacobian(SIDES[1 - w.foot]))
    nv = mdl.nv
    dt = model.dt
    n = w.n
    if contact.startswith("measured"):
        dts = dt * model.steps_per_sample
        p_ref, v_ref, a_ref = smoothed_path(measured_contact_path(biped, w), dts)
        p0 = patch_points(biped, data.oMf[fid]).mean(axis=0)
        if contact == "measured_sink":        # x, y held at touchdown, z as measured
            p_ref[:, :2], v_ref[:, :2], a_ref[:, :2] = p0[:2], 0.0, 0.0
    M = pin.crba(mdl, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    Jc = np.vstack(Js)
    MiJt = np.linalg.solve(M, Jc.T)
    impulse = np.zeros(3)
    if impact == "project":
        lam_i = np.linalg.lstsq(Jc @ MiJt, Jc @ v, rcond=None)[0]
        v = v - MiJt @ lam_i
        impulse = -lam_i[0:3]                  # the impulse on the stance foot [N·s]
    J = biped.joint_names
    qa = np.full((n, len(J)), np.nan)
    lam_out = np.full((n, 3), np.nan)
    other_out = np.full((n, 3), np.nan)
    com_z = np.full(n, np.nan)
    com_vz = np.full(n, np.nan)
    iv, iq = biped.idx_v, biped.idx_q
    lo, hi = biped.position_limits
    lam = np.zeros(3 * len(Js))
    k_fb = stabilisation
    diverged = False

    def stance_row(k, sub):
        """The stance foot's constraint row(s) and right-hand side at this step."""
        if contact == "pin":
            return Js[0], -k_fb * (Js[0] @ v)
        kinematics(q, v)
        if contact == "pin_current":
            Jp = point_jacobian(w.side, data.oMf[fid].act(pin_local))
            return Jp, -k_fb * (Jp @ v)
        if contact == "rolling":
            Jp = point_jacobian(w.side)
            return Jp, -k_fb * (Jp @ v)
        # measured(_sink): the contact point follows its measured path (PD, feed-forward)
        s = (sub + 1) / model.steps_per_sample
        pa = p0 if k == 0 else p_ref[k - 1]
        pr = pa + s * (p_ref[k] - pa)
        Jp = point_jacobian(w.side)
        p = patch_points(biped, data.oMf[fid]).mean(axis=0)
        kp, kd = 4.0 * k_fb * k_fb, 4.0 * k_fb
        return Jp, a_ref[k] + kd * (v_ref[k] - Jp @ v) + kp * (pr - p)

    try:
        for k in range(n):
            tau_a = w.tau[k]
            for sub in range(model.steps_per_sample):
                J0, rhs0 = stance_row(k, sub)
                Jc = np.vstack([J0] + Js[1:])
                if contact == "pin":       # the paper's model: every row −k J v, as stacked
                    rhs_c = -k_fb * (Jc @ v)
                else:
                    rhs_c = np.concatenate([rhs0] + [-k_fb * (Jo @ v) for Jo in Js[1:]])
                M = pin.crba(mdl, data, q)
                M = np.triu(M) + np.triu(M, 1).T
                h = pin.nonLinearEffects(mdl, data, q, v)
                tau = np.zeros(nv)
                tau[iv] = tau_a
                over = np.maximum(q[iq] - hi, 0.0) + np.minimum(q[iq] - lo, 0.0)
                if over.any():
                    tau[iv] += np.where(over != 0.0, -500.0 * over - 5.0 * v[iv], 0.0)
                a, lam = _kkt(M, Jc, tau - h, rhs_c)
                if len(Js) > 1 and lam[5] < 0.0:       # the other foot lets go
                    Js = Js[:1]
                    a, lam = _kkt(M, J0, tau - h, rhs0)
                v = v + dt * a
                q = pin.integrate(mdl, q, v * dt)
                if not (np.all(np.isfinite(q)) and np.abs(v).max() < 200.0):
                    raise FloatingPointError
            qa[k] = q[iq]
            lam_out[k] = lam[0:3]
            if diagnostics:
                other_out[k] = lam[3:6] if lam.size > 3 else 0.0
                com_z[k] = pin.centerOfMass(mdl, data, q, v)[2]
                com_vz[k] = data.vcom[0][2]
    except (FloatingPointError, np.linalg.LinAlgError):
        diverged = True
    intr = np.where(np.isnan(qa[:, :1]), np.nan, np.zeros((n, 3)))    # pinned: no intrusion
    out = replay_outputs(qa, lam_out, intr, np.zeros(n), diverged, variant, scored, J)
    if diagnostics:
        out.update(com_z=com_z, com_vz=com_vz, other_force=other_out, impact_impulse=impulse)
    return out


def _kkt(M: np.ndarray, Jc: np.ndarray, f: np.ndarray, rhs: np.ndarray):
    """Solve [M −Jᵀ; J 0][a; λ] = [f; rhs] → (a, λ)."""
    nv, nc = M.shape[0], Jc.shape[0]
    K = np.zeros((nv + nc, nv + nc))
    K[:nv, :nv] = M
    K[:nv, nv:] = -Jc.T
    K[nv:, :nv] = Jc
    sol = np.linalg.solve(K, np.concatenate([f, rhs]))
    return sol[:nv], sol[nv:]


__all__ = ["replay_rigid", "measured_contact_path", "measured_configurations", "smoothed_path",
           "CONTACT_MODES", "IMPACT_MODES"]
