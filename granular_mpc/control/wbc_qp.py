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

Inputs of each function (column-major, SI, world frame unless said):

* ``M`` (nv × nv): Pinocchio's mass matrix, upper triangle (CRBA) [kg, kg m, kg m²];
* ``h`` (nv): nonlinear effects ``C(q, v) v + g(q)`` [N, N m];
* ``Jcom`` (3 × nv): CoM Jacobian; ``J6`` (12 × nv): both feet's frame Jacobians
  (LOCAL_WORLD_ALIGNED, linear rows first), left then right;
* ``p``: the packed rest, :data:`PACKED` (names and sizes in order).

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

#: the packed input ``p``: (name, size) in order; ``rot_f`` and ``R`` column-major
PACKED = (("com", 3), ("vcom", 3), ("acom", 3), ("acc", 12), ("vel", 12), ("rot_f", 18),
          ("p_f", 6), ("offsets", None), ("R", 9), ("omega_B", 3), ("err_W", 3),
          ("ref_omega", 3), ("ref_com", 3), ("ref_com_vel", 3), ("ref_com_acc", 3),
          ("forces", None), ("swing_pos", 6), ("swing_vel", 6), ("swing_acc", 6),
          ("sink_accel", 2), ("w_force", 1), ("share", 2))

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


def _skew(r) -> ca.SX:
    return ca.vertcat(ca.horzcat(0.0, -r[2], r[1]), ca.horzcat(r[2], 0.0, -r[0]),
                      ca.horzcat(-r[1], r[0], 0.0))


def _row(x) -> ca.SX:
    return ca.reshape(x, 1, x.numel())


def assembly_function(k: AssemblyConstants, stance: tuple[bool, bool]) -> ca.Function:
    """``wbc_qp_<l><r>(M, h, Jcom, J6, p) -> (H, g, AT, b, CT, l, u, lb, ub)`` for one
    stance pair (the formulas of the NumPy assembly in ``wbc.py``, same order)."""
    nv, nps = k.nv, k.n_points
    nf = 2 * nps * 3
    n = nv + nf
    G = np.asarray(k.G, dtype=float)
    nr = G.shape[0]
    n_in = 6 + 2 * nps * nr
    sl = packed_slices(nps)
    M_in = ca.SX.sym("M", nv, nv)
    h = ca.SX.sym("h", nv)
    Jcom = ca.SX.sym("Jcom", 3, nv)
    J6 = ca.SX.sym("J6", 12, nv)
    p = ca.SX.sym("p", sl["share"].stop)
    P = {name: p[s] for name, s in sl.items()}
    # Pinocchio's CRBA fills the upper triangle
    M = ca.SX(nv, nv)
    for i in range(nv):
        for j in range(nv):
            M[i, j] = M_in[min(i, j), max(i, j)]
    Jrows, erows, wrows = [], [], []
    # trunk orientation
    R = ca.reshape(P["R"], 3, 3)
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
    rot = P["rot_f"]
    for i in range(2):
        # R column-major: rot[0] = R[0,0], rot[1] = R[1,0]
        yaw = ca.atan2(rot[9 * i + 1], rot[9 * i + 0])
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
    return ca.Function(name, [M_in, h, Jcom, J6, p], outs,
                       ["M", "h", "Jcom", "J6", "p"],
                       ["H", "g", "AT", "b", "CT", "l", "u", "lb", "ub"])


def compile_assembly(k: AssemblyConstants) -> dict[tuple[bool, bool], ca.Function] | None:
    """The compiled functions by stance pair, or None where nothing can be compiled (no C
    compiler, or ``GRANULAR_MPC_JIT=0``): CasADi's interpreter would be slower than the
    NumPy assembly, which then runs instead."""
    if compiler() is None or os.environ.get("GRANULAR_MPC_JIT", "1") == "0":
        return None
    fns = [assembly_function(k, s) for s in STANCES]
    lib = compile_functions("wbc_qp", fns)
    return {s: lib[f.name()] for s, f in zip(STANCES, fns)}


class AssemblyCaller:
    """Calls the compiled assembly through CasADi's buffer interface: inputs are this
    object's arrays (fill them), outputs land in the given QP arrays in place."""

    def __init__(self, functions: dict, nv: int, n_points: int, outputs: tuple) -> None:
        self.M = np.zeros((nv, nv), order="F")
        self.h = np.zeros(nv)
        self.Jcom = np.zeros((3, nv), order="F")
        self.J6 = np.zeros((12, nv), order="F")
        self.slices = packed_slices(n_points)
        self.p = np.zeros(self.slices["share"].stop)
        self.views = {name: self.p[s] for name, s in self.slices.items()}
        self._calls = {}
        for stance, fn in functions.items():
            buf, call = fn.buffer()
            for i, a in enumerate((self.M, self.h, self.Jcom, self.J6, self.p)):
                buf.set_arg(i, memoryview(a.reshape(-1, order="A")))
            for i, a in enumerate(outputs):
                buf.set_res(i, memoryview(a.reshape(-1)))
            self._calls[stance] = (buf, call)
        self.owner = None       # what bound inputs belong to (:meth:`bind_inputs`)

    def bind_inputs(self, M: np.ndarray, h: np.ndarray, Jcom: np.ndarray, owner=None) -> None:
        """Read ``M``, ``h`` and ``Jcom`` straight from these arrays from now on, instead of
        this object's own copies: e.g. the views of Pinocchio's ``Data.M``, ``Data.nle``,
        ``Data.Jcom`` (column-major, stable storage), which saves three copies per call.
        ``owner`` (kept alive, see :attr:`owner`) is the object whose storage they view."""
        for arr, own in ((M, self.M), (h, self.h), (Jcom, self.Jcom)):
            if arr.shape != own.shape or not arr.flags.f_contiguous or arr.dtype != np.float64:
                raise SolverError(f"assembly input of shape {arr.shape} cannot replace one of "
                                 f"{own.shape} (column-major float64 expected)")
        self.M, self.h, self.Jcom, self.owner = M, h, Jcom, owner
        for buf, _ in self._calls.values():
            for i, a in enumerate((M, h, Jcom)):
                buf.set_arg(i, memoryview(a.reshape(-1, order="A")))

    def __call__(self, stance: tuple[bool, bool]) -> None:
        self._calls[stance][1]()


__all__ = ["AssemblyConstants", "AssemblyCaller", "assembly_function", "compile_assembly",
           "packed_slices", "PACKED", "STANCES"]
