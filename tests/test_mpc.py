"""Centroidal-plus-sinkage MPC: discretisation, condensation, constraints, fallback."""

import math
from dataclasses import replace

import numpy as np
import pytest

from granular_mpc.config import MPCConfig
from granular_mpc.control.contact_model import ground_model
from granular_mpc.control.mpc import CentroidalMPC, predicted_sinkage
from granular_mpc.rotations import rot_z, skew
from granular_mpc.control.solvers.proxqp import QPSolution, QPStatus

MASS = 10.64
INERTIA = np.array([[0.17, 0.0, 0.02], [0.0, 0.16, 0.0], [0.02, 0.0, 0.08]])


def make(terrain, N=6, **cfg):
    c = MPCConfig(horizon=N, dt=0.04, **cfg)
    return CentroidalMPC(c, MASS, INERTIA, 9.81, ground_model(terrain, c), n_points=2,
                         max_pairs=N + 2)


def scenario(N, yaw=0.1):
    rng = np.random.default_rng(3)
    x0 = np.concatenate([[0.01, -0.02, yaw], [0.0, 0.01, 0.40], rng.normal(0, 0.1, 3),
                         [0.2, 0.05, 0.0]])
    x_ref = np.tile(x0, (N, 1))
    x_ref[:, 5] = 0.41
    x_ref[:, 2] = yaw
    contacts = np.zeros((N, 2), dtype=bool)
    contacts[: N // 2, 0] = True
    contacts[N // 2 - 1:, 1] = True                     # one double-support step
    points = np.zeros((N, 2, 2, 3))
    for k in range(N):
        points[k, 0] = [[0.02, 0.08, -0.01], [0.02, 0.11, -0.01]]
        points[k, 1] = [[0.10, -0.11, -0.01], [0.10, -0.08, -0.01]]
    load = contacts * (MASS * 9.81) / np.maximum(contacts.sum(axis=1, keepdims=True), 1)
    return x0, x_ref, contacts, points, load


def srb_rhs(x, f_list, yaw):
    """Continuous linearised single-rigid-body model (the MPC's own assumptions)."""
    Rz = rot_z(yaw)
    I_W = Rz @ INERTIA @ Rz.T
    dx = np.zeros(12)
    dx[0:3] = Rz.T @ x[6:9]
    dx[3:6] = x[9:12]
    tau = sum(np.cross(r, f) for r, f in f_list)
    dx[6:9] = np.linalg.solve(I_W, tau)
    dx[9:12] = sum(f for _, f in f_list) / MASS + np.array([0, 0, -9.81])
    return dx


def test_plan_equals_rk4_of_the_continuous_model(sand):
    """The condensed prediction (exact ZOH discretisation, A² = 0) equals a fine RK4
    integration of the continuous SRB model under the planned piecewise-constant forces."""
    N = 6
    mpc = make(sand, N)
    data = mpc.new_data()
    x0, x_ref, contacts, points, load = scenario(N)
    plan = mpc.solve(data, t=0.0, x0=x0, x_ref=x_ref, contacts=contacts, points=points,
                     nominal_load=load)
    assert plan.status.ok
    x = x0.copy()
    h = 0.04 / 200
    for k in range(N):
        f_list = [(points[k, f, i] - x_ref[k, 3:6], plan.forces[k, f, i])
                  for f in (0, 1) if contacts[k, f] for i in range(2)]
        for _ in range(200):
            k1 = srb_rhs(x, f_list, x_ref[0, 2])
            k2 = srb_rhs(x + 0.5 * h * k1, f_list, x_ref[0, 2])
            k3 = srb_rhs(x + 0.5 * h * k2, f_list, x_ref[0, 2])
            k4 = srb_rhs(x + h * k3, f_list, x_ref[0, 2])
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        # RK4 with h = 0.2 ms on a model that is polynomial (degree ≤ 2) in time under
        # constant forces: exact up to round-off (~1e-13); 1e-8 leaves room for the
        # condensed prediction's own round-off over 6 steps
        np.testing.assert_allclose(plan.states[k], x, atol=1e-8)


def test_plan_respects_the_ground_and_the_schedule(sand, rigid):
    N = 6
    for terrain in (sand, rigid):
        mpc = make(terrain, N)
        data = mpc.new_data()
        x0, x_ref, contacts, points, load = scenario(N)
        plan = mpc.solve(data, t=0.0, x0=x0, x_ref=x_ref, contacts=contacts,
                         points=points, nominal_load=load)
        assert plan.status.ok
        # Derived tolerance: ProxSuite stops when the primal residual ‖(violation)‖∞ ≤ eps_abs
        # (eps_rel = 0), every row in newtons here (box rows on F_z, cone and capacity rows
        # with unit coefficient on a force component), so each row is violated by at most
        # eps_abs = 1e-4 N; F_z ≤ f_max sums two points' box rows: 2·eps_abs. Measured worst
        # over four yaws × two grounds: 3.5e-5 N (cone row). (The cone/capacity checks were
        # at 1e-3, ten times the solver's guarantee.)
        tol = data.solver.eps_abs
        poly = mpc.ground.polytope
        Rz = rot_z(x_ref[0, 2])
        for k in range(N):
            for f in (0, 1):
                F = plan.forces[k, f]
                if not contacts[k, f]:
                    assert np.all(F == 0.0)
                    continue
                assert np.all(F[:, 2] >= -tol)                   # each point only pushes
                for pt in F:                                     # each point's own cone
                    cone = poly.G[poly.cone_rows] @ (Rz.T @ pt)
                    assert np.all(cone <= tol)
                local = Rz.T @ F.sum(axis=0)                     # the foot's total capacity
                assert np.all(poly.G[poly.capacity_rows] @ local <= poly.h[poly.capacity_rows] + tol)
                assert local[2] <= poly.f_max + F.shape[0] * tol
        # the plan supports the robot: mean vertical force ≈ weight. Measured 0.9416 m g on
        # both grounds (the force weight and the 1 cm height error trade off); ±15 % is the
        # band of a plan that carries the robot — an unloaded or doubled plan fails it.
        fz = plan.forces[..., 2].sum(axis=(1, 2))
        assert fz.mean() == pytest.approx(MASS * 9.81, rel=0.15)


def test_capacity_scaling_bounds_the_normal_force(sand):
    N = 6
    mpc = make(sand, N)
    x0, x_ref, contacts, points, load = scenario(N)
    cap = np.full((N, 2), 30.0)
    data = mpc.new_data()
    plan = mpc.solve(data, t=0.0, x0=x0, x_ref=x_ref, contacts=contacts,
                     points=points, nominal_load=load, capacity=cap)
    assert plan.status.ok
    # the foot's F_z is the sum of its points' box rows, each within eps_abs (see above);
    # measured excess 2e-7 N. The cap binds: the unscaled plan asks > 30 N of some foot.
    assert plan.forces[..., 2].sum(axis=2).max() <= 30.0 + 2 * data.solver.eps_abs
    free = mpc.solve(mpc.new_data(), t=0.0, x0=x0, x_ref=x_ref, contacts=contacts,
                     points=points, nominal_load=load)
    assert free.forces[..., 2].sum(axis=2).max() > 30.0 + 1.0


def test_failed_solve_falls_back_to_the_shifted_plan(sand):
    N = 6
    mpc = make(sand, N)
    data = mpc.new_data()
    x0, x_ref, contacts, points, load = scenario(N)
    first = mpc.solve(data, t=0.0, x0=x0, x_ref=x_ref, contacts=contacts, points=points,
                      nominal_load=load)
    data.solver.solve = lambda p: QPSolution(np.zeros(mpc.nu), QPStatus.MAX_ITER)
    c2 = np.roll(contacts, -1, axis=0)
    c2[-1] = contacts[-1]
    plan = mpc.solve(data, t=0.04, x0=x0, x_ref=x_ref, contacts=c2, points=points,
                     nominal_load=load)
    assert data.failures == 1
    assert plan.fallback.startswith("shifted")
    np.testing.assert_allclose(plan.forces[0, 0], first.forces[1, 0])
    data.last = None
    plan = mpc.solve(data, t=0.08, x0=x0, x_ref=x_ref, contacts=contacts, points=points,
                     nominal_load=load)
    assert plan.fallback == "nominal"
    assert plan.forces[0, 0, :, 2].sum() == pytest.approx(load[0, 0])


@pytest.mark.parametrize("assembly", ["compiled", "numpy"])
def test_plan_is_bit_identical_with_and_without_the_one_buffer_check(sand, assembly):
    """The MPC's QP arrays are views of one buffer (``QPProblem.buffer``), so the solver
    checks their finiteness with one reduction; without the buffer it checks them one by
    one: the same plans, bit for bit, over a warm-started sequence of ticks."""
    N = 6
    mpc = replace(make(sand, N), assembly=assembly)
    fast, slow = mpc.new_data(), mpc.new_data()
    assert fast.work.problem.buffer is not None
    assert np.shares_memory(fast.work.problem.buffer, fast.work.problem.C)
    slow.work.problem.buffer = None
    x0, x_ref, contacts, points, load = scenario(N)
    for tick in range(4):
        c = np.roll(contacts, -tick, axis=0)
        kw = dict(t=0.04 * tick, x0=x0 + 0.01 * tick, x_ref=x_ref, contacts=c, points=points,
                  nominal_load=load)
        a, b = mpc.solve(fast, **kw), mpc.solve(slow, **kw)
        assert a.status.ok and b.status is a.status
        for x, y in ((a.forces, b.forces), (a.states, b.states), (a.sinkage, b.sinkage)):
            assert x.tobytes() == y.tobytes()


def test_non_finite_input_is_a_non_finite_status_and_a_fallback(sand):
    N = 6
    mpc = make(sand, N)
    data = mpc.new_data()
    x0, x_ref, contacts, points, load = scenario(N)
    mpc.solve(data, t=0.0, x0=x0, x_ref=x_ref, contacts=contacts, points=points,
              nominal_load=load)
    bad = x0.copy()
    bad[9] = np.nan
    plan = mpc.solve(data, t=0.04, x0=bad, x_ref=x_ref, contacts=contacts, points=points,
                     nominal_load=load)
    assert plan.status is QPStatus.NON_FINITE and data.failures == 1
    assert plan.fallback.startswith("shifted") and np.isfinite(plan.forces).all()
    # the solver was not poisoned: the next finite tick solves
    plan = mpc.solve(data, t=0.08, x0=x0, x_ref=x_ref, contacts=contacts, points=points,
                     nominal_load=load)
    assert plan.status.ok


def test_granular_polytope_lies_inside_the_rft_yield_curve(sand):
    """Every force the MPC may ask of sand at the allowed sinkage is one the medium holds:
    the sagittal polytope's vertices are inside the closed-form yield curve at z_max."""
    gm = ground_model(sand, MPCConfig())
    z = min(MPCConfig().max_sinkage, 0.95 * sand.config.layer_depth)
    curve = []
    for g in np.linspace(-math.pi / 2, math.pi / 2, 721):
        r = sand.foot_forces(z, 0.0, math.cos(g), -math.sin(g))
        curve.append((abs(r.f_h), r.f_z))
    curve = np.array(curve)
    G, fmax = gm.polytope.G, gm.polytope.f_max
    # sagittal vertices of {|F_h| ≤ μ F_z, |F_h| ≤ κ (F_cap − F_z), F_z ≤ F_cap}
    mu, kappa = -G[0, 2], G[2, 2]
    fz_corner = kappa * fmax / (mu + kappa)
    vertices = [(0.0, 0.0), (mu * fz_corner, fz_corner), (0.0, fmax)]
    # the vertices and 199 points along each edge between them: inside = some yield point
    # carries at least this vertical force and this shear. Tolerance 1e-9·f_max: the corner
    # and the top vertex lie ON the curve by construction (flows at 45° and 90° are among the
    # fitted samples and among the 721 here), so they pass only up to float round-off;
    # measured: interior edge points dominated with a factor ≥ 1.001.
    tol = 1e-9 * fmax
    for (h0, z0), (h1, z1) in zip(vertices, vertices[1:]):
        for s in np.linspace(0.0, 1.0, 201):
            fh, fz = h0 + s * (h1 - h0), z0 + s * (z1 - z0)
            ok = np.any((curve[:, 1] >= fz - tol) & (curve[:, 0] >= fh - tol))
            assert ok, (fh, fz)
    # the polytope is not trivially small: its top is the vertical capacity at z_max and
    # its corner carries a shear of μ_h·F_z with μ_h > 0.2 (measured 0.34)
    assert fmax == pytest.approx(sand.vertical_capacity(z), rel=1e-9)
    assert mu > 0.2 and kappa > 0.0


def test_sinkage_prediction_is_plastic(sand):
    N = 6
    mpc = make(sand, N)
    forces = np.zeros((N, 2, 2, 3))
    forces[:, 0, :, 2] = np.array([20, 60, 100, 50, 10, 80])[:, None] / 2
    contacts = np.zeros((N, 2), dtype=bool)
    contacts[:, 0] = True
    z = predicted_sinkage(mpc.ground, forces, contacts)[:, 0]
    assert np.all(np.diff(z) >= 0.0)                      # never comes back up
    assert z[2] == pytest.approx(mpc.ground.sinkage(100.0))
    assert z[-1] == pytest.approx(z[2])


def test_predicted_sinkage_is_the_deepest_z_of_each_stance_stretch(sand, rigid):
    """The vectorised prediction is, bit for bit, the deepest Z(F_z) of the loads so far
    in each foot's current stance stretch (reset in swing), Z evaluated point by point
    by ``GroundModel.sinkage``; zero on rigid ground. Random forces (some negative, some
    repeated peaks) and random schedules."""
    rng = np.random.default_rng(11)
    gm = make(sand, 8).ground
    for trial in range(200):
        N = int(rng.integers(1, 16))
        forces = rng.uniform(-20.0, 200.0, (N, 2, 2, 3))
        if trial % 3 == 0:
            forces[1::2] = forces[0:N - 1:2][: len(forces[1::2])]   # repeated loads
        contacts = rng.random((N, 2)) < 0.7
        fz = forces[..., 2].sum(axis=2)
        expected = np.zeros((N, 2))
        for f in range(2):
            depth = 0.0
            for k in range(N):
                depth = max(depth, gm.sinkage(float(fz[k, f]))) if contacts[k, f] else 0.0
                expected[k, f] = depth
        assert np.array_equal(predicted_sinkage(gm, forces, contacts), expected)
    rigid_gm = make(rigid, 8).ground
    assert not predicted_sinkage(rigid_gm, forces, contacts).any()


def test_skew_is_the_cross_product():
    r, f = np.array([0.1, -0.2, 0.3]), np.array([2.0, 1.0, -1.0])
    np.testing.assert_allclose(skew(r) @ f, np.cross(r, f))


def test_capacities_equal_capacity_point_by_point(sand, rigid):
    """The vectorised capacity (the controller's force cap, one interpolation for both
    feet) is the scalar one at every depth, bit for bit: above the surface, on and between
    the tabulated depths, beyond the table; on rigid ground the polytope's bound."""
    rng = np.random.default_rng(5)
    for terrain in (sand, rigid):
        gm = ground_model(terrain, MPCConfig())
        depths = np.concatenate([[-0.01, 0.0, 1e-9], rng.uniform(-0.01, 0.3, 500)])
        expected = np.array([gm.capacity(float(d)) for d in depths])
        np.testing.assert_array_equal(gm.capacities(depths), expected)
        assert gm.capacities(depths).shape == depths.shape
