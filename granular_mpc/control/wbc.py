"""Whole-body controller: one ProxSuite QP over generalised accelerations and contact forces.

Decision variables ``x = [q̈ (nv), f (2 feet × n_points × 3)]`` (swing-foot forces held at
zero by box bounds, so the size never changes). Each tick:

* equality: the floating-base rows of ``M q̈ + h = Sᵀ τ + Σ Jᵢᵀ fᵢ`` (6 rows);
* inequalities: actuator torques ``τ = (M q̈ + h − Σ Jᵢᵀ fᵢ)_a`` within the URDF limits;
  contact forces inside the ground model's polytope (the same as the MPC's);
* weighted tasks, ``‖J q̈ + J̇v − a*‖²``: trunk orientation (PD on SO(3)), CoM (MPC feed-
  forward + PD), swing-foot position (cycloid feed-forward + PD), stance contact points,
  and ``‖f − f_MPC‖²``; a small regularisation on q̈.

On rigid ground the stance contact task asks the contact points to stay put (a* = −K v);
on granular ground it predicts their motion instead of pinning them: a* is the change of
the MPC's planned sinkage rate, with no feedback on the foot's velocity — the sand decides
how far the foot sinks and slips, and a controller that tried to hold the foot would pull
it up and shorten the stance leg.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..config import WBCConfig
from ..robot.model import SIDES, Biped
from ..rotations import matrix_from_quat_xyzw, rot_z, skew
from .contact_model import GroundModel
from .solvers.proxqp import ProxQPSolver, QPProblem, QPStatus

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
BIG = 1e20


def _cross(a, b) -> np.ndarray:
    """Cross product of two 3-vectors (np.cross costs ~20 µs of axis handling)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


@dataclass
class WBCReference:
    """Everything the WBC tracks at one tick (world frame)."""

    com: np.ndarray                 # position [m]
    com_vel: np.ndarray             # [m/s]
    com_acc: np.ndarray             # feed-forward [m/s²]
    R_trunk: np.ndarray             # desired trunk orientation
    omega: np.ndarray               # desired trunk angular velocity (W) [rad/s]
    stance: tuple[bool, bool]       # feet in stance per the plan
    forces: np.ndarray              # (2, n_points, 3) MPC forces
    swing_pos: np.ndarray           # (2, 3) foot-frame origin targets (swing feet)
    swing_vel: np.ndarray
    swing_acc: np.ndarray
    sink_accel: np.ndarray          # (2,) predicted sinkage acceleration of stance feet [m/s²]
    force_weight: float | None = None   # overrides config.w_force (e.g. no MPC plan yet)
    force_cap: np.ndarray | None = None  # (2,) largest normal force per foot now [N]


@dataclass
class FootPoints:
    """Contact points of one foot at the current state: positions (n, 3) and offsets from
    the foot frame origin (n, 3), world frame."""

    points: np.ndarray
    offsets: np.ndarray


@dataclass
class WBCData:
    solver: ProxQPSolver
    pin: pin.Data
    failures: int = 0
    solves: int = 0
    last_tau: np.ndarray | None = None
    last_status: QPStatus = QPStatus.SOLVED
    last_ms: float = 0.0
    keep_residuals: bool = False     # store each task's residual (debugging)
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class WholeBodyController:
    config: WBCConfig
    biped: Biped
    ground: GroundModel
    swing_kp: float = 400.0
    swing_kd: float = 40.0
    n_points: int = 2
    contact_damping: float = 20.0   # [1/s] the medium stops a foot loaded within capacity

    @property
    def nv(self) -> int:
        return self.biped.model.nv

    @property
    def nf(self) -> int:
        return 2 * self.n_points * 3

    @property
    def n(self) -> int:
        return self.nv + self.nf

    @property
    def n_in(self) -> int:
        return 6 + 2 * self.n_points * self.ground.polytope.G.shape[0]

    def new_data(self) -> WBCData:
        return WBCData(ProxQPSolver(self.n, 6, self.n_in, box=True, eps_abs=1e-5, max_iter=100),
                       self.biped.model.createData())

    # ------------------------------------------------------------------ the tick
    def solve(self, data: WBCData, q: np.ndarray, v: np.ndarray, ref: WBCReference,
              feet: tuple[FootPoints, FootPoints]) -> np.ndarray:
        """Joint torques (actuator order) [N·m] for state (q, v) and the references."""
        c = self.config
        b = self.biped
        model, pd = b.model, data.pin
        nv, nf, nps = self.nv, self.nf, self.n_points
        pin.computeJointJacobians(model, pd, q)
        pin.forwardKinematics(model, pd, q, v, np.zeros(nv))
        pin.updateFramePlacements(model, pd)
        M = pin.crba(model, pd, q)
        M = np.triu(M) + np.triu(M, 1).T
        h = pin.nonLinearEffects(model, pd, q, v)
        Jc = pin.jacobianCenterOfMass(model, pd, q, False)
        pin.centerOfMass(model, pd, q, v, np.zeros(nv))
        com, vcom, acom_drift = pd.com[0].copy(), pd.vcom[0].copy(), pd.acom[0].copy()

        Hq = np.zeros((nv, nv))
        gq = np.zeros(nv)
        tasks = []

        def add_task(J, drift, a_des, w, name=""):
            nonlocal Hq, gq
            e = drift - a_des
            Hq += w * (J.T @ J)
            gq += w * (J.T @ e)
            tasks.append((name, J, e, w))

        # trunk orientation: base angular acceleration (trunk frame) = q̈[3:6]
        R = matrix_from_quat_xyzw(q[3:7])
        err_W = pin.log3(ref.R_trunk @ R.T)
        omega_W = R @ v[3:6]
        alpha_W = c.kp_orientation * err_W + c.kd_orientation * (ref.omega - omega_W)
        # per-axis weights in the trunk frame (roll, pitch, yaw)
        J_ang = np.zeros((3, nv))
        J_ang[:, 3:6] = np.eye(3)
        sw = np.sqrt(np.asarray(c.w_orientation, dtype=float))
        add_task(sw[:, None] * J_ang, np.zeros(3), sw * (R.T @ alpha_W), 1.0, "orientation")
        # CoM
        a_com = ref.com_acc + c.kp_com * (ref.com - com) + c.kd_com * (ref.com_vel - vcom)
        add_task(Jc, acom_drift, a_com, c.w_com, "com")
        # feet: swing tracking or stance contact points
        Jpts = []
        for i, side in enumerate(SIDES):
            fid = b.foot_frame[side]
            J6 = pin.getFrameJacobian(model, pd, fid, _LWA)
            acc = pin.getFrameClassicalAcceleration(model, pd, fid, _LWA)
            vel = pin.getFrameVelocity(model, pd, fid, _LWA)
            a_o, alpha = acc.linear, acc.angular
            w_f = vel.angular
            pts = []
            for r in feet[i].offsets:
                Jp = J6[:3] - skew(r) @ J6[3:]
                wr = _cross(w_f, r)
                drift = a_o + _cross(alpha, r) + _cross(w_f, wr)
                vp = vel.linear + wr
                pts.append((Jp, drift, vp))
            Jpts.append(pts)
            if ref.stance[i]:
                for Jp, drift, vp in pts:
                    if self.ground.granular:
                        # the sand, not the controller, decides how the foot moves: the
                        # WBC predicts the foot's acceleration (the change of the planned
                        # sinkage rate) and never feeds back on the foot's velocity, which
                        # would pull a sinking foot up and collapse the stance leg
                        a_des = -self.contact_damping * vp
                        a_des[2] -= ref.sink_accel[i]
                        add_task(Jp, drift, a_des, c.w_contact, f"contact_{side}")
                    else:
                        add_task(Jp, drift, -40.0 * vp, c.w_contact, f"contact_{side}")
            else:
                p_o = pd.oMf[fid].translation
                a_des = (ref.swing_acc[i] + self.swing_kp * (ref.swing_pos[i] - p_o)
                         + self.swing_kd * (ref.swing_vel[i] - vel.linear))
                add_task(J6[:3], a_o, a_des, c.w_swing, f"swing_{side}")
        Hq[np.diag_indices_from(Hq)] += c.w_regularisation
        # assemble the QP
        H = np.zeros((self.n, self.n))
        g = np.zeros(self.n)
        H[:nv, :nv] = Hq
        g[:nv] = gq
        f_ref = ref.forces.reshape(-1)
        w_force = c.w_force if ref.force_weight is None else ref.force_weight
        H[nv:, nv:] += w_force * np.eye(nf)
        g[nv:] -= w_force * f_ref
        # contact Jacobian transpose map: Σ Jᵀ f
        JT = np.zeros((nv, nf))
        for i in range(2):
            for k in range(nps):
                col = (i * nps + k) * 3
                JT[:, col:col + 3] = Jpts[i][k][0].T
        A = np.hstack([M[:6], -JT[:6]])
        bvec = -h[:6]
        tau_max = b.torque_limits
        Ct = np.hstack([M[6:], -JT[6:]])
        poly = self.ground.polytope.scaled(1.0 / nps)
        nr = poly.G.shape[0]
        C = np.zeros((self.n_in, self.n))
        l = np.full(self.n_in, -BIG)
        u = np.zeros(self.n_in)
        C[:6] = Ct
        l[:6] = -tau_max - h[6:]
        u[:6] = tau_max - h[6:]
        lb = np.full(self.n, -BIG)
        ub = np.full(self.n, BIG)
        row = 6
        for i, side in enumerate(SIDES):
            yaw = float(np.arctan2(pd.oMf[b.foot_frame[side]].rotation[1, 0],
                                   pd.oMf[b.foot_frame[side]].rotation[0, 0]))
            Gw = poly.G @ rot_z(yaw).T
            share = 1.0
            if ref.force_cap is not None:
                share = min(max(ref.force_cap[i] / self.ground.polytope.f_max, 0.0), 1.0)
            for k in range(nps):
                col = nv + (i * nps + k) * 3
                C[row:row + nr, col:col + 3] = Gw
                u[row:row + nr] = poly.h * share
                row += nr
                if ref.stance[i]:
                    lb[col + 2] = 0.0
                    ub[col + 2] = poly.f_max * share
                else:
                    lb[col:col + 3] = 0.0
                    ub[col:col + 3] = 0.0
        H = 0.5 * (H + H.T)
        t0 = time.perf_counter()
        sol = data.solver.solve(QPProblem(H, g, A, bvec, C, l, u, lb, ub))
        data.last_ms = (time.perf_counter() - t0) * 1e3
        data.solves += 1
        data.last_status = sol.status
        if sol.status.ok:
            x = sol.x
            if data.keep_residuals:
                data.extra["task_residuals"] = {n: J @ x[:nv] + e for n, J, e, w in tasks}
            tau = M[6:] @ x[:nv] + h[6:] - JT[6:] @ x[nv:]
        else:
            data.failures += 1
            # fall back: the previous torques if any, else gravity/force feed-forward
            if data.last_tau is not None:
                tau = data.last_tau.copy()
            else:
                tau = h[6:] - JT[6:] @ f_ref
        tau = np.clip(tau, -tau_max, tau_max)
        data.last_tau = tau
        return tau[b.idx_v - 6]          # v order → actuator order


__all__ = ["WholeBodyController", "WBCReference", "WBCData", "FootPoints"]
