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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..config import MPCConfig
from ..rotations import rot_z, skew
from .contact_model import GroundModel
from .solvers.proxqp import ProxQPSolver, QPProblem, QPStatus

BIG = 1e20


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
class MPCData:
    """Changing part of the MPC: the persistent solver and the last plan."""

    solver: ProxQPSolver
    last: MPCPlan | None = None
    failures: int = 0
    solves: int = 0
    records: list = field(default_factory=list)


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

    @property
    def rows_per_pair(self) -> int:
        poly = self.ground.polytope
        return self.n_points * len(poly.cone_rows) + len(poly.capacity_rows)

    @property
    def n_in(self) -> int:
        return self.max_pairs * self.rows_per_pair

    def new_data(self) -> MPCData:
        return MPCData(ProxQPSolver(self.nu, 0, self.n_in, box=True, eps_abs=1e-4, max_iter=100))

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
        import time

        t0 = time.perf_counter()
        c = self.config
        N, nx, nps, npair = self.N, 12, self.n_points, self.nu_pair
        dt = c.dt
        yaw = float(x_ref[0, 2])
        Rz = rot_z(yaw)
        I_W_inv = Rz @ np.linalg.inv(self.inertia_B) @ Rz.T
        A = np.zeros((nx, nx))
        A[0:3, 6:9] = Rz.T
        A[3:6, 9:12] = np.eye(3)
        Adt = A * dt
        # one variable block per (step, foot in contact)
        pairs = [(k, f) for k in range(N) for f in (0, 1) if contacts[k, f]]
        if len(pairs) > self.max_pairs:   # more contacts than planned for: keep the loaded ones
            pairs = sorted(pairs, key=lambda kf: -nominal_load[kf])[: self.max_pairs]
            pairs.sort()
        Bp = np.zeros((len(pairs), nx, npair))
        for j, (k, f) in enumerate(pairs):
            pc = x_ref[k, 3:6]
            for i in range(nps):
                r = points[k, f, i] - pc
                Bc = np.zeros((nx, 3))
                Bc[6:9] = I_W_inv @ skew(r)
                Bc[9:12] = np.eye(3) / self.mass
                Bp[j, :, 3 * i:3 * i + 3] = Bc * dt + A @ Bc * (0.5 * dt * dt)
        Ep = np.einsum("ij,pjl->pil", Adt, Bp)        # (A dt) B_d of each pair
        cvec = np.zeros(nx)
        cvec[11] = -self.gravity
        cd = cvec * dt + A @ cvec * (0.5 * dt * dt)
        Acd = Adt @ cd
        Gam = np.zeros((N * nx, self.nu))
        free = np.zeros(N * nx)
        for k in range(1, N + 1):
            free[(k - 1) * nx:k * nx] = x0 + k * (Adt @ x0) + k * cd + 0.5 * k * (k - 1) * Acd
        for j, (kj, _) in enumerate(pairs):
            cols = slice(j * npair, (j + 1) * npair)
            for k in range(kj + 1, N + 1):
                Gam[(k - 1) * nx:k * nx, cols] = Bp[j] + (k - 1 - kj) * Ep[j]
        err = free - self._wrap_reference(x_ref, x0).ravel()
        q = np.tile(self._q_diag(), N)
        QG = Gam * q[:, None]
        H = Gam.T @ QG
        g = QG.T @ err
        H[np.diag_indices_from(H)] += c.weight_force
        if c.weight_sinkage > 0.0 and self.ground.granular:
            for j, (k, f) in enumerate(pairs):
                z0 = self.ground.sinkage(nominal_load[k, f])
                a = self.ground.sinkage_slope(nominal_load[k, f])
                F0 = nominal_load[k, f]
                # (z0 + a (F_z − F0))², F_z = Σ of the foot's points
                jz = [j * npair + 3 * i + 2 for i in range(nps)]
                H[np.ix_(jz, jz)] += 2.0 * c.weight_sinkage * a * a
                g[jz] += 2.0 * c.weight_sinkage * a * (z0 - a * F0)
        H = 0.5 * (H + H.T)
        # constraints: the polytope's cone rows (h = 0) on each contact point (a point's
        # friction / shear is bounded by its own normal force: no free moments), its
        # capacity rows (h > 0) on the foot's total force
        poly = self.ground.polytope
        cone = poly.G[poly.cone_rows] @ Rz.T
        capr = poly.G[poly.capacity_rows] @ Rz.T
        nc = cone.shape[0]
        C = np.zeros((self.n_in, self.nu))
        u = np.zeros(self.n_in)
        lb = np.zeros(self.nu)
        ub = np.zeros(self.nu)
        rows_pp = self.rows_per_pair
        for j, (k, f) in enumerate(pairs):
            share = 1.0
            if capacity is not None:
                share = min(max(capacity[k, f] / poly.f_max, 0.0), 1.0)
            r0 = j * rows_pp
            for i in range(nps):
                col = j * npair + 3 * i
                C[r0 + i * nc: r0 + (i + 1) * nc, col:col + 3] = cone
                C[r0 + nps * nc: r0 + rows_pp, col:col + 3] = capr
                lb[col:col + 2] = -BIG
                ub[col:col + 2] = BIG
                ub[col + 2] = poly.f_max * share / nps
            u[r0 + nps * nc: r0 + rows_pp] = poly.h[poly.capacity_rows] * share
        l = np.full(self.n_in, -BIG)
        build_ms = (time.perf_counter() - t0) * 1e3
        sol = data.solver.solve(QPProblem(H, g, None, None, C, l, u, lb, ub))
        data.solves += 1
        fallback = ""
        if sol.status.ok:
            U = sol.x
        else:
            data.failures += 1
            U, fallback = self._fallback(data, t, pairs, nominal_load)
        forces = np.zeros((N, 2, nps, 3))
        for j, (k, f) in enumerate(pairs):
            forces[k, f] = U[j * npair:(j + 1) * npair].reshape(nps, 3)
        states = (free + Gam @ U).reshape(N, nx)
        sink = self._predicted_sinkage(forces, contacts)
        plan = MPCPlan(t, forces, states, contacts.copy(), sink, sol.status, sol.solve_ms,
                       build_ms, fallback)
        data.last = plan
        return plan

    # ---------------------------------------------------------------- helpers
    def _wrap_reference(self, x_ref: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """Reference yaw unwrapped next to the current yaw (no 2π jumps in the error)."""
        out = x_ref.copy()
        out[:, 2] = x0[2] + (out[:, 2] - x0[2] + math.pi) % (2.0 * math.pi) - math.pi
        return out

    def _predicted_sinkage(self, forces: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        N = forces.shape[0]
        out = np.zeros((N, 2))
        for f in (0, 1):
            deepest = 0.0
            for k in range(N):
                if not contacts[k, f]:
                    deepest = 0.0
                    continue
                deepest = max(deepest, self.ground.sinkage(float(forces[k, f, :, 2].sum())))
                out[k, f] = deepest
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


__all__ = ["CentroidalMPC", "MPCData", "MPCPlan", "rot_z", "skew"]
