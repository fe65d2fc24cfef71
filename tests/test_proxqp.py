"""Our QP types in front of ProxSuite: correctness against a reference solver, the
warm-started update path, failure statuses as data."""

import numpy as np
import pytest
import qpsolvers

from granular_mpc.control.solvers.proxqp import ProxQPSolver, QPProblem, QPStatus
from granular_mpc.exceptions import SolverError


def random_qp(rng, n=12, n_eq=2, n_in=8):
    M = rng.normal(size=(n, n))
    H = M @ M.T + 0.5 * np.eye(n)
    g = rng.normal(size=n)
    A = rng.normal(size=(n_eq, n))
    x_feas = rng.normal(size=n)
    b = A @ x_feas
    C = rng.normal(size=(n_in, n))
    u = C @ x_feas + rng.uniform(0.1, 1.0, n_in)
    l = np.full(n_in, -1e20)
    lb = x_feas - rng.uniform(0.5, 2.0, n)
    ub = x_feas + rng.uniform(0.5, 2.0, n)
    return QPProblem(H, g, A, b, C, l, u, lb, ub)


def reference(p: QPProblem) -> np.ndarray:
    return qpsolvers.solve_qp(p.H, p.g, p.C, p.u, p.A, p.b, p.lb, p.ub, solver="proxqp",
                              eps_abs=1e-10, eps_rel=0.0)


def test_matches_reference_solver_over_random_problems():
    rng = np.random.default_rng(0)
    solver = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000)
    for _ in range(20):
        p = random_qp(rng)
        sol = solver.solve(p)
        assert sol.status is QPStatus.SOLVED
        np.testing.assert_allclose(sol.x, reference(p), atol=1e-5)
        assert p.violation(sol.x) < 1e-6


def test_warm_started_update_path_tracks_changing_problems():
    """The documented proxsuite 0.8 pitfall: warm start + update + solve must not crash and
    must give the same answer as a cold solve."""
    rng = np.random.default_rng(1)
    p = random_qp(rng)
    solver = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000)
    first = solver.solve(p)
    assert first.status.ok
    assert solver._warm, "warm start is switched on after the first success"
    for k in range(10):
        p.g = p.g + 0.05 * rng.normal(size=12)
        sol = solver.solve(p)
        cold = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000).solve(p)
        assert sol.status.ok and cold.status.ok
        np.testing.assert_allclose(sol.x, cold.x, atol=1e-6)


def test_infeasible_problem_is_reported_not_raised():
    n = 2
    p = QPProblem(np.eye(n), np.zeros(n), np.array([[1.0, 0.0], [1.0, 0.0]]),
                  np.array([0.0, 1.0]))
    sol = ProxQPSolver(n, 2, 0).solve(p)
    assert not sol.status.ok


def test_non_finite_data_is_a_status():
    p = QPProblem(np.eye(2), np.array([np.nan, 0.0]))
    sol = ProxQPSolver(2, 0, 0).solve(p)
    assert sol.status is QPStatus.NON_FINITE


def test_size_mismatch_raises_solver_error():
    with pytest.raises(SolverError, match="differs"):
        ProxQPSolver(3, 0, 0).solve(QPProblem(np.eye(2), np.zeros(2)))
