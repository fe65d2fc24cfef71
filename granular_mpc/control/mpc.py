"""Centroidal-plus-sinkage MPC: single rigid body, line-foot contact points, granular-aware
force constraints, one persistent warm-started ProxSuite QP.

State ``x = [Θ (roll, pitch, yaw), p_com, ω_W, v_com] ∈ R¹²`` (W frame). Dynamics (Di Carlo
et al. 2018), linearised about the reference yaw ψ:

    Θ̇ = R_z(ψ)ᵀ ω,  ṗ = v,  ω̇ = I_W⁻¹ Σ rᵢ × fᵢ,  v̇ = Σ fᵢ/m + g,   I_W = R_z I_B R_zᵀ

with rᵢ = pᵢ − p_com,ref the lever of contact point i. Each foot contributes two contact
points (the two patches across the sole width), so a stance foot can also give roll and
yaw moments. Because the drift matrix A satisfies A² = 0 the discretisation is exact:
``A_d = I + A dt``, ``B_d = B dt + A B dt²/2``, and the condensed matrices need no matrix
powers: ``A_d^m = I + m A dt``.

Sinkage: each stance foot's contact points sit at the predicted depth ``Z(F̄)`` of the
controller's ground model (``F̄`` the nominal load), which sets the levers; after each
solve the predicted sinkage of every stance foot, ``z_k = max_{j≤k} Z(f_z,j)`` (plastic),
is reported with the plan. An optional cost ``w_s Σ (Z(F̄) + Z'(F̄)(f_z − F̄))²`` trades peak
forces against sinkage. Force constraints come from :mod:`.contact_model`.

The QP: ``min ½ UᵀHU + gᵀU`` with one block of variables per *(step, foot in contact)*
pair — the forces of that foot's contact points. Its size is fixed per controller: the
largest number of such pairs any horizon of the gait can contain (N for a single-support
gait, a few more with double support); unused blocks are padding held at zero. The ground
polytope's cone rows (friction-like, no bound) hold for each contact point, its capacity
rows (with a bound) for the foot's total force.

The QP is built each tick by generated C (:mod:`.mpc_assembly`, the condensation in
closed form) or, with ``assembly="numpy"`` and wherever nothing can be compiled, by the
NumPy code below (the stacked condensed map): the same QP to round-off.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..config import MPCConfig
from ..exceptions import ConfigError
from ..rotations import rot_z, skew, skew_rows
from .contact_model import GroundModel
from .mpc_assembly import MPCAssemblyCaller, MPCAssemblyConstants, compile_assembly
from .mpc_rows import PolytopeRows, mpc_polytope_rows
from .solvers.daqp import DAQPSolver
from .solvers.proxqp import ProxQPSolver, QPProblem, QPStatus

BIG = 1e20

#: how the QP is built (``CentroidalMPC.assembly``)
ASSEMBLIES = ("compiled", "numpy")

@dataclass(frozen=True)
class QPNumerics:
    """How the MPC's QP is posed to ProxSuite (``MPCConfig.qp`` names one, :data:`QP_SETTINGS`).

    Attributes:
        backend: ProxSuite dense backend (``DENSE_BACKENDS`` of :mod:`.solvers.proxqp`), or
            ``daqp``: the QP solved by DAQP (:class:`.DAQPSolver`, dual active set, exact to
            round-off, hot-started from the previous active set) instead of ProxSuite; then
            ``mu_in_reset``, ``eps_abs`` and ``eps_primal_inf`` do not apply.
        scaled: QP variables in units of the robot's weight m g instead of newtons (the
            forces' Hessian weight becomes ``weight_force``·(m g)² ≈ 0.1 instead of 1e-5);
            the constraint rows stay in newtons, the box bounds are in m g.
        mu_in_reset: the inequality penalty each warm-started solve restarts from
            (:class:`ProxQPSolver`'s ``mu_in_reset``); None keeps the previous solve's.
        eps_abs: ProxSuite's absolute tolerance (in the scaled units when ``scaled``).
        eps_primal_inf: ProxSuite's primal infeasibility tolerance; the QP is feasible by
            construction (zero forces satisfy every row), so an infeasibility verdict can
            only be false. None: ProxSuite's default.
        drop_implied_rows: leave out the polytope rows the other rows and the box imply
            (:func:`.mpc_polytope_rows`; on dry sand the two lateral capacity rows, n_in
            144 → 120): the same feasible set, hence the same optimum, less work per solve.
    """

    backend: str
    scaled: bool
    mu_in_reset: float | None
    eps_abs: float
    eps_primal_inf: float | None
    drop_implied_rows: bool = False


#: The MPC QP's numerics by name (``controller.mpc.qp``). ``scaled`` (the default since
#: session 20): forces in units of m g, ProxSuite's primal-dual LDLT backend, μ_in restarted
#: at 0.1 each solve, eps_abs 1e-5 — plans within ≈ 0.001 N (median), 0.009 N (worst) of
#: the QP's optimum. ``newton`` (the default before session 20, which the figures marked as
#: such in docs/results.md used): forces in newtons, ProxSuite's ``automatic`` backend (the
#: primal LDLT for n_in = 2 n), μ_in kept from solve to solve; H's smallest eigenvalue is
#: then the force weight, 1e-5, so eps_abs = 1e-4 fixes the forces only to ≈ 10 N
#: (measured: 4.6 N median, 16 N worst from the optimum), and μ_in shrinks 0.1 → 1e-8 over
#: ≈ 40 ticks (the 1000-iteration solves of its p99). ``daqp`` (opt-in): the ``scaled`` QP
#: solved exactly by DAQP's dual active set instead of ProxSuite — solve 0.235 ms median
#: against ProxSuite's 0.47–0.53 ms on 60 recorded sand-walk ticks, forces within 0.0082 N
#: of the ``scaled`` plan's (docs/speed.md, "WBC call and MPC read-out, round 2").
#: ``scaled_rows`` (session 21, opt-in): ``scaled`` without the polytope rows the other rows
#: imply (``QPNumerics.drop_implied_rows``) — the same optimum, ≈ 11 % less ProxSuite time
#: (docs/speed.md, "Session 21: MPC tick").
QP_SETTINGS: dict[str, QPNumerics] = {
    "newton": QPNumerics("automatic", False, None, 1e-4, None),
    "scaled": QPNumerics("primal_dual_ldlt", True, 0.1, 1e-5, 1e-6),
    "daqp": QPNumerics("daqp", True, None, 1e-5, None),
    "scaled_rows": QPNumerics("primal_dual_ldlt", True, 0.1, 1e-5, 1e-6, True),
}


def predicted_sinkage(ground: GroundModel, forces: np.ndarray,
                      contacts: np.ndarray) -> np.ndarray:
    """Plastic sinkage of each foot at each step [m], ``(N, 2)``: ``max_{j≤k} Z(F_z,j)``
    over the current stance (reset in swing), for planned forces ``forces``
    ``(N, 2, n_points, 3)`` [N] and stance flags ``contacts`` ``(N, 2)``; zero on rigid
    ground. Z is non-decreasing, so the deepest point is ``Z(max_{j≤k} F_z,j)``: one Z
    evaluation per rise of the running peak (measured: a vectorised Z of all the rises,
    with the second pass it needs, saves ≈ 2 µs per MPC tick at best — not worth it)."""
    N = forces.shape[0]
    out = np.zeros((N, 2))
    if not ground.granular:
        return out
    fz = forces[..., 2].sum(axis=2).tolist()        # (N, 2) foot normal forces [N]
    cont = np.asarray(contacts, dtype=bool).tolist()
    sinkage = ground.sinkage
    for f in (0, 1):
        peak, depth = None, 0.0
        for k in range(N):
            if not cont[k][f]:
                peak, depth = None, 0.0
                continue
            if peak is None or fz[k][f] > peak:
                peak = fz[k][f]
                depth = max(depth, sinkage(peak))
            out[k, f] = depth
    return out


@dataclass
class MPCPlan:
    """Result of one MPC tick (world frame, SI)."""

    t: float
    forces: np.ndarray          # (N, 2 feet, n_points, 3) planned contact forces [N]
    states: np.ndarray          # (N, 12) predicted states after each step
    contacts: np.ndarray        # (N, 2) planned contact flags
    sinkage: np.ndarray         # (N, 2) predicted sinkage of each foot [m]
    status: QPStatus
    solve_ms: float
    build_ms: float
    fallback: str = ""          # "" or how the plan was obtained after a failure

    def force_at(self, t: float, dt: float) -> np.ndarray:
        """Planned forces (2, n_points, 3) at time ``t`` (zero-order hold per MPC step)."""
        k = int(np.clip((t - self.t) // dt, 0, self.forces.shape[0] - 1))
        return self.forces[k]


@dataclass
class MPCWork:
    """What one MPC tick needs that does not change between ticks: config-only terms
    (cost diagonal, inverse inertia, the ground polytope's rows) and preallocated QP
    buffers of the controller's fixed size (horizon N, ``max_pairs`` variable blocks).

    The buffers are refilled in place every tick (ProxSuite copies them into its model).
    """

    q_rep: np.ndarray           # (N·12,) state-error weights, one block per step
    inertia_inv_B: np.ndarray   # 3×3 inverse centroidal inertia, trunk frame [1/(kg m²)]
    steps: np.ndarray           # (N, 1) k = 1 … N as floats
    cone: np.ndarray            # polytope rows with h = 0 (per contact point), foot frame
    capacity_rows: np.ndarray   # polytope rows with h > 0 (per foot), foot frame
    h_capacity: np.ndarray      # their bounds [N]
    H: np.ndarray               # (nu, nu)
    g: np.ndarray               # (nu,)
    C: np.ndarray               # (n_in, nu)
    C4: np.ndarray              # view of C as (max_pairs, rows_per_pair, max_pairs, nu_pair)
    l: np.ndarray               # (n_in,) −BIG everywhere (constant)
    u: np.ndarray               # (n_in,)
    lb: np.ndarray              # (nu,)
    ub: np.ndarray              # (nu,)
    block_index: np.ndarray | None = None       # arange(max_pairs)
    assembly: MPCAssemblyCaller | None = None   # the compiled assembly (None: NumPy)
    #: the QP over the arrays above, handed to the solver each tick; with DAQP the arrays
    #: are views of the solver's own stacked problem (:meth:`.DAQPSolver.new_problem`),
    #: which it then reads without a copy
    problem: QPProblem | None = None


@dataclass
class MPCData:
    """Changing part of the MPC: the persistent solver, the last plan, the work arrays."""

    solver: ProxQPSolver | DAQPSolver
    last: MPCPlan | None = None
    failures: int = 0
    solves: int = 0
    records: list = field(default_factory=list)
    work: MPCWork | None = None


@dataclass(frozen=True)
class CentroidalMPC:
    """MPC model (immutable). Build a :class:`MPCData` with :meth:`new_data`."""

    config: MPCConfig
    mass: float
    inertia_B: np.ndarray       # 3×3 centroidal rotational inertia in the trunk frame [kg m²]
    gravity: float
    ground: GroundModel
    n_points: int = 2
    max_pairs: int = 10         # most (step, foot) contacts in one horizon
    #: how the QP is built each tick: ``compiled`` (the assembly generated to C,
    #: :mod:`.mpc_assembly`; NumPy where no C compiler exists) or ``numpy``
    #: (the stacked condensed map, the code before the compiled assembly). The same QP to
    #: round-off (≤ 1e-15 of each array's largest entry, tests/test_mpc_assembly.py).
    assembly: str = "compiled"

    # ---------------------------------------------------------------- sizes
    @property
    def N(self) -> int:
        return self.config.horizon

    @property
    def nu_pair(self) -> int:
        return self.n_points * 3

    @property
    def nu(self) -> int:
        return self.max_pairs * self.nu_pair

    @cached_property
    def polytope_rows(self) -> PolytopeRows:
        """The ground polytope's rows the QP carries (all of them, or without the implied
        ones when ``qp.drop_implied_rows``), foot heading frame."""
        poly = self.ground.polytope
        if self.qp.drop_implied_rows:
            return mpc_polytope_rows(poly, self.n_points)
        return PolytopeRows(poly.G[poly.cone_rows], poly.G[poly.capacity_rows],
                            poly.h[poly.capacity_rows], ())

    @property
    def rows_per_pair(self) -> int:
        rows = self.polytope_rows
        return self.n_points * rows.cone.shape[0] + rows.capacity.shape[0]

    @property
    def n_in(self) -> int:
        return self.max_pairs * self.rows_per_pair

    @property
    def qp(self) -> QPNumerics:
        """The QP's numerics, from the config (``controller.mpc.qp``)."""
        return QP_SETTINGS[self.config.qp]

    @property
    def force_unit(self) -> float:
        """Force [N] of one unit of the QP's variables: m g when ``qp.scaled``, else 1."""
        return self.mass * self.gravity if self.qp.scaled else 1.0

    def with_qp(self, name: str) -> "CentroidalMPC":
        """This MPC with the QP numerics ``name`` (a key of :data:`QP_SETTINGS`) in its
        config; the rest of the model is unchanged."""
        if name not in QP_SETTINGS:
            raise ConfigError(f"unknown MPC QP settings {name!r}", key="controller.mpc.qp",
                              value=name, allowed=", ".join(QP_SETTINGS))
        return replace(self, config=self.config.model_copy(update={"qp": name}))

    def new_data(self) -> MPCData:
        qp = self.qp
        if qp.backend == "daqp":
            solver = DAQPSolver(self.nu, 0, self.n_in, box=True, max_iter=1000)
            return MPCData(solver, work=self._new_work(solver))
        return MPCData(ProxQPSolver(self.nu, 0, self.n_in, box=True, eps_abs=qp.eps_abs,
                                    max_iter=100, backend=qp.backend,
                                    mu_in_reset=qp.mu_in_reset,
                                    eps_primal_inf=qp.eps_primal_inf, multipliers=False),
                       work=self._new_work())

    def _new_work(self, solver: ProxQPSolver | DAQPSolver | None = None) -> MPCWork:
        """The work arrays; for a :class:`.DAQPSolver` the QP buffers are views of its
        stacked problem (filled here with the same initial values as the own arrays)."""
        rows = self.polytope_rows
        nu, n_in = self.nu, self.n_in
        if isinstance(solver, DAQPSolver):
            qp = solver.new_problem()
            for arr, value in ((qp.H, 0.0), (qp.g, 0.0), (qp.C, 0.0), (qp.l, -BIG),
                               (qp.u, 0.0), (qp.lb, 0.0), (qp.ub, 0.0)):
                arr.fill(value)
        else:
            # one allocation, seven views (H, g, C, l, u, lb, ub): the solver's finiteness
            # check is then one reduction (QPProblem.buffer)
            buffer = np.zeros(nu * nu + nu + n_in * nu + 2 * n_in + 2 * nu)
            ends = np.cumsum([0, nu * nu, nu, n_in * nu, n_in, n_in, nu, nu])
            H, g, C, l, u, lb, ub = (buffer[a:b] for a, b in zip(ends[:-1], ends[1:]))
            l.fill(-BIG)
            qp = QPProblem(H.reshape(nu, nu), g, None, None, C.reshape(n_in, nu), l, u, lb, ub,
                           buffer=buffer)
        C = qp.C
        work = MPCWork(
            q_rep=np.tile(self._q_diag(), self.N),
            inertia_inv_B=np.linalg.inv(self.inertia_B),
            steps=np.arange(1, self.N + 1, dtype=float)[:, None],
            cone=rows.cone, capacity_rows=rows.capacity, h_capacity=rows.h_capacity,
            H=qp.H, g=qp.g, C=C,
            C4=C.reshape(self.max_pairs, self.rows_per_pair, self.max_pairs, self.nu_pair),
            l=qp.l, u=qp.u, lb=qp.lb, ub=qp.ub,
            block_index=np.arange(self.max_pairs), problem=qp)
        if self.assembly not in ASSEMBLIES:
            raise ConfigError(f"unknown MPC assembly {self.assembly!r}", key="assembly",
                              value=self.assembly, allowed=", ".join(ASSEMBLIES))
        if self.assembly == "compiled":
            constants = self.assembly_constants()
            fns = compile_assembly(constants.sizes)
            if fns is not None:
                work.assembly = MPCAssemblyCaller(fns, constants, (work.H, work.g, work.C,
                                                                   work.u, work.lb, work.ub))
        return work

    def assembly_constants(self) -> MPCAssemblyConstants:
        """The numbers the compiled assembly takes (its sizes, and the model's numbers it is
        handed each call: mass, inertia, weights, polytope, force unit)."""
        poly, rows = self.ground.polytope, self.polytope_rows
        nps = self.n_points
        cone, capr = rows.cone, rows.capacity
        nc = cone.shape[0]
        rows_point = np.zeros((self.rows_per_pair, nps, 3))
        for i in range(nps):      # cone rows on each point, capacity rows on their sum
            rows_point[i * nc:(i + 1) * nc, i] = cone
            rows_point[nps * nc:, i] = capr
        c = self.config
        return MPCAssemblyConstants(
            horizon=self.N, n_points=nps, max_pairs=self.max_pairs, dt=float(c.dt),
            mass=float(self.mass), gravity=float(self.gravity),
            inertia_inv_B=tuple(np.linalg.inv(self.inertia_B).ravel().tolist()),
            q=tuple(self._q_diag().tolist()), weight_force=float(c.weight_force),
            force_unit=float(self.force_unit), rows_point=tuple(rows_point.ravel().tolist()),
            h_capacity=tuple(rows.h_capacity.tolist()), f_max=float(poly.f_max))

    # ---------------------------------------------------------------- weights
    def _q_diag(self) -> np.ndarray:
        c = self.config
        return np.concatenate([c.weights_orientation, c.weights_position,
                               c.weights_angular_velocity, c.weights_velocity]).astype(float)

    # ---------------------------------------------------------------- the tick
    def solve(self, data: MPCData, *, t: float, x0: np.ndarray, x_ref: np.ndarray,
              contacts: np.ndarray, points: np.ndarray, nominal_load: np.ndarray,
              capacity: np.ndarray | None = None) -> MPCPlan:
        """One MPC tick.

        Args:
            t: time of the tick [s].
            x0: current state (12) [rad, m, rad/s, m/s].
            x_ref: (N, 12) reference after each step.
            contacts: (N, 2) bool, planned stance of (left, right) during each step.
            points: (N, 2, n_points, 3) contact points of each foot at each step in W [m]
                (used only where the foot is in stance).
            nominal_load: (N, 2) expected vertical load of each foot [N] (for the sinkage
                levers and the optional sinkage cost).
            capacity: (N, 2) largest normal force of each foot at each step [N] — on sand
                the capacity at the depth the foot can have reached by then; the polytope
                is scaled to it. None: the polytope's own bound.
        """
        t0 = time.perf_counter()
        w = data.work
        if w is None:
            w = data.work = self._new_work(data.solver)
        # one variable block per (step, foot in contact), in (step, foot) order
        ks, fs = np.nonzero(contacts)
        if len(ks) > self.max_pairs:   # more contacts than planned for: keep the loaded ones
            keep = np.sort(np.argsort(-nominal_load[ks, fs], kind="stable")[: self.max_pairs])
            ks, fs = ks[keep], fs[keep]
        P = len(ks)
        na = P * self.nu_pair          # active variables
        if w.assembly is not None:
            states_of = self._assemble_compiled(w, x0, x_ref, points, capacity, ks, fs)
        else:
            states_of = self._assemble_numpy(w, x0, x_ref, points, capacity, ks, fs)
        if self.config.weight_sinkage > 0.0 and self.ground.granular and P:
            self._add_sinkage_cost(w, nominal_load[ks, fs])
        if w.assembly is None:      # (the compiled H is symmetric to the last bit)
            w.H += w.H.T
            w.H *= 0.5
        build_ms = (time.perf_counter() - t0) * 1e3
        sol = data.solver.solve(w.problem)
        data.solves += 1
        fallback = ""
        fu = self.force_unit
        if sol.status.ok:
            U = sol.x * fu if fu != 1.0 else sol.x
        else:
            data.failures += 1
            U, fallback = self._fallback(data, t, list(zip(ks.tolist(), fs.tolist())),
                                         nominal_load)
        N, nps = self.N, self.n_points
        forces = np.zeros((N, 2, nps, 3))
        forces[ks, fs] = U[:na].reshape(P, nps, 3)
        states = states_of(U)
        sink = predicted_sinkage(self.ground, forces, contacts)
        plan = MPCPlan(t, forces, states, np.array(contacts, copy=True), sink, sol.status,
                       sol.solve_ms, build_ms, fallback)
        data.last = plan
        return plan

    # ---------------------------------------------------------------- assembly
    def _assemble_numpy(self, w: MPCWork, x0, x_ref, points, capacity, ks, fs):
        """Fill the QP buffers of ``w`` in NumPy, the stacked condensed map Γ (the reference,
        and the path without a C compiler: the code before the compiled assembly, so a
        closed loop with it is bit for bit what it was; ``solve`` symmetrises H after the
        sinkage cost); returns ``U ↦ predicted states (N, 12)``."""
        c = self.config
        N, nx, nps, npair = self.N, 12, self.n_points, self.nu_pair
        dt = c.dt
        yaw = float(x_ref[0, 2])
        Rz = rot_z(yaw)
        RzT = Rz.T
        I_W_inv = Rz @ w.inertia_inv_B @ RzT
        P = len(ks)
        na = P * npair                 # active variables
        # discrete input matrix of each pair, B_d = B dt + A B dt²/2 (A: Θ̇ ← R_zᵀω, ṗ ← v):
        # rows ω̇ = I_W⁻¹ [r]×, v̇ = I/m; rows Θ, p get R_zᵀ and I times those (dt²/2)
        r = points[ks, fs] - x_ref[ks, None, 3:6]                   # (P, nps, 3) levers
        IS = np.einsum("ab,pibc->piac", I_W_inv, skew_rows(r))      # I_W⁻¹ [r]×
        h2 = 0.5 * dt * dt
        Bp = np.zeros((P, nx, nps, 3))
        Bp[:, 0:3] = np.einsum("ab,pibc->paic", RzT, IS) * h2
        Bp[:, 3:6] = (np.eye(3) / self.mass * h2)[None, :, None, :]
        Bp[:, 6:9] = IS.transpose(0, 2, 1, 3) * dt
        Bp[:, 9:12] = (np.eye(3) / self.mass * dt)[None, :, None, :]
        Bp = Bp.reshape(P, nx, npair)
        # (A dt) B_d: only rows Θ (R_zᵀ dt · rows ω) and p (dt · rows v)
        Ep = np.zeros((P, nx, npair))
        Ep[:, 0:3] = np.einsum("ab,pbl->pal", RzT * dt, Bp[:, 6:9])
        Ep[:, 3:6] = Bp[:, 9:12] * dt
        # free response: A_d^k = I + k A dt (A² = 0), gravity drift c_d
        Adt_x0 = np.zeros(nx)
        Adt_x0[0:3] = (RzT * dt) @ x0[6:9]
        Adt_x0[3:6] = dt * x0[9:12]
        cd = np.zeros(nx)
        cd[11] = -self.gravity * dt
        cd[5] = -self.gravity * h2
        Acd = np.zeros(nx)
        Acd[5] = dt * cd[11]
        ksteps = w.steps
        free = (x0 + ksteps * Adt_x0 + ksteps * cd + 0.5 * ksteps * (ksteps - 1) * Acd).ravel()
        # condensed input map of the active pairs: step k (1…N) after pair j's step k_j
        # sees B_j + (k − 1 − k_j) E_j (A_d^m B_j with A_d^m = I + m A dt); zero before
        m = ksteps - 1.0 - ks[None, :]                                # (N, P)
        G4 = (Bp.transpose(1, 0, 2)[None] + m[:, None, :, None] * Ep.transpose(1, 0, 2)[None])
        G4 = np.where((m >= 0.0)[:, None, :, None], G4, 0.0)
        Gam = G4.reshape(N * nx, na)
        err = free - self._wrap_reference(x_ref, x0).ravel()
        # the QP's variables: forces in units of fu (m g when scaled; see ``QPNumerics``)
        fu = self.force_unit
        scaled = fu != 1.0
        Gs = Gam * fu if scaled else Gam
        QG = Gs * w.q_rep[:, None]
        H, g = w.H, w.g
        H.fill(0.0)
        g.fill(0.0)
        H[:na, :na] = Gs.T @ QG
        g[:na] = QG.T @ err
        H[np.arange(self.nu), np.arange(self.nu)] += c.weight_force * fu * fu
        # constraints: the polytope's cone rows (h = 0) on each contact point (a point's
        # friction / shear is bounded by its own normal force: no free moments), its
        # capacity rows (h > 0) on the foot's total force
        poly = self.ground.polytope
        cone = w.cone @ RzT
        capr = w.capacity_rows @ RzT
        nc = cone.shape[0]
        block = np.zeros((self.rows_per_pair, npair))
        for i in range(nps):
            block[i * nc:(i + 1) * nc, 3 * i:3 * i + 3] = cone
            block[nps * nc:, 3 * i:3 * i + 3] = capr
        if scaled:          # rows stay in newtons: C u = (C fu) (F / fu)
            block *= fu
        diag = np.arange(self.max_pairs)
        w.C4[diag[:P], :, diag[:P], :] = block
        w.C4[diag[P:], :, diag[P:], :] = 0.0
        if capacity is not None:
            share = np.minimum(np.maximum(capacity[ks, fs] / poly.f_max, 0.0), 1.0)
        else:
            share = np.ones(P)
        u2 = w.u.reshape(self.max_pairs, self.rows_per_pair)
        u2.fill(0.0)
        u2[:P, nps * nc:] = w.h_capacity[None, :] * share[:, None]
        lb3 = w.lb.reshape(self.max_pairs, nps, 3)
        ub3 = w.ub.reshape(self.max_pairs, nps, 3)
        lb3.fill(0.0)
        ub3.fill(0.0)
        lb3[:P, :, :2] = -BIG
        ub3[:P, :, :2] = BIG
        ub3[:P, :, 2] = (poly.f_max * share / nps)[:, None]
        if scaled:
            ub3[:P, :, 2] /= fu
        return lambda U: (free + Gam @ U[:na]).reshape(N, nx)

    def _assemble_compiled(self, w: MPCWork, x0, x_ref, points, capacity, ks, fs):
        """Fill the QP buffers of ``w`` with the compiled assembly (:mod:`.mpc_assembly`);
        returns ``U ↦ predicted states (N, 12)``."""
        a = w.assembly
        a.sel.fill(0.0)
        a.sel[w.block_index[:len(ks)], 2 * ks + fs] = 1.0
        a.x0[:] = x0
        a.xref[:] = x_ref
        a.points[:] = points
        if capacity is None:
            a.capacity.fill(self.ground.polytope.f_max)
        else:
            a.capacity[:] = capacity
        a.qp()

        def states(U: np.ndarray) -> np.ndarray:
            a.U[:] = U
            a.states()
            return a.state_out.copy()
        return states

    def _add_sinkage_cost(self, w: MPCWork, F0: np.ndarray) -> None:
        """Add the sinkage cost ``w_s Σ (Z(F̄) + Z'(F̄)(F_z − F̄))²`` of the active blocks
        (nominal loads ``F0`` [N]) to ``w.H``, ``w.g`` (a symmetric term)."""
        c, fu = self.config, self.force_unit
        P, nps, npair = len(F0), self.n_points, self.nu_pair
        z0 = np.array([self.ground.sinkage(f) for f in F0])
        a = np.array([self.ground.sinkage_slope(f) for f in F0])
        if fu != 1.0:       # z0 + a (F − F0) = z0 + (a fu)(u − F0/fu)
            a, F0 = a * fu, F0 / fu
        # (z0 + a (F_z − F0))², F_z = Σ of the foot's points
        jz = (np.arange(P)[:, None] * npair + 3 * np.arange(nps)[None, :] + 2)
        w.H[jz[:, :, None], jz[:, None, :]] += (2.0 * c.weight_sinkage * a * a)[:, None, None]
        w.g[jz] += (2.0 * c.weight_sinkage * a * (z0 - a * F0))[:, None]

    # ---------------------------------------------------------------- helpers
    def _wrap_reference(self, x_ref: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """Reference yaw unwrapped next to the current yaw (no 2π jumps in the error)."""
        out = x_ref.copy()
        out[:, 2] = x0[2] + (out[:, 2] - x0[2] + math.pi) % (2.0 * math.pi) - math.pi
        return out

    def _fallback(self, data: MPCData, t: float, pairs: list,
                  nominal_load: np.ndarray) -> tuple[np.ndarray, str]:
        """Shifted previous plan where it covers a pair, else nominal (gravity-sharing)
        forces."""
        nps, npair = self.n_points, self.nu_pair
        U = np.zeros(self.nu)
        last = data.last
        shift = int(round((t - last.t) / self.config.dt)) if last is not None else 0
        shifted = 0
        for j, (k, f) in enumerate(pairs):
            block = np.zeros((nps, 3))
            src = k + shift
            if last is not None and last.status.ok and src < self.N and last.contacts[src, f]:
                block = last.forces[src, f]
                shifted += 1
            else:
                block[:, 2] = nominal_load[k, f] / nps
            U[j * npair:(j + 1) * npair] = block.ravel()
        if shifted == len(pairs) and pairs:
            return U, "shifted"
        return U, "shifted+nominal" if shifted else "nominal"


__all__ = ["ASSEMBLIES", "CentroidalMPC", "MPCData", "MPCPlan", "MPCWork", "QPNumerics",
           "QP_SETTINGS", "predicted_sinkage", "rot_z", "skew"]
