"""The MPC's QP assembly, compiled (control/mpc_assembly.py) and NumPy (control/mpc.py's
reference path), against a plain NumPy reference of the formulas: the condensed map Γ built
step by step, ``H = Γᵀ Q Γ``, ``g = Γᵀ Q e``."""

from dataclasses import replace

import numpy as np
import pytest

from granular_mpc.config import MPCConfig
from granular_mpc.control.contact_model import ground_model
from granular_mpc.control.mpc import ASSEMBLIES, CentroidalMPC
from granular_mpc.control.mpc_assembly import compile_assembly, condensation_tables
from granular_mpc.exceptions import ConfigError
from granular_mpc.rotations import rot_z, skew

MASS = 10.64
INERTIA = np.array([[0.17, 0.0, 0.02], [0.0, 0.16, 0.0], [0.02, 0.0, 0.08]])
BIG = 1e20


def make(terrain, N, max_pairs, qp="scaled", weight_sinkage=0.0, assembly="compiled"):
    c = MPCConfig(horizon=N, dt=0.04, qp=qp, weight_sinkage=weight_sinkage)
    return CentroidalMPC(c, MASS, INERTIA, 9.81, ground_model(terrain, c), n_points=2,
                         max_pairs=max_pairs, assembly=assembly)


def random_tick(rng, N, yaw):
    """A random state, reference, contact set (any pattern, double support included),
    contact points, loads and capacities."""
    x0 = np.concatenate([rng.normal(0, 0.05, 2), [yaw + rng.normal(0, 0.1)],
                         rng.normal(0, 0.05, 2), [0.4], rng.normal(0, 0.3, 6)])
    x_ref = np.tile(x0, (N, 1)) + rng.normal(0, 0.02, (N, 12))
    x_ref[:, 2] = yaw + rng.choice([-2.0, 0.0, 2.0]) * np.pi   # exercise the yaw unwrap
    contacts = rng.random((N, 2)) < 0.6
    points = rng.normal(0, 0.1, (N, 2, 2, 3)) + x0[3:6] - [0.0, 0.0, 0.41]
    load = contacts * (MASS * 9.81) / np.maximum(contacts.sum(axis=1, keepdims=True), 1)
    cap = rng.uniform(-20.0, 400.0, (N, 2))
    return dict(t=0.0, x0=x0, x_ref=x_ref, contacts=contacts, points=points,
                nominal_load=load, capacity=cap)


def reference_qp(mpc, x0, x_ref, contacts, points, nominal_load, capacity, **_):
    """(H, g, C, l, u, lb, ub) of the MPC's QP, formula by formula (module docstring of
    control/mpc.py): B_d = B dt + A B dt²/2, A_d^m = I + m A dt, Γ stacked step by step."""
    c, N, nps = mpc.config, mpc.N, mpc.n_points
    dt, m, fu = c.dt, mpc.mass, mpc.force_unit
    Rz = rot_z(x_ref[0, 2])
    I_W_inv = Rz @ np.linalg.inv(mpc.inertia_B) @ Rz.T
    A = np.zeros((12, 12))
    A[0:3, 6:9] = Rz.T
    A[3:6, 9:12] = np.eye(3)
    ks, fs = np.nonzero(contacts)
    if len(ks) > mpc.max_pairs:
        keep = np.sort(np.argsort(-nominal_load[ks, fs], kind="stable")[: mpc.max_pairs])
        ks, fs = ks[keep], fs[keep]
    P = len(ks)
    Gam = np.zeros((N * 12, mpc.nu))
    for j, (k, f) in enumerate(zip(ks, fs)):
        Bc = np.zeros((12, 3 * nps))
        for i in range(nps):
            r = points[k, f, i] - x_ref[k, 3:6]
            Bc[6:9, 3 * i:3 * i + 3] = I_W_inv @ skew(r)
            Bc[9:12, 3 * i:3 * i + 3] = np.eye(3) / m
        Bd = Bc * dt + A @ Bc * dt * dt / 2
        for kk in range(k + 1, N + 1):          # the state after step kk
            Ad = np.eye(12) + (kk - 1 - k) * A * dt
            Gam[(kk - 1) * 12:kk * 12, j * 3 * nps:(j + 1) * 3 * nps] = Ad @ Bd
    free = np.zeros((N, 12))
    grav = np.zeros(12)
    grav[11] = -mpc.gravity
    x = x0.copy()
    for kk in range(N):                          # exact ZOH of the drift (A² = 0)
        x = x + A @ x * dt + grav * dt + A @ grav * dt * dt / 2
        free[kk] = x
    ref = x_ref.copy()
    ref[:, 2] = x0[2] + (ref[:, 2] - x0[2] + np.pi) % (2 * np.pi) - np.pi
    q = np.tile(np.concatenate([c.weights_orientation, c.weights_position,
                                c.weights_angular_velocity, c.weights_velocity]), N)
    Gs = Gam * fu
    H = Gs.T @ (q[:, None] * Gs) + np.eye(mpc.nu) * c.weight_force * fu * fu
    g = Gs.T @ (q * (free - ref).ravel())
    if c.weight_sinkage > 0.0 and mpc.ground.granular:
        for j, (k, f) in enumerate(zip(ks, fs)):
            F0 = nominal_load[k, f]
            z0, a = mpc.ground.sinkage(F0), mpc.ground.sinkage_slope(F0)
            jz = [j * 3 * nps + 3 * i + 2 for i in range(nps)]
            for i1 in jz:
                g[i1] += 2 * c.weight_sinkage * a * fu * (z0 - a * F0)
                for i2 in jz:
                    H[i1, i2] += 2 * c.weight_sinkage * a * a * fu * fu
    poly = mpc.ground.polytope
    cone, capr = poly.G[poly.cone_rows], poly.G[poly.capacity_rows]
    rows = mpc.rows_per_pair
    C = np.zeros((mpc.n_in, mpc.nu))
    u = np.zeros(mpc.n_in)
    lb, ub = np.zeros(mpc.nu), np.zeros(mpc.nu)
    for j, (k, f) in enumerate(zip(ks, fs)):
        share = 1.0 if capacity is None else min(max(capacity[k, f] / poly.f_max, 0.0), 1.0)
        r0, v0 = j * rows, j * 3 * nps
        for i in range(nps):
            C[r0 + i * len(cone):r0 + (i + 1) * len(cone), v0 + 3 * i:v0 + 3 * i + 3] = \
                cone @ Rz.T * fu
            C[r0 + nps * len(cone):r0 + rows, v0 + 3 * i:v0 + 3 * i + 3] = capr @ Rz.T * fu
            lb[v0 + 3 * i:v0 + 3 * i + 2] = -BIG
            ub[v0 + 3 * i:v0 + 3 * i + 2] = BIG
            ub[v0 + 3 * i + 2] = poly.f_max * share / nps / fu
        u[r0 + nps * len(cone):r0 + rows] = poly.h[poly.capacity_rows] * share
    return H, g, C, np.full(mpc.n_in, -BIG), u, lb, ub, free, Gam, ks, fs, P


def assert_close(a, b, name):
    """Equal to 1e-12 of the array's largest (non-infinite-bound) entry; ±BIG exactly."""
    big = np.abs(b) >= BIG
    assert np.array_equal(np.abs(a) >= BIG, big), name
    np.testing.assert_array_equal(a[big], b[big], err_msg=name)
    scale = max(np.abs(np.where(big, 0.0, b)).max(), 1e-300)
    err = np.abs(np.where(big, 0.0, a - b)).max()
    assert err <= 1e-12 * scale, f"{name}: {err:.3g} > 1e-12 × {scale:.3g}"
    return err / scale


@pytest.mark.parametrize("assembly", ["compiled", "numpy"])
@pytest.mark.parametrize("qp", ["scaled", "newton"])
def test_qp_equals_the_plain_reference(sand, rigid, assembly, qp):
    """H, g, C, l, u, lb, ub of both assemblies equal the step-by-step reference to 1e-12
    of each array's largest entry (measured ≤ 1e-15) on random states, yaws near ±π and
    2π away, random contact sets (also more contacts than blocks), with and without
    capacities and the sinkage cost; the predicted states equal free + Γ U."""
    rng = np.random.default_rng(7)
    checked = 0
    for trial in range(12):
        terrain = (sand, rigid)[trial % 2]
        N = (6, 10)[trial % 3 == 0]
        max_pairs = (N + 2, N // 2 + 1)[trial % 4 == 3]        # some ticks are truncated
        mpc = make(terrain, N, max_pairs, qp=qp, weight_sinkage=(0.0, 1e3)[trial % 5 == 1],
                   assembly=assembly)
        if assembly == "compiled" and mpc.new_data().work.assembly is None:
            pytest.skip("no C compiler: the compiled assembly is not built")
        kw = random_tick(rng, N, yaw=(0.3, np.pi - 0.05, -np.pi + 0.02)[trial % 3])
        if trial % 3 == 2:
            kw["capacity"] = None
        data = mpc.new_data()
        plan = mpc.solve(data, **kw)
        H, g, C, l, u, lb, ub, free, Gam, ks, fs, P = reference_qp(mpc, **kw)
        w = data.work
        for name, a, b in (("H", w.H, H), ("g", w.g, g), ("C", w.C, C), ("l", w.l, l),
                           ("u", w.u, u), ("lb", w.lb, lb), ("ub", w.ub, ub)):
            assert_close(a, b, name)
        assert plan.status.ok
        U = np.zeros(mpc.nu)
        U[:P * 3 * mpc.n_points] = plan.forces[ks, fs].ravel()
        assert_close(plan.states, free + (Gam @ U).reshape(N, 12), "states")
        checked += P > 0
    assert checked >= 10


def test_compiled_and_numpy_assemblies_plan_alike(sand):
    """Along 20 warm-started ticks both assemblies give the same plans (the QPs differ by
    round-off only: measured ≤ 5e-10 N apart on the forces)."""
    rng = np.random.default_rng(3)
    mpc = make(sand, 10, 12)
    if mpc.new_data().work.assembly is None:
        pytest.skip("no C compiler: the compiled assembly is not built")
    ref = replace(mpc, assembly="numpy")
    d1, d2 = mpc.new_data(), ref.new_data()
    assert d2.work.assembly is None
    for _ in range(20):
        kw = random_tick(rng, 10, yaw=0.2)
        a, b = mpc.solve(d1, **kw), ref.solve(d2, **kw)
        assert a.status.ok and b.status.ok
        np.testing.assert_allclose(a.forces, b.forces, rtol=0, atol=1e-6)
        np.testing.assert_allclose(a.states, b.states, rtol=0, atol=1e-9)


def test_one_library_serves_models_of_the_same_sizes(sand, rigid):
    """The model's numbers are an input of the compiled code: weights and the QP scaling
    share one build; other sizes (horizon, blocks, polytope rows) get another."""
    a = make(sand, 10, 12).assembly_constants()
    b = make(sand, 10, 12, qp="newton", weight_sinkage=5.0).assembly_constants()
    assert a.sizes == b.sizes and a != b
    assert make(sand, 6, 8).assembly_constants().sizes != a.sizes
    assert make(rigid, 10, 12).assembly_constants().sizes != a.sizes
    fns = compile_assembly(a.sizes)
    if fns is None:
        pytest.skip("no C compiler")
    assert compile_assembly(b.sizes) is fns
    assert len(a.packed()) == fns[0].size1_in(0)


def test_step_tables_count_what_both_blocks_reach():
    """S0[a, b] = #{k ≤ N: k > a, k > b}, S1 = Σ (k − 1 − b), S2 = Σ (k − 1 − a)(k − 1 − b)
    over those steps, by brute force."""
    N = 7
    t = condensation_tables(N)
    for a in range(N):
        for b in range(N):
            ks = [k for k in range(1, N + 1) if k > a and k > b]
            assert t.s0[a, b] == len(ks)
            assert t.s1[a, b] == sum(k - 1 - b for k in ks)
            assert t.s2[a, b] == sum((k - 1 - a) * (k - 1 - b) for k in ks)
        assert t.reach[a].sum() == N - a and t.lag[a, -1] == N - 1 - a


def test_unknown_assembly_is_one_clear_error(sand):
    assert ASSEMBLIES == ("compiled", "numpy")
    with pytest.raises(ConfigError) as err:
        make(sand, 6, 8, assembly="fortran").new_data()
    assert err.value.key == "assembly" and "numpy" in err.value.allowed
