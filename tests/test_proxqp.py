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


_REPRO = r"""
import glob, sys
import numpy as np, pandas as pd
from granular_mpc.control.solvers.proxqp import proxsuite_build
from granular_mpc.runner import run_scenario
from granular_mpc.scenario import load_scenario

def log(out):
    return pd.concat([pd.read_parquet(f) for f in sorted(glob.glob(out + "/log/part-*.parquet"))])

logs = []
for i in range(2):
    out = f"{sys.argv[1]}/run{i}"
    run_scenario(load_scenario("sand_walk", ["sim.duration=1.2"]), out, progress=False)
    logs.append(log(out))
a, b = logs
cols = [c for c in a.columns if a[c].dtype.kind == "f" and not c.endswith("_ms")]
print(proxsuite_build(), len(a), int((a[cols].values != b[cols].values).any(axis=1).sum()))
"""


@pytest.mark.slow
def test_generic_build_makes_closed_loop_runs_bit_reproducible(tmp_path):
    """With GRANULAR_MPC_PROXSUITE=generic two runs of one scenario in one process give the
    same log bit for bit (the AVX2 build parts at ~1e-10 after ~0.5 s: heap alignment)."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, GRANULAR_MPC_PROXSUITE="generic", MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, "-c", _REPRO, str(tmp_path)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    build, rows, differing = proc.stdout.split()[-3:]
    assert build == "proxsuite_pywrap" and int(rows) > 500
    assert int(differing) == 0


def test_unknown_proxsuite_build_is_a_clear_error(monkeypatch):
    import sys

    from granular_mpc.control.solvers import proxqp

    monkeypatch.setenv("GRANULAR_MPC_PROXSUITE", "avx9000")
    monkeypatch.delitem(sys.modules, "proxsuite", raising=False)
    with pytest.raises(SolverError, match="GRANULAR_MPC_PROXSUITE.*allowed: native, generic"):
        proxqp.load_proxsuite()
