"""The MPC's QP assembly as compiled code: one CasADi function for the QP, one for the
predicted states, generated to C once per problem size.

:meth:`~granular_mpc.control.mpc.CentroidalMPC.solve` needs, every tick, the QP
``(H, g, C, u, lb, ub)`` of the condensed centroidal model (``l`` is constant) and, after
the solve, the predicted states. In NumPy (``CentroidalMPC(assembly="numpy")``, the
reference) that is some sixty calls on arrays of a few dozen numbers, each dominated by the
interpreter's per-call overhead (≈ 0.3 ms a tick); here it is one call of generated C on
preallocated buffers (CasADi's buffer interface, as :mod:`.wbc_qp`), over a fixed
``max_pairs`` variable blocks: which (step, foot) pair each block holds is an input, the
one-hot matrix ``sel``; an unused block's row of ``sel`` is zero, which zeroes its cost,
rows, bounds and its effect on the states.

**The condensation in closed form.** The prediction is ``x_k = free_k + Σ_j Γ_kj U_j`` with,
for the block j of step ``k_j`` (0 … N−1) and the states k = 1 … N,
``Γ_kj = B_j + (k − 1 − k_j) E_j`` if k > k_j, else 0 (``B_j`` the block's discrete input
matrix, ``E_j = (A dt) B_j``, A² = 0). The state weight Q is the same at every step, so with
the step tables of :class:`CondensationTables`

    H_ij = Σ_k Γ_kiᵀ Q Γ_kj = S0[k_i,k_j] B_iᵀQB_j + S1[k_i,k_j] B_iᵀQE_j
                              + S1[k_j,k_i] E_iᵀQB_j + S2[k_i,k_j] E_iᵀQE_j,
    g_j  = Σ_k Γ_kjᵀ Q e_k   = B_jᵀ T0[k_j] + E_jᵀ T1[k_j],   T0 = R (Q e), T1 = L (Q e),

and the products of the B and E blocks reduce to two (nu × 3 × nu) products (comments of
:func:`assembly_functions`) instead of the (nu × 12 N) · (12 N × nu) one of the stacked
map: the same QP to round-off (``tests/test_mpc_assembly.py``: 1e-12 of each array's
largest entry against a step-by-step NumPy reference, measured ≤ 1e-15).

Inputs (numbers in the layout the NumPy arrays have, C order):

* ``model``: the model's numbers, :meth:`MPCAssemblyConstants.packed` (so the library is
  specialised to the sizes only: horizon, points per foot, blocks, polytope rows);
* ``x0`` (12): the current state [rad, m, rad/s, m/s];
* ``xref`` (N, 12): the reference after each step (yaw not unwrapped: that is done here);
* ``points`` (N, 2, n_points, 3): the contact points [m], world frame;
* ``capacity`` (N, 2): largest normal force of each foot at each step [N];
* ``sel`` (max_pairs, 2 N): ``sel[j, 2 k + f] = 1`` if block j holds foot f at step k.

Outputs of ``mpc_qp``: ``H`` (nu × nu, symmetric), ``g`` (nu), ``CT`` (nu × n_in, so
that the column-major result is the row-major ``C``), ``u`` (n_in), ``lb``, ``ub`` (nu) —
in the QP's variables (forces / ``force_unit``), and ``aux`` for ``mpc_states``, which
takes it and the solution ``U`` [N] (nu) and returns ``free + Γ U`` as (N, 12).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..codegen import compile_functions, compiler

BIG = 1e20


@dataclass(frozen=True)
class CondensationTables:
    """Step tables of an N-step horizon (constant; rows: a block's step a = 0 … N−1,
    columns: the state after step k = 1 … N, or another block's step b).

    Attributes:
        reach: (N, N) ``[k > a]``: the block's force acts on that state.
        lag: (N, N) ``(k − 1 − a)[k > a]``: drift steps in between (Γ_kj = B_j + lag·E_j).
        s0: (N, N) ``reach @ reachᵀ``: states both blocks a, b act on.
        s1: (N, N) ``reach @ lagᵀ``: Σ of b's lag over them.
        s2: (N, N) ``lag @ lagᵀ``: Σ of the product of both lags.
    """

    reach: np.ndarray
    lag: np.ndarray
    s0: np.ndarray
    s1: np.ndarray
    s2: np.ndarray


def condensation_tables(N: int) -> CondensationTables:
    """The :class:`CondensationTables` of an ``N``-step horizon."""
    a = np.arange(N, dtype=float)[:, None]
    k = np.arange(1, N + 1, dtype=float)[None, :]
    reach = (k > a).astype(float)
    lag = np.where(k > a, k - 1.0 - a, 0.0)
    return CondensationTables(reach, lag, reach @ reach.T, reach @ lag.T, lag @ lag.T)


@dataclass(frozen=True)
class MPCAssemblyConstants:
    """The MPC model's numbers the assembly needs (SI). They are an input of the compiled
    function (:meth:`packed`), so one library serves every model of the same
    :attr:`sizes` (weights, terrain, QP scaling alike).

    Attributes:
        horizon: N steps; n_points: contact points per foot; max_pairs: variable blocks.
        dt: MPC step [s]; mass [kg]; gravity [m/s²].
        inertia_inv_B: inverse centroidal inertia, trunk frame, row-major 3×3 [1/(kg m²)].
        q: the 12 state-error weights of one step.
        weight_force: the force regulariser (per N², before scaling).
        force_unit: force of one unit of the QP's variables [N] (m g when scaled, else 1).
        rows_point: one pair's constraint rows, yaw frame, row-major (rows_per_pair ×
            n_points·3): the polytope's cone rows on each point, its capacity rows on
            their sum.
        h_capacity: the capacity rows' bounds [N]; f_max: the polytope's normal bound [N].
    """

    horizon: int
    n_points: int
    max_pairs: int
    dt: float
    mass: float
    gravity: float
    inertia_inv_B: tuple
    q: tuple
    weight_force: float
    force_unit: float
    rows_point: tuple
    h_capacity: tuple
    f_max: float

    @property
    def sizes(self) -> tuple[int, int, int, int, int]:
        """(horizon, n_points, max_pairs, rows_per_pair, capacity rows): what the compiled
        code is specialised to."""
        npair = 3 * self.n_points
        return (self.horizon, self.n_points, self.max_pairs, len(self.rows_point) // npair,
                len(self.h_capacity))

    def packed(self) -> np.ndarray:
        """The numbers as the compiled functions' ``model`` input, in :data:`MODEL` order."""
        return np.concatenate([[self.dt, self.mass, self.gravity], self.inertia_inv_B, self.q,
                               [self.weight_force, self.force_unit, self.f_max],
                               self.rows_point, self.h_capacity]).astype(float)


#: the packed ``model`` input: (name, size) in order; None sizes depend on the polytope
MODEL = (("dt", 1), ("mass", 1), ("gravity", 1), ("inertia_inv_B", 9), ("q", 12),
         ("weight_force", 1), ("force_unit", 1), ("f_max", 1), ("rows_point", None),
         ("h_capacity", None))


def assembly_functions(sizes: tuple[int, int, int, int, int]) -> tuple[ca.Function,
                                                                      ca.Function]:
    """``mpc_qp(model, x0, xref, points, capacity, sel) -> (H, g, CT, u, lb, ub, aux)`` and
    ``mpc_states(aux, U) -> states`` for :attr:`MPCAssemblyConstants.sizes` ``sizes``
    (``aux``: what the states need from the assembly, B, E, the free response and the
    step tables of the blocks)."""
    N, nps, Pm, rpp, ncap = sizes
    npair = 3 * nps
    nu = Pm * npair
    tables = condensation_tables(N)
    model = ca.MX.sym("model", 27 + rpp * npair + ncap)
    dt, mass, grav = model[0], model[1], model[2]
    Ii_B = ca.reshape(model[3:12], 3, 3).T
    q = model[12:24]
    wf, fu, f_max = model[24], model[25], model[26]
    rows_pointT = ca.reshape(model[27:27 + rpp * npair], npair, rpp)
    h_cap = model[27 + rpp * npair:]
    h2 = 0.5 * dt * dt

    x0 = ca.MX.sym("x0", 12)
    xref = ca.MX.sym("xref", 12, N)
    points = ca.MX.sym("points", npair, 2 * N)
    capacity = ca.MX.sym("capacity", 2 * N)
    selT = ca.MX.sym("sel", 2 * N, Pm)
    sel = selT.T
    selK = ca.mtimes(sel, ca.DM(np.kron(np.eye(N), np.ones((2, 1)))))   # (Pm, N)
    mask = ca.sum2(sel)                                                  # (Pm, 1)
    Rk = ca.mtimes(selK, ca.DM(tables.reach))                            # (Pm, N)
    Lk = ca.mtimes(selK, ca.DM(tables.lag))
    # yaw frame
    yaw = xref[2, 0]
    c, s = ca.cos(yaw), ca.sin(yaw)
    Rz = ca.vertcat(ca.horzcat(c, -s, 0.0), ca.horzcat(s, c, 0.0), ca.horzcat(0.0, 0.0, 1.0))
    RzT = Rz.T
    Ii = ca.mtimes([Rz, Ii_B, RzT])
    # levers (3, n_points·Pm), pair-major: point minus the reference CoM of its step
    com = ca.mtimes(xref[3:6, :], selK.T)                                # (3, Pm)
    r = ca.reshape(ca.mtimes(points, selT) - ca.repmat(com, nps, 1), 3, nps * Pm)
    X, Y, Z = r[0, :], r[1, :], r[2, :]
    # I_W⁻¹ [r]× column by column ([r]× e_c = r × e_c), interleaved to (3, nu)
    c0 = ca.mtimes(Ii[:, 1], Z) - ca.mtimes(Ii[:, 2], Y)
    c1 = ca.mtimes(Ii[:, 2], X) - ca.mtimes(Ii[:, 0], Z)
    c2 = ca.mtimes(Ii[:, 0], Y) - ca.mtimes(Ii[:, 1], X)
    IS = ca.reshape(ca.vertcat(c0, c1, c2), 3, nu)
    RIS = ca.mtimes(RzT, IS)
    eye = ca.DM(np.tile(np.eye(3), nps * Pm)) / mass
    B = ca.vertcat(RIS * h2, eye * h2, IS * dt, eye * dt)                # (12, nu)
    E = ca.vertcat(ca.mtimes(RzT * dt, IS * dt), eye * dt * dt)          # (6, nu) rows Θ, p
    # free response and its error to the (yaw-unwrapped) reference
    ks = np.arange(1, N + 1, dtype=float)[None, :]
    adt = ca.vertcat(ca.mtimes(RzT * dt, x0[6:9]), dt * x0[9:12], ca.DM.zeros(6))
    cd = ca.vertcat(ca.DM.zeros(5), -grav * h2, ca.DM.zeros(5), -grav * dt)
    acd = ca.vertcat(ca.DM.zeros(5), dt * (-grav * dt), ca.DM.zeros(6))
    free = (ca.repmat(x0, 1, N) + ca.mtimes(adt, ca.DM(ks)) + ca.mtimes(cd, ca.DM(ks))
            + ca.mtimes(acd, ca.DM(0.5 * ks * (ks - 1))))
    yaw_err = xref[2, :] - x0[2] + np.pi
    wrapped = ca.fmod(yaw_err, 2.0 * np.pi)       # Python's %: fmod, then + 2π if < 0
    wrapped = wrapped + (wrapped < 0.0) * (2.0 * np.pi)
    ref = ca.vertcat(xref[0:2, :], x0[2] + wrapped - np.pi, xref[3:12, :])
    Qe = (free - ref) * ca.repmat(q, 1, N)                               # (12, N)
    # cost (the closed-form condensation of the module docstring). Rows of B_j: Θ: h2 R_zᵀ
    # I_W⁻¹[r]×, p: h2/m, ω: dt I_W⁻¹[r]×, v: dt/m; those of E_j are Θ: dt² R_zᵀ I_W⁻¹[r]×,
    # p: dt²/m. With V = √q_Θ R_zᵀ I_W⁻¹[r]× and W = √q_ω I_W⁻¹[r]× (3 × nu each) and
    # D_p = q_p/m², D_v = q_v/m² (axis by axis, every pair of points):
    # B_iᵀQB_j = h2² (VᵀV + D_p) + dt² (WᵀW + D_v), B_iᵀQE_j = h2 dt² (VᵀV + D_p),
    # E_iᵀQE_j = dt⁴ (VᵀV + D_p), so
    #   H = fu² [(VᵀV + D_p) ∘ (h2² S0 + h2 dt² (S1 + S1ᵀ) + dt⁴ S2) + (WᵀW + D_v) ∘ dt² S0]
    #       + w_f fu² I
    # with the step tables S expanded to the blocks: two (nu × 3 × nu) products instead of
    # three (nu × 12 × nu) ones, and an H symmetric to the last bit (every term is).
    sq = ca.sqrt(q)
    V = ca.mtimes(ca.diag(sq[0:3]), RIS)
    W = IS * ca.repmat(sq[6:9], 1, nu)
    S0 = ca.mtimes(Rk, Rk.T)
    S1 = ca.mtimes(Rk, Lk.T)
    S2 = ca.mtimes(Lk, Lk.T)
    f2 = fu * fu
    CV = S0 * (f2 * h2 * h2) + (S1 + S1.T) * (f2 * h2 * dt * dt) + S2 * (f2 * dt ** 4)
    CW = S0 * (f2 * dt * dt)
    ones = ca.DM.ones(npair, npair)
    pattern = ca.DM.ones(nps, nps)
    Dp = ca.kron(pattern, ca.diag(q[3:6])) / (mass * mass)
    Dv = ca.kron(pattern, ca.diag(q[9:12])) / (mass * mass)
    H = (ca.mtimes(V.T, V) * ca.kron(CV, ones) + ca.mtimes(W.T, W) * ca.kron(CW, ones)
         + ca.kron(CV, Dp) + ca.kron(CW, Dv) + ca.DM.eye(nu) * (wf * f2))
    T0 = ca.mtimes(Rk, Qe.T)                                             # (Pm, 12)
    T1 = ca.mtimes(Lk, Qe[0:6, :].T)                                     # (Pm, 6)
    spread = ca.DM.ones(1, npair)
    g = (ca.sum1(B * ca.kron(T0.T, spread)) + ca.sum1(E * ca.kron(T1.T, spread))).T * fu
    # constraint rows (in newtons: C u = (C fu)(F / fu)), bounds
    blockT = ca.mtimes(ca.kron(ca.DM.eye(nps), Rz), rows_pointT) * fu   # (npair, rpp)
    CT = ca.kron(ca.densify(ca.diag(mask)), blockT)                      # (nu, n_in)
    share = ca.fmin(ca.fmax(ca.mtimes(sel, capacity) / f_max, 0.0), 1.0)  # (Pm, 1)
    u = ca.vec(ca.vertcat(ca.DM.zeros(rpp - ncap, Pm), ca.mtimes(h_cap, share.T)))
    lb_pair = np.tile([-BIG, -BIG, 0.0], nps)[:, None]
    z_rows = np.tile([0.0, 0.0, 1.0], nps)[:, None]
    lb = ca.vec(ca.mtimes(ca.DM(lb_pair), mask.T))
    ub = ca.vec(ca.mtimes(ca.DM(-lb_pair), mask.T)
                + ca.mtimes(ca.DM(z_rows), (f_max * share / nps / fu).T))
    aux = ca.vertcat(ca.vec(B), ca.vec(E), ca.vec(free), ca.vec(Rk), ca.vec(Lk))
    qp = ca.Function("mpc_qp", [model, x0, xref, points, capacity, selT],
                     [ca.densify(x) for x in (H, g, CT, u, lb, ub, aux)],
                     ["model", "x0", "xref", "points", "capacity", "sel"],
                     ["H", "g", "CT", "u", "lb", "ub", "aux"])
    # predicted states: free + Σ_j R[k_j, k] B_j U_j + L[k_j, k] E_j U_j
    A = ca.MX.sym("aux", aux.numel())
    U = ca.MX.sym("U", nu)
    i = np.cumsum([0, 12 * nu, 6 * nu, 12 * N, Pm * N, Pm * N])
    B_, E_ = ca.reshape(A[i[0]:i[1]], 12, nu), ca.reshape(A[i[1]:i[2]], 6, nu)
    free_ = ca.reshape(A[i[2]:i[3]], 12, N)
    Rk_, Lk_ = ca.reshape(A[i[3]:i[4]], Pm, N), ca.reshape(A[i[4]:i[5]], Pm, N)
    Ublk = ca.DM(np.kron(np.eye(Pm), np.ones((npair, 1))))                # (nu, Pm)
    Urow = ca.repmat(U.T, 12, 1)
    BU = ca.mtimes(B_ * Urow, Ublk)                                      # (12, Pm)
    EU = ca.mtimes(E_ * Urow[0:6, :], Ublk)                              # (6, Pm)
    states = free_ + ca.mtimes(BU, Rk_) + ca.vertcat(ca.mtimes(EU, Lk_), ca.DM.zeros(6, N))
    st = ca.Function("mpc_states", [A, U], [ca.densify(states)], ["aux", "U"], ["states"])
    return qp, st


#: compiled functions by sizes (one build per size and process; cached on disk)
_COMPILED: dict = {}


def compile_assembly(sizes: tuple[int, int, int, int, int]) -> tuple[ca.Function,
                                                                    ca.Function] | None:
    """The compiled ``(mpc_qp, mpc_states)`` for ``sizes``
    (:attr:`MPCAssemblyConstants.sizes`), or None where nothing can be compiled (no C
    compiler, or ``GRANULAR_MPC_JIT=0``): CasADi's interpreter would be slower than the
    NumPy assembly, which then runs instead."""
    if compiler() is None or os.environ.get("GRANULAR_MPC_JIT", "1") == "0":
        return None
    if sizes not in _COMPILED:
        fns = assembly_functions(sizes)
        lib = compile_functions("mpc_qp", fns)
        _COMPILED[sizes] = (lib["mpc_qp"], lib["mpc_states"])
    return _COMPILED[sizes]


class MPCAssemblyCaller:
    """Calls the compiled assembly through CasADi's buffer interface: inputs are this
    object's arrays (fill ``x0``, ``xref``, ``points``, ``capacity``, ``sel`` before
    :attr:`qp`, ``U`` before :attr:`states`), outputs land in the given QP arrays
    ``(H, g, C, u, lb, ub)`` in place and in :attr:`state_out` (N, 12)."""

    def __init__(self, functions: tuple[ca.Function, ca.Function],
                 constants: MPCAssemblyConstants, outputs: tuple) -> None:
        N, nps, Pm = constants.horizon, constants.n_points, constants.max_pairs
        self.model = constants.packed()
        self.x0 = np.zeros(12)
        self.xref = np.zeros((N, 12))
        self.points = np.zeros((N, 2, nps, 3))
        self.capacity = np.zeros((N, 2))
        self.sel = np.zeros((Pm, 2 * N))
        self.U = np.zeros(Pm * nps * 3)
        self.aux = np.zeros(functions[0].nnz_out(6))
        self.state_out = np.zeros((N, 12))
        for a in outputs:       # written in place: views of the caller's arrays
            if not a.flags.c_contiguous:
                raise ValueError("MPC assembly outputs must be C-contiguous arrays")
        self._buffers = []
        calls = []
        for fn, ins, outs in ((functions[0], (self.model, self.x0, self.xref, self.points,
                                              self.capacity, self.sel),
                               tuple(outputs) + (self.aux,)),
                              (functions[1], (self.aux, self.U), (self.state_out,))):
            buf, call = fn.buffer()
            for i, a in enumerate(ins):
                buf.set_arg(i, memoryview(a.reshape(-1)))
            for i, a in enumerate(outs):
                buf.set_res(i, memoryview(a.reshape(-1)))
            self._buffers.append(buf)
            calls.append(call)
        self.qp, self.states = calls


__all__ = ["CondensationTables", "MODEL", "MPCAssemblyCaller", "MPCAssemblyConstants",
           "assembly_functions", "compile_assembly", "condensation_tables"]
