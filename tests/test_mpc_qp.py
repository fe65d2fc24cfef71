"""The MPC's QP as ProxSuite sees it with ``controller.mpc.qp: scaled``: forces in units
of m g, warm starts that restart the inequality penalty, no false infeasibility (issue 12,
docs/speed.md "The MPC tick")."""

import dataclasses

import numpy as np
import pytest

from granular_mpc.config import MPCConfig
from granular_mpc.control.contact_model import ground_model
from granular_mpc.control.mpc import CentroidalMPC
from granular_mpc.control.solvers.proxqp import ProxQPSolver, QPProblem
from granular_mpc.exceptions import ConfigError

MASS = 10.64
INERTIA = np.array([[0.17, 0.0, 0.02], [0.0, 0.16, 0.0], [0.02, 0.0, 0.08]])
N = 10


def make(terrain, weight_sinkage=0.0, qp="scaled"):
    c = MPCConfig(horizon=N, dt=0.04, weight_sinkage=weight_sinkage, qp=qp)
    return CentroidalMPC(c, MASS, INERTIA, 9.81, ground_model(terrain, c), n_points=2,
                         max_pairs=14)


def walk_ticks(n: int, seed: int) -> list:
    """``n`` MPC inputs of a synthetic walk at 0.2 m/s: a 0.4 s gait cycle (60 % stance,
    double support) moving one MPC step per tick, noisy states, a growing force cap."""
    rng = np.random.default_rng(seed)
    out = []
    for j in range(n):
        t = j * 0.04
        x0 = np.concatenate([rng.normal(0, 0.02, 2), [0.0],
                             [0.2 * t, 0.01 * np.sin(7 * t), 0.40 + rng.normal(0, 0.005)],
                             rng.normal(0, 0.1, 3), [0.2, 0.05 * np.cos(7 * t), rng.normal(0, 0.02)]])
        x_ref = np.tile(x0, (N, 1))
        x_ref[:, 5] = 0.41
        x_ref[:, 2] = 0.0
        x_ref[:, 3] = x0[3] + 0.2 * 0.04 * np.arange(1, N + 1)
        contacts = np.zeros((N, 2), dtype=bool)
        points = np.zeros((N, 2, 2, 3))
        for k in range(N):
            phase = ((j + k) % 10) / 10
            contacts[k] = (phase < 0.6, phase >= 0.5 or phase < 0.1)
            xs = 0.2 * (j + k) * 0.04
            points[k, 0] = [[xs + 0.02, 0.08, -0.01], [xs + 0.02, 0.11, -0.01]]
            points[k, 1] = [[xs + 0.05, -0.11, -0.01], [xs + 0.05, -0.08, -0.01]]
        load = contacts * (MASS * 9.81) / np.maximum(contacts.sum(axis=1, keepdims=True), 1)
        cap = np.where(contacts, np.minimum(30.0 + 40.0 * np.arange(N)[:, None], 200.0), 0.0)
        out.append(dict(t=t, x0=x0, x_ref=x_ref, contacts=contacts, points=points,
                        nominal_load=load, capacity=cap))
    return out


def tight(mpc) -> tuple:
    """The MPC with a cold, tight solver (eps_abs 1e-9, primal-dual backend): the QP's
    optimum (on the 90 ticks of seeds 0–2 within 0.0016 N of an interior-point solve,
    Clarabel at 1e-12, for forces in newtons and in m g alike)."""
    data = mpc.new_data()
    data.solver = ProxQPSolver(mpc.nu, 0, mpc.n_in, box=True, eps_abs=1e-9, max_iter=10000,
                               backend="primal_dual_ldlt", eps_primal_inf=1e-9)
    return mpc, data


def test_scaled_and_newton_qps_have_the_same_optimum(sand):
    """Forces in units of m g change the QP's numbers, not its solution: both QPs solved
    tightly give the same plan (measured ≤ 2e-6 N apart; 1e-3 N leaves room for the
    eps_abs = 1e-9 stopping point of each, ×(m g) in the scaled one), with and without the
    sinkage cost (whose slope and nominal load are rescaled too)."""
    for kw, w_sink in zip(walk_ticks(4, seed=1), (0.0, 0.0, 1e3, 1e3)):
        plans = []
        for scaled in (True, False):
            mpc, data = tight(make(sand, w_sink, qp="scaled" if scaled else "newton"))
            plans.append(mpc.solve(data, **kw))
        assert all(p.status.ok for p in plans)
        np.testing.assert_allclose(plans[0].forces, plans[1].forces, rtol=0, atol=1e-3)
        np.testing.assert_allclose(plans[0].states, plans[1].states, rtol=0, atol=1e-6)


def test_force_unit_is_the_weight_when_scaled(sand):
    assert make(sand).force_unit == pytest.approx(MASS * 9.81)
    assert make(sand, qp="newton").force_unit == 1.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_warm_started_plans_land_at_the_optimum(sand, seed):
    """Along 30 warm-started ticks the default settings' forces are the QP's optimum to
    ≈ 0.00015–0.0006 N (median; measured over seeds 0–2 with eps_abs 1e-5; 0.002–0.004 N
    at the former 1e-4) — the newton settings (automatic backend, shrinking μ_in) stopped
    3–4.7 N from it (median). Bound: 0.006 N, ten times the measured worst median; no
    tick may fail (zero forces are feasible)."""
    mpc = make(sand)
    data = mpc.new_data()
    ref_mpc = make(sand, qp="newton")
    errors = []
    for kw in walk_ticks(30, seed):
        plan = mpc.solve(data, **kw)
        assert plan.status.ok and plan.fallback == ""
        _, ref_data = tight(ref_mpc)
        best = ref_mpc.solve(ref_data, **kw)
        assert best.status.ok
        errors.append(float(np.abs(plan.forces - best.forces).max()))
    assert data.failures == 0
    assert np.median(errors) <= 0.006


@pytest.mark.parametrize("assembly", ["compiled", "numpy"])
def test_daqp_plans_the_optimum(sand, assembly):
    """``qp: daqp`` (the ``scaled`` QP solved by DAQP, reading it where the assembly wrote
    it): along 30 warm ticks each plan is the QP's optimum (a tight cold ProxSuite solve of
    the same model) — measured ≤ 7.9e-7 N (the tight solve's own stopping point, eps_abs
    1e-9 × m g); bound 1e-4 N — with and without the sinkage cost, never failing."""
    for w_sink in (0.0, 1e3):
        mpc = dataclasses.replace(make(sand, w_sink).with_qp("daqp"), assembly=assembly)
        data = mpc.new_data()
        ref_mpc, ref_data = tight(make(sand, w_sink))
        for kw in walk_ticks(30, seed=2):
            plan = mpc.solve(data, **kw)
            _, ref_data = tight(ref_mpc)
            best = ref_mpc.solve(ref_data, **kw)
            assert plan.status.ok and plan.fallback == "" and best.status.ok
            np.testing.assert_allclose(plan.forces, best.forces, rtol=0, atol=1e-4)
        assert data.failures == 0


def test_feasible_qp_is_not_declared_infeasible(sand):
    """The cold first tick of seed 1 (zero forces feasible) that ProxSuite's primal-dual
    backend called primal infeasible at its default eps_primal_inf = 1e-4: solved with the
    MPC's 1e-6."""
    kw = walk_ticks(1, seed=1)[0]
    mpc = make(sand)
    plan = mpc.solve(mpc.new_data(), **kw)
    assert plan.status.ok and plan.fallback == ""


def test_mu_in_reset_solves_a_warm_sequence_like_cold_solves():
    """A warm-started solver that restarts μ_in at 0.1 each update reaches each QP's cold
    solution (random strictly convex QPs with box and inequality rows, eps_abs 1e-9:
    measured ≤ 1e-7 apart)."""
    rng = np.random.default_rng(4)
    warm = ProxQPSolver(12, 0, 8, box=True, eps_abs=1e-9, max_iter=1000, mu_in_reset=0.1)
    for _ in range(8):
        M = rng.normal(size=(12, 12))
        p = QPProblem(M @ M.T + 0.1 * np.eye(12), rng.normal(size=12), None, None,
                      rng.normal(size=(8, 12)), np.full(8, -1e20), rng.uniform(0.1, 1.0, 8),
                      np.full(12, -1.0), np.full(12, 1.0))
        a = warm.solve(p)
        b = ProxQPSolver(12, 0, 8, box=True, eps_abs=1e-9, max_iter=1000).solve(p)
        assert a.status.ok and b.status.ok
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-5)


def test_qp_settings_are_chosen_by_the_config(sand):
    """``controller.mpc.qp`` reaches the MPC: ``scaled`` (the default) puts forces in units
    of m g, ``newton`` keeps them in newtons; an unknown name is one clear error."""
    assert MPCConfig().qp == "scaled"
    assert make(sand, qp="newton").force_unit == 1.0
    assert make(sand, qp="newton").qp.mu_in_reset is None
    scaled = make(sand, qp="scaled")
    assert scaled.qp.backend == "primal_dual_ldlt" and scaled.qp.mu_in_reset == 0.1
    assert make(sand, qp="newton").with_qp("scaled").qp == scaled.qp
    with pytest.raises(ConfigError) as err:
        scaled.with_qp("fast")
    assert err.value.key == "controller.mpc.qp" and "newton" in err.value.allowed
    with pytest.raises(Exception, match="qp"):
        MPCConfig(qp="fast")
