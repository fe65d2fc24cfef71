"""The whole-body QP's assembly as compiled code: one CasADi function per stance pair.

:meth:`~granular_mpc.control.wbc.WholeBodyController.solve` needs, every tick, the QP
``(H, g, A, b, C, l, u, lb, ub)`` built from Pinocchio's terms (M, h, the CoM and foot
Jacobians, the feet's velocities and drift accelerations) and the references. In NumPy
that is some sixty calls on 24-wide arrays, each dominated by the interpreter's per-call
overhead; here the same arithmetic (the same formulas, in the same order, as the NumPy
assembly of ``wbc.py``, which stays the reference) is one CasADi SX expression per stance
pair (left, right in stance or not: the task rows differ), generated to C once per
controller model with :func:`granular_mpc.codegen.compile_functions` and called through
CasADi's buffer interface on the WBC's preallocated arrays.

Inputs of each function (column-major, SI, world frame unless said), :data:`INPUTS` in
order — all but ``p`` are read straight from Pinocchio's ``Data`` after ``computeAllTerms``
and ``centerOfMass(ACCELERATION)`` (views bound once, :meth:`AssemblyCaller.bind_inputs`):

* ``M`` (nv × nv): the mass matrix, upper triangle (CRBA) [kg, kg m, kg m²];
* ``h`` (nv): nonlinear effects ``C(q, v) v + g(q)`` [N, N m];
* ``Jcom`` (3 × nv): CoM Jacobian; ``J`` (6 × nv): the joint Jacobians in the world frame
  (``Data.J``: spatial velocity at W's origin, linear rows first);
* ``com``, ``vcom``, ``acom`` (3): CoM position [m], velocity [m/s], drift acceleration
  (q̈ = 0) [m/s²];
* ``R`` (3 × 3): the trunk's rotation (the free flyer's placement, ``Data.oMi[1]``);
* per foot (left, right), of the foot frame's parent joint: ``R_l``/``R_r`` (3 × 3) and
  ``p_l``/``p_r`` (3) its placement ``Data.oMi`` [m], ``v_l``/``v_r`` (6) its spatial
  velocity and ``a_l``/``a_r`` (6) its drift acceleration, joint frame (``Data.v``,
  ``Data.a``; linear first) — the foot frame's placement, Jacobian (LOCAL_WORLD_ALIGNED),
  velocity and classical acceleration follow from them and the frame's fixed placement in
  its joint (:attr:`AssemblyConstants.foot_placement`) by Pinocchio's own formulas
  (``getFrameJacobian``, ``getFrameVelocity``, ``getFrameClassicalAcceleration``);
* ``p``: the packed rest (the references and the contact points' offsets),
  :data:`PACKED` (names and sizes in order).

Outputs: ``H`` (n × n), ``g`` (n), ``A^T`` (n × 6), ``b`` (6), ``C^T`` (n × n_in), ``l``,
``u`` (n_in), ``lb``, ``ub`` (n) — the transposes so that CasADi's column-major result is
the row-major ``A`` and ``C`` ProxSuite reads.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..codegen import compile_functions, compiler
from ..exceptions import SolverError

BIG = 1e20

#: the packed input ``p``: (name, size) in order (None: 2 feet × n_points × 3)
PACKED = (("offsets", None), ("omega_B", 3), ("err_W", 3),
          ("ref_omega", 3), ("ref_com", 3), ("ref_com_vel", 3), ("ref_com_acc", 3),
          ("forces", None), ("swing_pos", 6), ("swing_vel", 6), ("swing_acc", 6),
          ("sink_accel", 2), ("w_force", 1), ("share", 2))

#: the functions' inputs in order: Pinocchio's terms (see the module docstring), then ``p``
INPUTS = ("M", "h", "Jcom", "J", "com", "vcom", "acom", "R",
          "R_l", "p_l", "v_l", "a_l", "R_r", "p_r", "v_r", "a_r", "p")

#: stance pairs (left, right), the order of the compiled functions
STANCES = ((True, True), (True, False), (False, True), (False, False))


def packed_slices(n_points: int) -> dict[str, slice]:
    """Where each named input sits in ``p`` for ``n_points`` contact points per foot."""
    out, i = {}, 0
    for name, size in PACKED:
        size = 2 * n_points * 3 if size is None else size
        out[name] = slice(i, i + size)
        i += size
    return out


@dataclass(frozen=True)
class AssemblyConstants:
    """What the assembly takes from the controller's configuration (numbers only)."""

    nv: int
    n_points: int
    w_orientation_sqrt: tuple      # √ of the roll, pitch, yaw weights
    w_com: float
    w_swing: float
    w_contact: float
    w_regularisation: float
    kp_orientation: float
    kd_orientation: float
    kp_com: float
    kd_com: float
    swing_kp: float
    swing_kd: float
    contact_damping: float
    granular: bool
    tau_max: tuple                 # [N m]
    G: tuple                       # ground polytope rows (nr × 3), foot frame
    h_point: tuple                 # its bounds for one contact point [N]
    f_max_point: float             # largest normal force of one contact point [N]
    #: each foot frame's fixed placement in its parent joint: (rotation column-major (9),
    #: translation (3) [m]), left then right
    foot_placement: tuple = ()
    #: the velocity columns each foot's parent joint depends on (its support), left, right
    foot_support: tuple = ()


def input_shapes(nv: int) -> dict[str, tuple[int, int]]:
    """The shape of each input of :data:`INPUTS` but ``p`` (rows, columns)."""
    shapes = {"M": (nv, nv), "h": (nv, 1), "Jcom": (3, nv), "J": (6, nv), "com": (3, 1),
              "vcom": (3, 1), "acom": (3, 1), "R": (3, 3)}
    for s in "lr":
        shapes.update({f"R_{s}": (3, 3), f"p_{s}": (3, 1), f"v_{s}": (6, 1), f"a_{s}": (6, 1)})
    return shapes


def _mv(R: ca.SX, x) -> list:
    """``R x`` for a 3 × 3 ``R`` and a 3-vector ``x`` (Eigen's order: Σ_k R[a, k] x[k])."""
    return [R[a, 0] * x[0] + R[a, 1] * x[1] + R[a, 2] * x[2] for a in range(3)]


def _cross(a, b) -> list:
    """``a × b`` of 3-vectors (Eigen's formula)."""
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def foot_kinematics(J: ca.SX, R_i: ca.SX, p_i: ca.SX, v_i: ca.SX, a_i: ca.SX,
                    placement: tuple, support: tuple) -> tuple:
    """One foot frame's terms from its parent joint's, Pinocchio's formulas:

    * placement ``oMf = oMi · iMf``: ``R_f = R_i R_p``, ``p_f = p_i + R_i t_p``;
    * velocity (LOCAL_WORLD_ALIGNED): ``(R_i (v + ω × t_p), R_i ω)`` of the joint's
      spatial velocity (v, ω) in its own frame;
    * classical acceleration: the same map of the drift (a, α), plus ``ω_W × v_W``;
    * Jacobian: the support columns of ``Data.J`` with ``J_lin − p_f × J_ang``, others 0.

    Returns ``(J6 (6 × nv), acc (6), vel (6), R_f (3 × 3), p_f (3))`` (linear first)."""
    Rp = np.asarray(placement[:9], dtype=float).reshape(3, 3, order="F")
    t = [float(x) for x in placement[9:12]]
    R_f = ca.SX(3, 3)
    for r in range(3):
        for c in range(3):
            R_f[r, c] = R_i[r, 0] * Rp[0, c] + R_i[r, 1] * Rp[1, c] + R_i[r, 2] * Rp[2, c]
    Rt = _mv(R_i, t)
    p_f = [p_i[m] + Rt[m] for m in range(3)]
    w = [v_i[3 + m] for m in range(3)]
    wt = _cross(w, t)
    vel_lin = _mv(R_i, [v_i[m] + wt[m] for m in range(3)])
    vel_ang = _mv(R_i, w)
    al = [a_i[3 + m] for m in range(3)]
    at = _cross(al, t)
    acc_lin = _mv(R_i, [a_i[m] + at[m] for m in range(3)])
    wv = _cross(vel_ang, vel_lin)
    acc_lin = [acc_lin[m] + wv[m] for m in range(3)]
    acc_ang = _mv(R_i, al)
    nv = J.shape[1]
    J6 = ca.SX(6, nv)
    for c in support:
        col = J[:, c]
        pw = _cross(p_f, [col[3], col[4], col[5]])
        for m in range(3):
            J6[m, c] = col[m] - pw[m]
            J6[3 + m, c] = col[3 + m]
    return J6, ca.vertcat(*acc_lin, *acc_ang), ca.vertcat(*vel_lin, *vel_ang), R_f, p_f


def _skew(r) -> ca.SX:
    return ca.vertcat(ca.horzcat(0.0, -r[2], r[1]), ca.horzcat(r[2], 0.0, -r[0]),
                      ca.horzcat(-r[1], r[0], 0.0))


def _row(x) -> ca.SX:
    return ca.reshape(x, 1, x.numel())


def assembly_function(k: AssemblyConstants, stance: tuple[bool, bool]) -> ca.Function:
    """``wbc_qp_<l><r>(M, h, Jcom, J, …, p) -> (H, g, AT, b, CT, l, u, lb, ub)`` (inputs
    :data:`INPUTS`) for one stance pair (the formulas of the NumPy assembly in ``wbc.py``,
    same order; the foot frames' terms by :func:`foot_kinematics`)."""
    nv, nps = k.nv, k.n_points
    nf = 2 * nps * 3
    n = nv + nf
    G = np.asarray(k.G, dtype=float)
    nr = G.shape[0]
    n_in = 6 + 2 * nps * nr
    sl = packed_slices(nps)
    syms = {name: ca.SX.sym(name, *shape) for name, shape in input_shapes(nv).items()}
    syms["p"] = p = ca.SX.sym("p", sl["share"].stop)
    M_in, h, Jcom = syms["M"], syms["h"], syms["Jcom"]
    P = {name: p[s] for name, s in sl.items()}
    P.update(com=syms["com"], vcom=syms["vcom"], acom=syms["acom"])
    feet = [foot_kinematics(syms["J"], syms[f"R_{s}"], syms[f"p_{s}"], syms[f"v_{s}"],
                            syms[f"a_{s}"], k.foot_placement[i], k.foot_support[i])
            for i, s in enumerate("lr")]
    J6 = ca.vertcat(feet[0][0], feet[1][0])
    P["acc"] = ca.vertcat(feet[0][1], feet[1][1])
    P["vel"] = ca.vertcat(feet[0][2], feet[1][2])
    P["p_f"] = ca.vertcat(*feet[0][4], *feet[1][4])
    # Pinocchio's CRBA fills the upper triangle
    M = ca.SX(nv, nv)
    for i in range(nv):
        for j in range(nv):
            M[i, j] = M_in[min(i, j), max(i, j)]
    Jrows, erows, wrows = [], [], []
    # trunk orientation
    R = syms["R"]
    omega_W = ca.mtimes(R, P["omega_B"])
    alpha_W = k.kp_orientation * P["err_W"] + k.kd_orientation * (P["ref_omega"] - omega_W)
    sw = k.w_orientation_sqrt
    J_or = ca.SX(3, nv)
    J_or[0, 3], J_or[1, 4], J_or[2, 5] = sw
    RtA = ca.mtimes(R.T, alpha_W)
    Jrows.append(J_or)
    erows.append(ca.vertcat(*[0.0 - sw[a] * RtA[a] for a in range(3)]))
    wrows += [1.0] * 3
    # CoM
    a_com = (P["ref_com_acc"] + k.kp_com * (P["ref_com"] - P["com"])
             + k.kd_com * (P["ref_com_vel"] - P["vcom"]))
    Jrows.append(Jcom)
    erows.append(P["acom"] - a_com)
    wrows += [k.w_com] * 3
    # feet
    acc, vel, off = P["acc"], P["vel"], P["offsets"]
    Jp_cols = []                       # contact point Jacobians, (foot, point) order
    for i in range(2):
        Jo, Jw = J6[6 * i:6 * i + 3, :], J6[6 * i + 3:6 * i + 6, :]
        ax, ay, az, alx, aly, alz = (acc[6 * i + m] for m in range(6))
        vx, vy, vz, wx, wy, wz = (vel[6 * i + m] for m in range(6))
        for j in range(nps):
            o = 3 * (i * nps + j)
            rx, ry, rz = off[o], off[o + 1], off[o + 2]
            Jp = Jo - ca.mtimes(_skew((rx, ry, rz)), Jw)
            Jp_cols.append(Jp)
            if not stance[i]:
                continue
            wrx, wry, wrz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
            drift = (ax + (aly * rz - alz * ry) + (wy * wrz - wz * wry),
                     ay + (alz * rx - alx * rz) + (wz * wrx - wx * wrz),
                     az + (alx * ry - aly * rx) + (wx * wry - wy * wrx))
            vp = (vx + wrx, vy + wry, vz + wrz)
            if k.granular:
                a_des = [-k.contact_damping * vp[m] for m in range(3)]
                a_des[2] = a_des[2] - P["sink_accel"][i]
            else:
                a_des = [-40.0 * vp[m] for m in range(3)]
            Jrows.append(Jp)
            erows.append(ca.vertcat(*[drift[m] - a_des[m] for m in range(3)]))
            wrows += [k.w_contact] * 3
        if not stance[i]:
            p_o = P["p_f"][3 * i:3 * i + 3]
            a_des = (P["swing_acc"][3 * i:3 * i + 3]
                     + k.swing_kp * (P["swing_pos"][3 * i:3 * i + 3] - p_o)
                     + k.swing_kd * (P["swing_vel"][3 * i:3 * i + 3] - vel[6 * i:6 * i + 3]))
            Jrows.append(Jo)
            erows.append(acc[6 * i:6 * i + 3] - a_des)
            wrows += [k.w_swing] * 3
    Jt = ca.vertcat(*Jrows)
    et = ca.vertcat(*erows)
    WJ = ca.vertcat(*[Jt[r, :] * wrows[r] for r in range(Jt.shape[0])])
    Hq = ca.mtimes(Jt.T, WJ)
    for a in range(nv):
        Hq[a, a] = Hq[a, a] + k.w_regularisation
    H = ca.SX(n, n)
    H[:nv, :nv] = (Hq + Hq.T) * 0.5
    w_force = P["w_force"]
    for a in range(nf):
        H[nv + a, nv + a] = w_force
    g = ca.vertcat(ca.mtimes(WJ.T, et), -w_force * P["forces"])
    JT = ca.horzcat(*[Jp.T for Jp in Jp_cols])                     # (nv, nf)
    A = ca.horzcat(M[:6, :], -JT[:6, :])
    b = -h[:6]
    tau_max = np.asarray(k.tau_max, dtype=float)
    h_a = h[6:]
    C = ca.SX(n_in, n)
    C[:6, :] = ca.horzcat(M[6:, :], -JT[6:, :])
    l = ca.vertcat(-tau_max - h_a, ca.DM.ones(n_in - 6) * -BIG)
    u_rows = [tau_max - h_a]
    share = P["share"]
    for i in range(2):
        R_f = feet[i][3]
        yaw = ca.atan2(R_f[1, 0], R_f[0, 0])
        cy, sy = ca.cos(yaw), ca.sin(yaw)
        Gw = ca.SX(nr, 3)
        for r in range(nr):
            Gw[r, 0] = G[r, 0] * cy + G[r, 1] * (-sy)
            Gw[r, 1] = G[r, 0] * sy + G[r, 1] * cy
            Gw[r, 2] = G[r, 2]
        for j in range(nps):
            pt = i * nps + j
            C[6 + pt * nr:6 + (pt + 1) * nr, nv + 3 * pt:nv + 3 * pt + 3] = Gw
            u_rows.append(ca.DM(np.asarray(k.h_point, dtype=float)) * share[i])
    u = ca.vertcat(*u_rows)
    lb, ub = [-BIG] * nv, [BIG] * nv
    for i in range(2):
        for _ in range(nps):
            if stance[i]:
                lb += [-BIG, -BIG, 0.0]
                ub += [BIG, BIG, k.f_max_point * share[i]]
            else:
                lb += [0.0] * 3
                ub += [0.0] * 3
    lb = ca.vertcat(*[ca.SX(x) for x in lb])
    ub = ca.vertcat(*[x if isinstance(x, ca.SX) else ca.SX(x) for x in ub])
    name = "wbc_qp_" + "".join("s" if s else "w" for s in stance)
    outs = [ca.densify(x) for x in (H, g, A.T, b, C.T, l, u, lb, ub)]
    return ca.Function(name, [syms[x] for x in INPUTS], outs, list(INPUTS),
                       ["H", "g", "AT", "b", "CT", "l", "u", "lb", "ub"])


def torque_function(k: AssemblyConstants, actuator_rows: tuple) -> ca.Function:
    """``wbc_tau(CT, h, x) -> (tau, tau_act)``: the joint torques of a QP solution
    ``x = [q̈, f]``, ``τ = M_a q̈ + h_a − J_aᵀ f`` (C's first six rows are ``[M_a, −J_aᵀ]``:
    ``CT`` is C's transpose, the row-major ``C`` read as column-major), clipped to
    ±``tau_max`` [N m]; ``tau`` in v order of the actuated joints, ``tau_act`` the same
    numbers in actuator order (``tau[actuator_rows]``). The sums in the grouping of the
    NumPy read-out, ``(M_a q̈ + h_a) + (−J_aᵀ) f``."""
    nv, nps = k.nv, k.n_points
    n = nv + 2 * nps * 3
    n_in = 6 + 2 * nps * np.asarray(k.G).shape[0]
    CT = ca.SX.sym("CT", n, n_in)
    h = ca.SX.sym("h", nv)
    x = ca.SX.sym("x", n)
    tau_max = np.asarray(k.tau_max, dtype=float)
    tau = []
    for r in range(nv - 6):
        acc = CT[0, r] * x[0]
        for j in range(1, nv):
            acc = acc + CT[j, r] * x[j]
        frc = CT[nv, r] * x[nv]
        for j in range(nv + 1, n):
            frc = frc + CT[j, r] * x[j]
        t = (acc + h[6 + r]) + frc
        tau.append(ca.fmin(ca.fmax(t, -tau_max[r]), tau_max[r]))
    return ca.Function("wbc_tau", [CT, h, x],
                       [ca.vertcat(*tau), ca.vertcat(*[tau[r] for r in actuator_rows])],
                       ["CT", "h", "x"], ["tau", "tau_act"])


def compile_assembly(k: AssemblyConstants, actuator_rows: tuple) -> dict | None:
    """The compiled functions by stance pair and the torque read-out
    :func:`torque_function` (``actuator_rows``: v order → actuator order) under the key
    ``"tau"``, or None where nothing can be
    compiled (no C compiler, or ``GRANULAR_MPC_JIT=0``): CasADi's interpreter would be
    slower than the NumPy assembly, which then runs instead."""
    if compiler() is None or os.environ.get("GRANULAR_MPC_JIT", "1") == "0":
        return None
    fns = [assembly_function(k, s) for s in STANCES] + [torque_function(k, tuple(actuator_rows))]
    keys = list(STANCES) + ["tau"]
    lib = compile_functions("wbc_qp", fns)
    return {key: lib[f.name()] for key, f in zip(keys, fns)}


class AssemblyCaller:
    """Calls the compiled assembly through CasADi's buffer interface: inputs are this
    object's arrays (:attr:`inputs`, by the names of :data:`INPUTS`; fill them, or bind
    other storage with :meth:`bind_inputs`), outputs land in the given QP arrays in place.
    :attr:`p` is the packed input, :attr:`views` its named slices."""

    def __init__(self, functions: dict, nv: int, n_points: int, outputs: tuple) -> None:
        self.slices = packed_slices(n_points)
        self.p = np.zeros(self.slices["share"].stop)
        self.views = {name: self.p[s] for name, s in self.slices.items()}
        self.inputs = {name: np.zeros(shape, order="F")
                       for name, shape in input_shapes(nv).items()}
        self.inputs["p"] = self.p
        self._calls = {}
        for stance, fn in functions.items():
            if stance == "tau":
                continue
            buf, call = fn.buffer()
            for i, name in enumerate(INPUTS):
                buf.set_arg(i, memoryview(self.inputs[name].reshape(-1, order="A")))
            for i, a in enumerate(outputs):
                buf.set_res(i, memoryview(a.reshape(-1)))
            self._calls[stance] = (buf, call)
        self.owner = None       # what bound inputs belong to (:meth:`bind_inputs`)
        self.x = np.zeros(len(outputs[0]))          # the QP's solution, copied in
        self.tau = np.zeros(nv - 6)                 # v order of the actuated joints
        self.tau_act = np.zeros(nv - 6)             # actuator order
        buf, call = functions["tau"].buffer()
        C = outputs[4]
        buf.set_arg(0, memoryview(C.reshape(-1)))   # row-major C = column-major Cᵀ
        buf.set_arg(1, memoryview(self.inputs["h"].reshape(-1, order="A")))
        buf.set_arg(2, memoryview(self.x))
        buf.set_res(0, memoryview(self.tau))
        buf.set_res(1, memoryview(self.tau_act))
        self.torque = (buf, call)      # the torque read-out (:meth:`torques`)

    def torques(self, x: np.ndarray) -> None:
        """The clipped joint torques of the QP solution ``x`` [N m] into :attr:`tau` (v
        order) and :attr:`tau_act` (actuator order), from the C and h of the last
        assembly (:func:`torque_function`)."""
        self.x[:] = x
        self.torque[1]()

    def bind_inputs(self, arrays: dict[str, np.ndarray], owner=None) -> None:
        """Read the named inputs straight from these arrays from now on, instead of this
        object's own: e.g. views of Pinocchio's ``Data.M``, ``Data.nle``, ``Data.J``,
        ``Data.oMi[j].rotation``, ``Data.v[j].vector`` (column-major, stable storage that
        Pinocchio's algorithms overwrite in place), which saves a call and a copy per input
        and tick. ``owner`` (kept alive, see :attr:`owner`) is the object whose storage
        they view.

        Raises:
            SolverError: an array of another shape than the input's (a 1-column input
                also takes a 1-D array of its length), not column-major or not float64.
        """
        for name, arr in arrays.items():
            own = self.inputs[name]
            shape_ok = arr.shape == own.shape or (own.ndim == 2 and own.shape[1] == 1
                                                 and arr.shape == own.shape[:1])
            if not shape_ok or not arr.flags.f_contiguous or arr.dtype != np.float64:
                raise SolverError(f"assembly input {name} of shape {arr.shape} cannot replace "
                                  f"one of {own.shape} (column-major float64 expected)")
        self.inputs.update(arrays)
        self.owner = owner
        for buf, _ in self._calls.values():
            for i, name in enumerate(INPUTS):
                if name in arrays:
                    buf.set_arg(i, memoryview(arrays[name].reshape(-1, order="A")))
        if "h" in arrays:
            self.torque[0].set_arg(1, memoryview(arrays["h"].reshape(-1, order="A")))

    def __call__(self, stance: tuple[bool, bool]) -> None:
        self._calls[stance][1]()


__all__ = ["AssemblyConstants", "AssemblyCaller", "assembly_function", "compile_assembly",
           "foot_kinematics", "input_shapes", "packed_slices", "torque_function", "INPUTS",
           "PACKED", "STANCES"]
