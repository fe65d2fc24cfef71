"""DAQP adapter: the contract of the ProxSuite one (sizes, statuses, no exceptions for a
numerical failure), checked against a tight independent reference on QPs of the
whole-body controller's structure."""

import numpy as np
import pytest
import scipy.sparse

from granular_mpc.control.solvers.daqp import DAQP_INF, DAQPSolver
from granular_mpc.control.solvers.proxqp import QPProblem, QPStatus, load_proxsuite
from granular_mpc.exceptions import SolverError

BIG = 1e20
#: the WBC's sizes: q̈ (12) + forces (2 feet × 2 points × 3), 6 floating-base equalities,
#: 6 torque rows + 4 points × 8 polytope rows
NV, NF, N_EQ, N_IN = 12, 12, 6, 38
#: ‖x_daqp − x_ref‖∞ against Clarabel at 1e-12 tolerances: measured worst 3.3e-8 over 360
#: problems (20 seeds × 3 stance pairs × 6); bound 1e-6. (ProxSuite at eps_abs 1e-10 agrees
#: with DAQP to 2.7e-9 but declares 3 of those 360 QPs primal infeasible at its default
#: infeasibility tolerance, so it is not the reference here.)
X_TOL = 1e-6


def wbc_like_qp(rng, stance=(True, False)) -> QPProblem:
    """A random feasible QP with the WBC's structure: a dense cost, 6 equalities, two-sided
    torque rows, one-sided polytope rows per contact point, swing forces boxed to 0."""
    n = NV + NF
    M = rng.normal(size=(n, n))
    H = M @ M.T + 0.1 * np.eye(n)
    g = rng.normal(size=n) * 10.0
    x = np.zeros(n)
    x[:NV] = rng.normal(size=NV)
    lb, ub = np.full(n, -BIG), np.full(n, BIG)
    f = x[NV:].reshape(2, 2, 3)
    for i, on in enumerate(stance):
        if on:
            f[i] = rng.uniform(-2.0, 2.0, (2, 3))
            f[i, :, 2] = rng.uniform(5.0, 50.0, 2)
            lb[NV:].reshape(2, 2, 3)[i, :, 2] = 0.0
            ub[NV:].reshape(2, 2, 3)[i, :, 2] = 60.0
        else:
            lb[NV:].reshape(2, 2, 3)[i] = 0.0
            ub[NV:].reshape(2, 2, 3)[i] = 0.0
    A = rng.normal(size=(N_EQ, n))
    b = A @ x
    C = np.zeros((N_IN, n))
    C[:6] = rng.normal(size=(6, n))
    G = np.array([[1, 0, -0.5], [-1, 0, -0.5], [0, 1, -0.5], [0, -1, -0.5],
                  [1, 1, -0.7], [1, -1, -0.7], [-1, 1, -0.7], [-1, -1, -0.7]], float)
    for pt in range(4):
        C[6 + 8 * pt:14 + 8 * pt, NV + 3 * pt:NV + 3 * pt + 3] = G
    cx = C @ x
    l = np.full(N_IN, -BIG)
    u = cx + rng.uniform(0.0, 1.0, N_IN)
    l[:6] = cx[:6] - rng.uniform(0.0, 1.0, 6)
    return QPProblem(H, g, A, b, C, l, u, lb, ub)


def tight_reference(p: QPProblem) -> np.ndarray:
    """``p`` solved by Clarabel (an interior-point solver, through qpsolvers) at 1e-12
    tolerances: the two-sided torque rows as two one-sided ones, ±1e20 as ±inf."""
    load_proxsuite()        # our ProxSuite build first: qpsolvers imports ProxSuite too
    import qpsolvers

    G = np.vstack([p.C, -p.C[:6]])
    h = np.concatenate([p.u, -p.l[:6]])
    lb = np.where(p.lb < -1e19, -np.inf, p.lb)
    ub = np.where(p.ub > 1e19, np.inf, p.ub)
    csc = scipy.sparse.csc_matrix
    x = qpsolvers.solve_qp(csc(p.H), p.g, csc(G), h, csc(p.A), p.b, lb, ub, solver="clarabel",
                           tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12,
                           tol_ktratio=1e-10)
    assert x is not None
    return x


@pytest.mark.parametrize("stance", [(True, True), (True, False), (False, False)])
def test_matches_a_tight_reference_on_wbc_shaped_qps(stance):
    rng = np.random.default_rng(sum(stance))
    solver = DAQPSolver(NV + NF, N_EQ, N_IN, box=True)
    for _ in range(6):
        p = wbc_like_qp(rng, stance)
        sol = solver.solve(p)
        assert sol.status is QPStatus.SOLVED
        ref = tight_reference(p)
        np.testing.assert_allclose(sol.x, ref, atol=X_TOL)
        assert p.violation(sol.x) <= 1e-6          # DAQP's primal tolerance (measured 9e-12)
        assert abs(sol.objective - p.objective(sol.x)) <= 1e-8 * max(1.0, abs(sol.objective))
        assert sol.y.shape == (N_EQ,) and sol.z.shape == (N_IN,)


def test_hot_start_tracks_changing_problems_with_fewer_iterations():
    """Hot start (the previous working set) gives the cold solution in fewer iterations."""
    rng = np.random.default_rng(4)
    p = wbc_like_qp(rng)
    hot, cold = DAQPSolver(NV + NF, N_EQ, N_IN, box=True), \
        DAQPSolver(NV + NF, N_EQ, N_IN, box=True, hot_start=False)
    hot.solve(p)
    cold.solve(p)
    its = {"hot": 0, "cold": 0}
    for _ in range(10):
        p.g = p.g + 0.1 * rng.normal(size=p.n)
        sh, sc = hot.solve(p), cold.solve(p)
        assert sh.status.ok and sc.status.ok and not sh.retried
        np.testing.assert_allclose(sh.x, sc.x, atol=1e-9)
        its["hot"] += sh.iterations
        its["cold"] += sc.iterations
    assert its["hot"] < its["cold"], its


def test_own_problem_is_solved_in_place_like_a_copied_one():
    """A caller filling :meth:`new_problem`'s arrays gets the answer of the copy path."""
    rng = np.random.default_rng(5)
    p = wbc_like_qp(rng)
    a, b = DAQPSolver(NV + NF, N_EQ, N_IN, box=True), DAQPSolver(NV + NF, N_EQ, N_IN, box=True)
    own = b.new_problem()
    assert b.new_problem() is own
    for key in ("H", "g", "A", "b", "C", "l", "u", "lb", "ub"):
        np.copyto(getattr(own, key), getattr(p, key))
    assert np.shares_memory(own.A, b.A_stack) and np.shares_memory(own.C, b.A_stack)
    np.testing.assert_array_equal(a.solve(p).x, b.solve(own).x)


def test_infinite_bounds_are_free_sides():
    p = QPProblem(np.eye(2), np.array([-1.0, -1.0]), C=np.array([[1.0, 0.0]]),
                  l=np.array([-np.inf]), u=np.array([0.5]),
                  lb=np.array([-np.inf, -np.inf]), ub=np.array([np.inf, 0.25]))
    sol = DAQPSolver(2, 0, 1, box=True).solve(p)
    assert sol.status is QPStatus.SOLVED
    np.testing.assert_allclose(sol.x, [0.5, 0.25], atol=1e-12)
    assert DAQP_INF > BIG
    # a missing lower side is free too
    p = QPProblem(np.eye(2), np.array([-1.0, -1.0]), C=np.array([[1.0, 1.0]]),
                  u=np.array([1.0]))
    sol = DAQPSolver(2, 0, 1).solve(p)
    assert sol.status is QPStatus.SOLVED
    np.testing.assert_allclose(sol.x, [0.5, 0.5], atol=1e-12)


def test_infeasible_problem_is_a_failure_status_not_an_exception():
    p = QPProblem(np.eye(2), np.zeros(2), C=np.array([[1.0, 0.0]]), l=np.array([1.0]),
                  u=np.array([-1.0]))
    sol = DAQPSolver(2, 0, 1).solve(p)
    assert sol.status is QPStatus.PRIMAL_INFEASIBLE
    # inconsistent equalities: DAQP rejects the initial working set (FAILED), no exception
    p = QPProblem(np.eye(2), np.zeros(2), np.array([[1.0, 0.0], [1.0, 0.0]]),
                  np.array([0.0, 1.0]))
    assert not DAQPSolver(2, 2, 0).solve(p).status.ok


def test_solver_recovers_after_a_failure():
    solver = DAQPSolver(2, 0, 1)
    bad = QPProblem(np.eye(2), np.zeros(2), C=np.array([[1.0, 0.0]]), l=np.array([1.0]),
                    u=np.array([-1.0]))
    good = QPProblem(np.eye(2), np.array([-1.0, 0.0]), C=np.array([[1.0, 0.0]]),
                     l=np.array([-BIG]), u=np.array([0.5]))
    assert solver.solve(good).status.ok
    assert not solver.solve(bad).status.ok
    sol = solver.solve(good)
    assert sol.status.ok
    np.testing.assert_allclose(sol.x, [0.5, 0.0], atol=1e-12)


@pytest.mark.parametrize("where", ["g", "H", "u"])
def test_non_finite_data_is_a_status(where):
    p = QPProblem(np.eye(2), np.zeros(2), C=np.array([[1.0, 0.0]]), l=np.array([-1.0]),
                  u=np.array([1.0]))
    getattr(p, where).flat[0] = np.nan
    sol = DAQPSolver(2, 0, 1).solve(p)
    assert sol.status is QPStatus.NON_FINITE
    assert np.array_equal(sol.x, np.zeros(2))


def test_non_positive_definite_cost_is_a_status():
    sol = DAQPSolver(2, 0, 0).solve(QPProblem(-np.eye(2), np.ones(2)))
    assert not sol.status.ok


def test_size_mismatch_raises_solver_error():
    with pytest.raises(SolverError, match="differs"):
        DAQPSolver(3, 0, 0).solve(QPProblem(np.eye(2), np.zeros(2)))
