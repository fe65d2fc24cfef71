"""Our QP types in front of ProxSuite: correctness against independent reference solvers,
the warm-started update path, failure statuses as data.

References: DAQP (a dual active-set solver: exact to round-off on these small dense QPs)
and Clarabel (an interior-point solver), both through qpsolvers — neither shares code with
ProxSuite. qpsolvers imports every backend it finds, ProxSuite included, when it is first
imported; ProxSuite's build is fixed by its first import in the process (see
``load_proxsuite``), so qpsolvers is imported only after the package has loaded the build
GRANULAR_MPC_PROXSUITE selects, never at collection.
"""

import functools
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse

from granular_mpc.control.solvers.proxqp import ProxQPSolver, QPProblem, QPStatus, load_proxsuite
from granular_mpc.exceptions import SolverError

#: ‖x − x_ref‖∞ of our solver at eps_abs = 1e-9: measured worst 1.1e-7 over seeds 1–30
#: (one problem each; the assertions use seed 0); bound 1e-6, 9× above
X_TOL = 1e-6
#: relative objective gap, same measurement: 7.0e-8; bound 1e-6
OBJ_TOL = 1e-6
#: the two references agree: measured 5.1e-11 over seeds 1–30 (Clarabel at 1e-12
#: tolerances); bound 1e-8 — a wrong reference would be off by O(1)
REF_TOL = 1e-8
CLARABEL_TIGHT = dict(tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12, tol_ktratio=1e-10)


@functools.cache
def _qpsolvers():
    load_proxsuite()          # the chosen ProxSuite build first (see the module docstring)
    import qpsolvers

    return qpsolvers


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


def reference(p: QPProblem, solver: str = "daqp") -> np.ndarray:
    """Solution of ``p`` by an independent solver (``l`` is −∞ in these problems)."""
    H, C, A, kw = p.H, p.C, p.A, {}
    if solver == "clarabel":                       # a sparse solver: give it CSC matrices
        H, C, A = (scipy.sparse.csc_matrix(m) for m in (H, C, A))
        kw = CLARABEL_TIGHT
    x = _qpsolvers().solve_qp(H, p.g, C, p.u, A, p.b, p.lb, p.ub, solver=solver, **kw)
    assert x is not None, f"{solver} found no solution"
    return x


def test_matches_reference_solver_over_random_problems():
    rng = np.random.default_rng(0)
    solver = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000)
    for _ in range(20):
        p = random_qp(rng)
        assert np.all(p.l < -1e19)               # the references see only C x ≤ u
        sol = solver.solve(p)
        assert sol.status is QPStatus.SOLVED
        ref = reference(p, "daqp")
        np.testing.assert_allclose(reference(p, "clarabel"), ref, atol=REF_TOL)
        np.testing.assert_allclose(sol.x, ref, atol=X_TOL)
        assert abs(p.objective(sol.x) - p.objective(ref)) <= OBJ_TOL * max(1.0, abs(p.objective(ref)))
        # ProxSuite stops at a primal residual ≤ eps_abs (eps_rel = 0); ×2 for round-off in
        # recomputing it here. Measured worst 9.6e-10.
        assert p.violation(sol.x) < 2e-9


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_warm_started_update_path_tracks_changing_problems(seed):
    """The documented proxsuite 0.8 pitfall: warm start + update + solve must not crash and
    must give the reference answer; the warm start is really used (fewer iterations)."""
    rng = np.random.default_rng(seed)
    p = random_qp(rng)
    solver = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000)
    first = solver.solve(p)
    assert first.status.ok
    warm_its, cold_its = 0, 0
    for k in range(10):
        p.g = p.g + 0.05 * rng.normal(size=12)
        sol = solver.solve(p)
        cold = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000).solve(p)
        assert sol.status.ok and cold.status.ok and not sol.retried
        np.testing.assert_allclose(sol.x, reference(p), atol=X_TOL)
        warm_its += sol.iterations
        cold_its += cold.iterations
    # warm-started iterations / cold ones over the 10 updates: measured mean 0.42, worst
    # 0.84 (seed 0) over seeds 0–59. Bound: fewer in total, on each of three seeds.
    assert warm_its < cold_its, (warm_its, cold_its)


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


def _buffered(n: int, n_in: int):
    """A QP whose arrays are views of one buffer (as the MPC's): H, g, C, l, u."""
    buf = np.zeros(n * n + n + n_in * n + 2 * n_in)
    ends = np.cumsum([0, n * n, n, n_in * n, n_in, n_in])
    H, g, C, l, u = (buf[a:b] for a, b in zip(ends[:-1], ends[1:]))
    return QPProblem(H.reshape(n, n), g, None, None, C.reshape(n_in, n), l, u, buffer=buf)


def test_the_one_buffer_check_accepts_a_free_side_and_rejects_nan():
    """With ``QPProblem.buffer`` the finiteness check is one sum; free sides at ±inf make
    that sum non-finite, and the per-array check must then still accept the problem
    (without a warning); NaN in the data or in a bound is still a NON_FINITE status."""
    p = _buffered(2, 2)
    p.H[:] = np.eye(2)
    p.g[:] = (-1.0, -2.0)
    p.C[:] = np.eye(2)
    p.l[:] = -np.inf
    p.u[:] = (0.5, np.inf)                  # a row free on both sides: −inf + inf in the sum
    sol = ProxQPSolver(2, 0, 2, eps_abs=1e-9).solve(p)
    assert sol.status.ok
    np.testing.assert_allclose(sol.x, [0.5, 2.0], atol=1e-6)
    p.u[0] = np.nan
    assert ProxQPSolver(2, 0, 2).solve(p).status is QPStatus.NON_FINITE
    p.u[0] = 0.5
    p.g[1] = np.inf
    assert ProxQPSolver(2, 0, 2).solve(p).status is QPStatus.NON_FINITE


def test_without_multipliers_the_solutions_are_bit_identical():
    """``multipliers=False`` (the MPC's setting) only leaves y, z out: x, status and
    iterations are the same, bit for bit, along a warm-started sequence."""
    rng = np.random.default_rng(4)
    p = random_qp(rng)
    with_yz = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000)
    without = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000, multipliers=False)
    for _ in range(5):
        a, b = with_yz.solve(p), without.solve(p)
        assert a.status.ok and b.status is a.status and b.iterations == a.iterations
        assert a.x.tobytes() == b.x.tobytes()
        assert a.y.shape == (2,) and a.z.shape == (8 + 12,)
        assert b.y is None and b.z is None
        p.g = p.g + 0.05 * rng.normal(size=12)


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
    env = dict(os.environ, GRANULAR_MPC_PROXSUITE="generic", MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, "-c", _REPRO, str(tmp_path)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    build, rows, differing = proc.stdout.split()[-3:]
    assert build == "proxsuite_pywrap" and int(rows) > 500
    assert int(differing) == 0


def test_unknown_proxsuite_build_is_a_clear_error(monkeypatch):
    from granular_mpc.control.solvers import proxqp

    monkeypatch.setenv("GRANULAR_MPC_PROXSUITE", "avx9000")
    monkeypatch.delitem(sys.modules, "proxsuite", raising=False)
    with pytest.raises(SolverError, match="GRANULAR_MPC_PROXSUITE.*allowed: native, generic"):
        proxqp.load_proxsuite()


# --------------------------------------------------------------------------------------
# the opt-in native (vectorised, not bit-reproducible) build: one explicit multi-seed
# statistical test
# --------------------------------------------------------------------------------------

_NATIVE = r"""
import json, sys
import numpy as np
from granular_mpc.control.solvers.proxqp import proxsuite_build
from granular_mpc.runner import run_scenario
from granular_mpc.scenario import load_scenario

out, duration = sys.argv[1], float(sys.argv[2])
for seed in (int(s) for s in sys.argv[3].split(",")):
    rng = np.random.default_rng(seed)          # the perturbation of this seed
    clearance = rng.uniform(-0.008, -0.002)    # initial sole depth [m] (default -0.005)
    fy = rng.uniform(-5.0, 5.0)                # lateral push [N] for 0.1 s: |impulse| ≤ 0.5 N·s
    t_push = rng.uniform(2.5, 3.5)             # during the averaging window [s]
    over = [f"sim.duration={duration}", f"sim.seed={seed}", f"initial_clearance={clearance}",
            f"pushes=[{{at: time, time: {t_push}, force: [0.0, {fy}, 0.0], duration: 0.1}}]",
            "output.plots=false"]
    s = run_scenario(load_scenario("sand_walk", over), f"{out}/seed{seed}", progress=False).summary
    print(json.dumps({"seed": seed, "build": proxsuite_build(), "fell": s["fell"],
                      "mean_speed_mps": s["mean_speed_mps"], "command": s["commanded_speed_mps"]}))
"""

#: seeds of the asserted runs; the margin below was measured on seeds 4–6 (not asserted)
NATIVE_SEEDS = (1, 2, 3)
#: 5 s: the summary's speed window is [2.45 s, end] (start delay + ramp + settle), so 5 s
#: averages 6.4 gait periods of steady walking (tests/test_examples_frontdoor.py)
NATIVE_SECONDS = 5.0
#: stated budget for |mean speed − command| / command, the same as the front-door examples'
#: (tests/test_examples_frontdoor.py). Measured on the native build, seeds 4–6 (not the
#: asserted ones), controller of commit f81274c: 0.1759–0.1768 m/s for 0.2 m/s (−12 %),
#: ≥ 0.026 m/s inside the bound, spread 0.001 m/s; the generic build's unperturbed run:
#: 0.176 m/s. (Before f81274c: 0.168–0.170 m/s.)
NATIVE_SPEED_BUDGET = 0.25


@pytest.mark.slow
def test_native_build_walks_on_sand_over_perturbed_seeds(tmp_path):
    """The suite's closed loops run on the generic build (the package default); this runs
    the opt-in native build (AVX2 where the CPU has it), over three perturbed starts (initial
    sole depth, a lateral push): every run walks without falling (rate 3/3) at a mean
    speed within the budget of the command. ~35 s at load 2."""
    env = dict(os.environ, GRANULAR_MPC_PROXSUITE="native", MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, "-c", _NATIVE, str(tmp_path), str(NATIVE_SECONDS),
                           ",".join(map(str, NATIVE_SEEDS))], env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    runs = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert [r["seed"] for r in runs] == list(NATIVE_SEEDS)
    cpu_flags = Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").exists() else ""
    if " avx2" in cpu_flags:                       # the vectorised build is really the one run
        assert all(r["build"] != "proxsuite_pywrap" for r in runs), runs
    assert sum(not r["fell"] for r in runs) == len(runs), runs
    for r in runs:
        assert r["command"] == 0.2                    # sim/sand_walk.yaml
        assert abs(r["mean_speed_mps"] - r["command"]) <= NATIVE_SPEED_BUDGET * r["command"], runs


def test_further_settings_are_applied_and_unknown_names_rejected():
    p = random_qp(np.random.default_rng(0))
    # the settings override the constructor's own: one iteration cannot reach 1e-9
    capped = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000,
                          settings={"max_iter": 1}).solve(p)
    assert capped.status is QPStatus.MAX_ITER
    free = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000).solve(p)
    assert free.status is QPStatus.SOLVED and free.iterations > 1
    with pytest.raises(SolverError, match="default_rh0.*allowed:.*default_rho"):
        ProxQPSolver(12, 2, 8, settings={"default_rh0": 1e-7})


def test_proxsuite_timings_split_the_call_and_leave_the_numbers_alone():
    rng = np.random.default_rng(1)
    problems = [random_qp(rng) for _ in range(5)]
    timed = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000, timings=True)
    plain = ProxQPSolver(12, 2, 8, box=True, eps_abs=1e-9, max_iter=1000)
    for p in problems:      # warm-started along the sequence, as the MPC does
        a, b = timed.solve(p), plain.solve(p)
        np.testing.assert_array_equal(a.x, b.x)
        assert a.iterations == b.iterations
        # ProxSuite's own timers run inside our call's
        assert 0.0 <= a.setup_ms and 0.0 < a.kernel_ms
        assert a.setup_ms + a.kernel_ms <= a.solve_ms
        assert np.isnan(b.setup_ms) and np.isnan(b.kernel_ms)
