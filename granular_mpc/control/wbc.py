"""Whole-body controller: one QP over generalised accelerations and contact forces.

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

The QP is solved by ProxSuite or DAQP (``controller.wbc.solver``). With DAQP the QP's
arrays are views of the solver's own stacked arrays (:meth:`.DAQPSolver.new_problem`), so
the compiled assembly writes straight into what DAQP reads and nothing is copied.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pinocchio as pin

from ..config import WBCConfig
from ..robot.model import SIDES, Biped
from ..rotations import matrix_from_quat_xyzw, skew_rows
from .contact_model import GroundModel
from .solvers.daqp import DAQPSolver
from .solvers.proxqp import ProxQPSolver, QPProblem, QPStatus
from .wbc_qp import AssemblyCaller, AssemblyConstants, compile_assembly

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_ACCELERATION = pin.KinematicLevel.ACCELERATION
BIG = 1e20


def _point_kinematics(acc: list, vel: list, offsets: list) -> tuple[np.ndarray, np.ndarray]:
    """Drift accelerations ``a_o + α × r + ω × (ω × r)`` and velocities ``v_o + ω × r`` of
    the contact points (world frame) of both feet, from each foot frame's classical
    acceleration and velocity (6-vectors, linear first) and the points' offsets r (lists).
    Plain float arithmetic: for a handful of points it is far cheaper than NumPy's
    per-call overhead (same IEEE operations as the array form)."""
    drift, vp = [], []
    for (ax, ay, az, alx, aly, alz), (vx, vy, vz, wx, wy, wz), pts in zip(acc, vel, offsets):
        d_f, v_f = [], []
        for rx, ry, rz in pts:
            wrx, wry, wrz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
            d_f.append((ax + (aly * rz - alz * ry) + (wy * wrz - wz * wry),
                        ay + (alz * rx - alx * rz) + (wz * wrx - wx * wrz),
                        az + (alx * ry - aly * rx) + (wx * wry - wy * wrx)))
            v_f.append((vx + wrx, vy + wry, vz + wrz))
        drift.append(d_f)
        vp.append(v_f)
    return np.array(drift), np.array(vp)


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
class WBCWork:
    """Preallocated QP buffers of the WBC (fixed size: nv + 2·n_points·3 variables) and
    the config-only terms, built once per controller and refilled in place each tick
    (ProxSuite copies them into its model; with DAQP they are views of the solver's own
    stacked problem, :meth:`.DAQPSolver.new_problem`, read without a copy)."""

    H: np.ndarray               # (n, n)
    g: np.ndarray               # (n,)
    A: np.ndarray               # (6, n) floating-base rows
    b: np.ndarray               # (6,)
    C: np.ndarray               # (n_in, n)
    C_poly: np.ndarray          # view of C's polytope rows: (points, rows, points, 3)
    l: np.ndarray               # (n_in,)
    u: np.ndarray               # (n_in,)
    lb: np.ndarray              # (n,)
    ub: np.ndarray              # (n,)
    J: np.ndarray               # (max task rows, nv) stacked task Jacobians
    e: np.ndarray               # (max task rows,) stacked drift − desired acceleration
    w: np.ndarray               # (max task rows,) task weights
    sw: np.ndarray              # (3,) √ of the orientation weights
    h_point: np.ndarray         # (rows,) polytope bounds for one contact point [N]
    f_max_point: float          # largest normal force of one contact point [N]
    diag_nv: np.ndarray         # indices of the q̈ block's diagonal
    diag_f: np.ndarray          # indices of the force block's diagonal (in H)
    lower: tuple                # indices of the strict lower triangle of M
    problem: QPProblem | None = None    # the QP over the arrays above (made once)
    C_tau_q: np.ndarray | None = None   # view of C's torque rows' q̈ block, M_a (6, nv)
    C_tau_f: np.ndarray | None = None   # view of C's torque rows' force block, −J_aᵀ


@dataclass
class WBCData:
    solver: ProxQPSolver | DAQPSolver
    pin: pin.Data
    failures: int = 0
    solves: int = 0
    last_tau: np.ndarray | None = None
    last_status: QPStatus = QPStatus.SOLVED
    last_ms: float = 0.0
    keep_residuals: bool = False     # store each task's residual (debugging)
    extra: dict = field(default_factory=dict)
    work: WBCWork | None = None
    assembly: AssemblyCaller | None = None   # the compiled QP assembly (None: NumPy)


@dataclass(frozen=True)
class WholeBodyController:
    config: WBCConfig
    biped: Biped
    ground: GroundModel
    swing_kp: float = 400.0
    swing_kd: float = 40.0
    n_points: int = 2
    contact_damping: float = 20.0   # [1/s] the medium stops a foot loaded within capacity
    #: how the QP is built each tick: ``compiled`` (the assembly generated to C,
    #: :mod:`.wbc_qp`; NumPy where no C compiler exists) or ``numpy`` (the reference).
    #: The two give the same QP to rounding (≈ 2e-15 relative, ``tests/test_wbc.py``).
    assembly: str = "compiled"

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
        solver = self._new_solver()
        work = self._new_work(solver)
        return WBCData(solver, self.biped.model.createData(), work=work,
                       assembly=self._bind_assembly(work))

    def _new_solver(self) -> ProxQPSolver | DAQPSolver:
        """The QP solver named by ``config.solver``, sized for this controller:
        ``proxsuite`` (warm started, eps_abs 1e-5 — the WBC's tolerance since it was
        written) or ``daqp`` (hot-started active set, exact to round-off)."""
        if self.config.solver == "daqp":
            return DAQPSolver(self.n, 6, self.n_in, box=True, max_iter=200)
        return ProxQPSolver(self.n, 6, self.n_in, box=True, eps_abs=1e-5, max_iter=100)

    def _bind_assembly(self, work: WBCWork) -> AssemblyCaller | None:
        """The compiled assembly writing into ``work``'s QP arrays (None: NumPy assembly)."""
        if self.assembly != "compiled":
            return None
        fns = _compiled(self.assembly_constants(), tuple(self._torque_bounds[2].tolist()))
        if fns is None:
            return None
        return AssemblyCaller(fns, self.nv, self.n_points,
                              (work.H, work.g, work.A, work.b, work.C, work.l, work.u,
                               work.lb, work.ub))

    @cached_property
    def _free_flyer(self) -> bool:
        """Whether joint 1 of the model is the trunk's free flyer (its placement is the
        trunk's rotation)."""
        return self.biped.model.joints[1].shortname() == "JointModelFreeFlyer"

    def assembly_constants(self) -> AssemblyConstants:
        """The numbers the compiled assembly bakes in (gains, weights, limits, polytope)."""
        c = self.config
        poly = self.ground.polytope.scaled(1.0 / self.n_points)
        return AssemblyConstants(
            nv=self.nv, n_points=self.n_points,
            w_orientation_sqrt=tuple(np.sqrt(np.asarray(c.w_orientation, dtype=float)).tolist()),
            w_com=c.w_com, w_swing=c.w_swing, w_contact=c.w_contact,
            w_regularisation=c.w_regularisation, kp_orientation=c.kp_orientation,
            kd_orientation=c.kd_orientation, kp_com=c.kp_com, kd_com=c.kd_com,
            swing_kp=float(self.swing_kp), swing_kd=float(self.swing_kd),
            contact_damping=float(self.contact_damping), granular=bool(self.ground.granular),
            tau_max=tuple(self.biped.torque_limits_v.tolist()),   # v order, as τ is computed
            G=tuple(map(tuple, np.asarray(self.ground.polytope.G, dtype=float).tolist())),
            h_point=tuple(np.asarray(poly.h, dtype=float).tolist()),
            f_max_point=float(poly.f_max),
            foot_placement=tuple(
                tuple(self.biped.model.frames[fid].placement.rotation.ravel("F").tolist()
                      + self.biped.model.frames[fid].placement.translation.tolist())
                for fid in self._foot_frames),
            foot_support=tuple(self._support_columns(self._foot_joints[i]) for i in range(2)))

    @cached_property
    def _foot_frames(self) -> tuple[int, int]:
        """The foot frames' ids (left, right)."""
        return self.biped.foot_frame[SIDES[0]], self.biped.foot_frame[SIDES[1]]

    @cached_property
    def _foot_joints(self) -> tuple[int, int]:
        """The foot frames' parent joints (left, right)."""
        return tuple(int(self.biped.model.frames[fid].parentJoint) for fid in self._foot_frames)

    def _support_columns(self, joint: int) -> tuple[int, ...]:
        """The velocity columns the placement of ``joint`` depends on (its support's)."""
        model = self.biped.model
        return tuple(c for j in list(model.supports[joint])[1:]
                     for c in range(model.idx_vs[j], model.idx_vs[j] + model.nvs[j]))

    def _pinocchio_inputs(self, pd: pin.Data) -> dict[str, np.ndarray]:
        """The compiled assembly's inputs as views of ``pd``'s storage (:mod:`.wbc_qp`'s
        ``INPUTS`` but ``p``; the trunk's rotation only with a free flyer, whose placement it
        is — else :meth:`_assemble_compiled` copies it in each tick)."""
        out = {"M": pd.M, "h": pd.nle, "Jcom": pd.Jcom, "J": pd.J, "com": pd.com[0],
               "vcom": pd.vcom[0], "acom": pd.acom[0]}
        if self._free_flyer:
            out["R"] = pd.oMi[1].rotation
        for s, j in zip("lr", self._foot_joints):
            out.update({f"R_{s}": pd.oMi[j].rotation, f"p_{s}": pd.oMi[j].translation,
                        f"v_{s}": pd.v[j].vector, f"a_{s}": pd.a[j].vector})
        return out

    @cached_property
    def _torque_bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-tick constants of :meth:`solve`: the torque bounds −τ_max, τ_max [N·m] (v
        order of the actuated joints) and the rows taking v order to actuator order."""
        tau_max = self.biped.torque_limits_v          # v order, as τ is computed
        return -tau_max, tau_max, self.biped.idx_v - 6

    def _new_work(self, solver: ProxQPSolver | DAQPSolver | None = None) -> WBCWork:
        """The QP buffers; for a :class:`DAQPSolver` they are views of its stacked arrays
        (filled here with the same initial values as the ProxSuite path's own arrays)."""
        n, nv, n_in, nps = self.n, self.nv, self.n_in, self.n_points
        poly = self.ground.polytope.scaled(1.0 / nps)
        nr = poly.G.shape[0]
        rows = 3 + 3 + 2 * nps * 3          # orientation, CoM, both feet's contact points
        if isinstance(solver, DAQPSolver):
            qp = solver.new_problem()
            for arr, value in ((qp.H, 0.0), (qp.g, 0.0), (qp.A, 0.0), (qp.b, 0.0),
                               (qp.C, 0.0), (qp.l, -BIG), (qp.u, 0.0), (qp.lb, -BIG),
                               (qp.ub, BIG)):
                arr.fill(value)
        else:
            qp = QPProblem(np.zeros((n, n)), np.zeros(n), np.zeros((6, n)), np.zeros(6),
                           np.zeros((n_in, n)), np.full(n_in, -BIG), np.zeros(n_in),
                           np.full(n, -BIG), np.full(n, BIG))
        C = qp.C
        w = WBCWork(
            H=qp.H, g=qp.g, A=qp.A, b=qp.b, C=C,
            C_poly=C[6:, nv:].reshape(2 * nps, nr, 2 * nps, 3),
            l=qp.l, u=qp.u, lb=qp.lb, ub=qp.ub,
            J=np.zeros((rows, nv)), e=np.zeros(rows), w=np.zeros(rows),
            sw=np.sqrt(np.asarray(self.config.w_orientation, dtype=float)),
            h_point=poly.h, f_max_point=poly.f_max,
            diag_nv=np.arange(nv), diag_f=np.arange(nv, n), lower=np.tril_indices(nv, -1),
            C_tau_q=C[:6, :nv], C_tau_f=C[:6, nv:])
        # every tick refills these arrays in place: one problem object over them (DAQP's
        # own, which it then reads without a copy)
        w.problem = qp
        return w

    # ------------------------------------------------------------------ the tick
    def solve(self, data: WBCData, q: np.ndarray, v: np.ndarray, ref: WBCReference,
              feet: tuple[FootPoints, FootPoints]) -> np.ndarray:
        """Joint torques (actuator order) [N·m] for state (q, v) and the references."""
        w = data.work
        if w is None:
            w = data.work = self._new_work(data.solver)
            data.assembly = self._bind_assembly(w)     # its outputs are the new arrays
        nv = self.nv
        if data.assembly is not None and not data.keep_residuals:
            h_a = self._assemble_compiled(data, q, v, ref, feet)
            Jt = et = names = None
            # C's first rows are [M_a, −J_aᵀ]: τ = M_a q̈ + h_a − J_aᵀ f, computed as
            # M_a q̈ + h_a + (−J_aᵀ) f (the same numbers: negating a product or a sum is
            # exact in IEEE arithmetic) on views made once
            M_a, mJT_a = w.C_tau_q, w.C_tau_f
        else:
            h_a, Jt, et, names, M_a, JT_a = self._assemble_numpy(data, q, v, ref, feet)
            mJT_a = None
        tau_min, tau_max, actuator_rows = self._torque_bounds
        t0 = time.perf_counter()
        sol = data.solver.solve(w.problem)
        data.last_ms = (time.perf_counter() - t0) * 1e3
        data.solves += 1
        data.last_status = sol.status
        if sol.status.ok and mJT_a is not None:
            # τ = M_a q̈ + h_a − J_aᵀ f, clipped and put in actuator order by compiled code
            # (wbc_qp.torque_function: the same sums and clip as the NumPy lines below)
            a = data.assembly
            a.torques(sol.x)
            data.last_tau = a.tau.copy()
            return a.tau_act.copy()
        if sol.status.ok:
            x = sol.x
            if data.keep_residuals:
                res = Jt @ x[:nv] + et
                data.extra["task_residuals"] = {k: res[r0:r1] for k, r0, r1 in names}
            tau = M_a @ x[:nv] + h_a - JT_a @ x[nv:]
        else:
            data.failures += 1
            # fall back: the previous torques if any, else gravity/force feed-forward
            if data.last_tau is not None:
                tau = data.last_tau.copy()
            elif mJT_a is not None:
                tau = h_a + mJT_a @ ref.forces.reshape(-1)
            else:
                tau = h_a - JT_a @ ref.forces.reshape(-1)
        tau = np.minimum(np.maximum(tau, tau_min), tau_max)
        data.last_tau = tau
        return tau[actuator_rows]          # v order → actuator order

    def _assemble_numpy(self, data: WBCData, q: np.ndarray, v: np.ndarray, ref: WBCReference,
                       feet: tuple[FootPoints, FootPoints]):
        """Build the QP in ``data.work`` (made by :meth:`new_data`) with NumPy: the
        reference assembly.

        Returns ``(h_a, J, e, names, M_a, JT_a)``: the actuated rows of the nonlinear
        effects, the stacked task Jacobian and errors, (task, first row, last row) per
        task, and the actuated rows of M and of the contact Jacobians' transpose."""
        c = self.config
        b = self.biped
        model, pd = b.model, data.pin
        w = data.work
        nv, nps = self.nv, self.n_points
        # one pass: M (CRBA), h (RNEA at q̈ = 0), joint Jacobians, CoM and its Jacobian,
        # body velocities and drift accelerations (q̈ = 0); then the CoM drift from those
        pin.computeAllTerms(model, pd, q, v)
        pin.updateFramePlacements(model, pd)
        pin.centerOfMass(model, pd, _ACCELERATION, False)
        M = pd.M.copy()
        M[w.lower] = M.T[w.lower]      # Pinocchio's CRBA fills the upper triangle
        h = pd.nle
        com, vcom, acom_drift = pd.com[0], pd.vcom[0], pd.acom[0]

        J, e, wt = w.J, w.e, w.w
        names = []              # (task name, first row, last row) for keep_residuals
        # trunk orientation: base angular acceleration (trunk frame) = q̈[3:6]; per-axis
        # weights in the trunk frame (roll, pitch, yaw) as √w on the rows
        R = matrix_from_quat_xyzw(q[3:7])
        err_W = pin.log3(ref.R_trunk @ R.T)
        omega_W = R @ v[3:6]
        alpha_W = c.kp_orientation * err_W + c.kd_orientation * (ref.omega - omega_W)
        sw = w.sw
        J[0:3] = 0.0
        J[0, 3], J[1, 4], J[2, 5] = sw
        e[0:3] = 0.0 - sw * (R.T @ alpha_W)
        wt[0:3] = 1.0
        names.append(("orientation", 0, 3))
        # CoM
        a_com = ref.com_acc + c.kp_com * (ref.com - com) + c.kd_com * (ref.com_vel - vcom)
        J[3:6] = pd.Jcom
        e[3:6] = acom_drift - a_com
        wt[3:6] = c.w_com
        names.append(("com", 3, 6))
        # feet: frame Jacobians, velocities and drift accelerations, both feet at once
        fids = (b.foot_frame[SIDES[0]], b.foot_frame[SIDES[1]])
        J6 = np.stack([pin.getFrameJacobian(model, pd, fid, _LWA) for fid in fids])  # (2,6,nv)
        acc = [pin.getFrameClassicalAcceleration(model, pd, fid, _LWA).vector.tolist()
               for fid in fids]
        vel = [pin.getFrameVelocity(model, pd, fid, _LWA).vector.tolist() for fid in fids]
        r = np.stack([feet[0].offsets, feet[1].offsets])                            # (2,nps,3)
        # contact point Jacobians J_o − [r]× J_ω (one batched product for all points)
        Jp = J6[:, None, :3, :] - skew_rows(r) @ J6[:, None, 3:, :]                 # (2,nps,3,nv)
        drift, vp = _point_kinematics(acc, vel, r.tolist())                         # (2,nps,3)
        row = 6
        granular = self.ground.granular
        for i, side in enumerate(SIDES):
            if ref.stance[i]:
                if granular:
                    # the sand, not the controller, decides how the foot moves: the WBC
                    # predicts the foot's acceleration (the change of the planned sinkage
                    # rate) and never feeds back on the foot's velocity, which would pull a
                    # sinking foot up and collapse the stance leg
                    a_des = -self.contact_damping * vp[i]
                    a_des[:, 2] -= ref.sink_accel[i]
                else:
                    a_des = -40.0 * vp[i]
                k = nps * 3
                J[row:row + k] = Jp[i].reshape(k, nv)
                e[row:row + k] = (drift[i] - a_des).ravel()
                wt[row:row + k] = c.w_contact
                names.append((f"contact_{side}", row + k - 3, row + k))
                row += k
            else:
                p_o = pd.oMf[fids[i]].translation
                a_des = (ref.swing_acc[i] + self.swing_kp * (ref.swing_pos[i] - p_o)
                         + self.swing_kd * (ref.swing_vel[i] - np.array(vel[i][:3])))
                J[row:row + 3] = J6[i, :3]
                e[row:row + 3] = np.array(acc[i][:3]) - a_des
                wt[row:row + 3] = c.w_swing
                names.append((f"swing_{side}", row, row + 3))
                row += 3
        Jt, et, wt_ = J[:row], e[:row], wt[:row]
        WJ = Jt * wt_[:, None]
        # assemble the QP in the preallocated buffers
        H, g = w.H, w.g
        Hq = Jt.T @ WJ
        Hq[w.diag_nv, w.diag_nv] += c.w_regularisation
        H[:nv, :nv] = Hq
        H[:nv, :nv] += Hq.T
        H[:nv, :nv] *= 0.5
        g[:nv] = WJ.T @ et
        f_ref = ref.forces.reshape(-1)
        w_force = c.w_force if ref.force_weight is None else ref.force_weight
        H[w.diag_f, w.diag_f] = w_force
        g[nv:] = -w_force * f_ref
        # contact Jacobian transpose map: Σ Jᵀ f (columns point-major, axis-minor)
        JT = Jp.reshape(-1, nv).T                                                  # (nv, nf)
        w.A[:, :nv] = M[:6]
        w.A[:, nv:] = -JT[:6]
        w.b[:] = -h[:6]
        tau_max = b.torque_limits_v          # the torque rows are in v order
        C, l, u, lb, ub = w.C, w.l, w.u, w.lb, w.ub
        C[:6, :nv] = M[6:]
        C[:6, nv:] = -JT[6:]
        h_a = h[6:]
        l[:6] = -tau_max - h_a
        u[:6] = tau_max - h_a
        # force polytope of each contact point, turned to its foot's heading
        cy, sy = np.empty(2), np.empty(2)
        for i, fid in enumerate(fids):
            rot = pd.oMf[fid].rotation
            yaw = math.atan2(rot[1, 0], rot[0, 0])
            cy[i], sy[i] = math.cos(yaw), math.sin(yaw)
        G = self.ground.polytope.G
        # G R_z(ψ)ᵀ: columns (G_x c − G_y s, G_x s + G_y c, G_z)
        Gw = np.empty((2,) + G.shape)
        Gw[:, :, 0] = G[None, :, 0] * cy[:, None] + G[None, :, 1] * (-sy[:, None])
        Gw[:, :, 1] = G[None, :, 0] * sy[:, None] + G[None, :, 1] * cy[:, None]
        Gw[:, :, 2] = G[None, :, 2]
        pts = np.arange(2 * nps)
        w.C_poly[pts, :, pts, :] = np.repeat(Gw, nps, axis=0)
        if ref.force_cap is not None:
            share = np.minimum(np.maximum(np.asarray(ref.force_cap, dtype=float)
                                          / self.ground.polytope.f_max, 0.0), 1.0)
        else:
            share = np.ones(2)
        nr = G.shape[0]
        u[6:].reshape(2, nps, nr)[:] = w.h_point[None, None, :] * share[:, None, None]
        lb3, ub3 = lb[nv:].reshape(2, nps, 3), ub[nv:].reshape(2, nps, 3)
        for i in range(2):
            if ref.stance[i]:
                lb3[i, :, :2] = -BIG
                ub3[i, :, :2] = BIG
                lb3[i, :, 2] = 0.0
                ub3[i, :, 2] = w.f_max_point * share[i]
            else:
                lb3[i] = 0.0
                ub3[i] = 0.0
        return h_a, Jt, et, names, M[6:], JT[6:]

    def _assemble_compiled(self, data: WBCData, q: np.ndarray, v: np.ndarray,
                           ref: WBCReference, feet: tuple[FootPoints, FootPoints]) -> np.ndarray:
        """Build the QP in ``data.work`` with the compiled assembly (:mod:`.wbc_qp`);
        returns the actuated rows of the nonlinear effects ``h_a`` [N·m].

        The compiled function reads Pinocchio's terms where Pinocchio writes them (views of
        ``data.pin``'s storage, bound once): M, h, the joint and CoM Jacobians, the CoM
        terms, the trunk's placement and the feet's parent joints' placements, velocities
        and drift accelerations, from which it forms the foot frames' terms itself. Only
        the references, the contact offsets and the trunk's orientation error are copied
        (one concatenate into the packed input)."""
        b = self.biped
        model, pd = b.model, data.pin
        a = data.assembly
        if a.owner is not pd:
            a.bind_inputs(self._pinocchio_inputs(pd), owner=pd)
        pin.computeAllTerms(model, pd, q, v)
        pin.updateFramePlacements(model, pd)
        pin.centerOfMass(model, pd, _ACCELERATION, False)
        R = a.inputs["R"]
        if not self._free_flyer:
            R[:] = matrix_from_quat_xyzw(q[3:7])
        if ref.force_cap is not None:
            f_max = self.ground.polytope.f_max
            share = (min(max(float(ref.force_cap[0]) / f_max, 0.0), 1.0),
                     min(max(float(ref.force_cap[1]) / f_max, 0.0), 1.0))
        else:
            share = (1.0, 1.0)
        w_force = self.config.w_force if ref.force_weight is None else ref.force_weight
        # the packed input p, in the order of wbc_qp.PACKED, written in one call
        np.concatenate((
            feet[0].offsets.ravel(), feet[1].offsets.ravel(),
            v[3:6], pin.log3(ref.R_trunk @ R.T), ref.omega, ref.com,
            ref.com_vel, ref.com_acc, ref.forces.ravel(), ref.swing_pos.ravel(),
            ref.swing_vel.ravel(), ref.swing_acc.ravel(), ref.sink_accel, (w_force,), share),
            out=a.p)
        a((bool(ref.stance[0]), bool(ref.stance[1])))
        return a.inputs["h"][6:]


_COMPILED: dict = {}


def _compiled(constants: AssemblyConstants, actuator_rows: tuple):
    """The compiled assembly and torque read-out for these constants and the rows taking
    v order to actuator order, built once per process."""
    key = (constants, actuator_rows)
    if key not in _COMPILED:
        _COMPILED[key] = compile_assembly(constants, actuator_rows)
    return _COMPILED[key]


__all__ = ["WholeBodyController", "WBCReference", "WBCData", "WBCWork", "FootPoints"]
