"""The polytope rows the MPC's QP keeps (granular_mpc/control/mpc_rows.py) and the
``scaled_rows`` QP without the implied ones: the same feasible set, the same optimum."""

import numpy as np
import pytest

from granular_mpc.config import MPCConfig
from granular_mpc.control.contact_model import ForcePolytope, ground_model
from granular_mpc.control.mpc import QP_SETTINGS
from granular_mpc.control.mpc_rows import mpc_polytope_rows, row_is_redundant
from test_mpc_qp import make, tight, walk_ticks


def sample_block(poly: ForcePolytope, n: int, rng) -> np.ndarray:
    """``n`` random forces of a two-point block (n, 2, 3) inside the box
    0 ≤ f_z ≤ f_max/2, |f_x|, |f_y| ≤ f_max, many of them near the polytope's faces."""
    zmax = poly.f_max / 2
    f = np.empty((n, 2, 3))
    f[..., 2] = zmax * rng.uniform(0.0, 1.0, (n, 2)) ** 0.3
    f[..., :2] = rng.uniform(-1.0, 1.0, (n, 2, 2)) * f[..., 2:3] * 0.5
    return f


def satisfies(poly: ForcePolytope, rows: np.ndarray, f: np.ndarray, tol: float) -> np.ndarray:
    """Which forces ``f`` (n, 2, 3) satisfy the polytope rows ``rows`` (cone rows on each
    point, capacity rows on the sum; evaluated directly, no LP)."""
    ok = np.ones(f.shape[0], dtype=bool)
    for i in rows:
        g, h = poly.G[i], poly.h[i]
        if h <= 0.0:
            ok &= np.all(f @ g <= tol, axis=1)
        else:
            ok &= f.sum(axis=1) @ g <= h + tol
    return ok


def test_sand_drops_the_lateral_capacity_rows_only(sand):
    """On sand the lateral capacity bound is the lateral ratio times the normal capacity,
    so the cone rows and f_z ≤ f_max imply it: exactly those two rows go, every cone row
    and the normal capacity rows stay."""
    c = MPCConfig()
    poly = ground_model(sand, c).polytope
    rows = mpc_polytope_rows(poly, 2)
    lateral = [i for i in range(poly.G.shape[0])
               if poly.h[i] > 0 and poly.G[i, 2] == 0.0 and poly.G[i, 0] == 0.0]
    assert sorted(rows.dropped) == sorted(lateral) and len(lateral) == 2
    assert rows.cone.shape[0] == len(poly.cone_rows)
    assert rows.capacity.shape[0] == len(poly.capacity_rows) - 2
    assert np.all(rows.h_capacity > 0)


def test_dropped_rows_hold_wherever_the_kept_ones_do(sand):
    """Independent check by sampling: of 200,000 random forces of a block plus the block's
    lateral corners (both points at f_max/2 and at the lateral ratio, one where a dropped
    row is tight), every one that satisfies the kept rows and the box (to 1e-9 of f_max)
    satisfies the dropped rows too, and the corners reach their bound (the check has
    teeth)."""
    ground = ground_model(sand, MPCConfig())
    poly = ground.polytope
    rows = mpc_polytope_rows(poly, 2)
    kept = [i for i in range(poly.G.shape[0]) if i not in rows.dropped]
    zmax, mu = poly.f_max / 2, ground.lateral_ratio
    corners = np.array([[[0.0, sgn * mu * zmax, zmax]] * 2 for sgn in (1.0, -1.0)])
    f = np.concatenate([sample_block(poly, 200_000, np.random.default_rng(0)), corners])
    tol = 1e-9 * poly.f_max
    inside = satisfies(poly, kept, f, tol)
    assert inside.sum() > 1000 and inside[-2:].all()
    assert np.all(satisfies(poly, list(rows.dropped), f[inside], tol))
    worst = max(float(np.max(f[inside].sum(axis=1) @ poly.G[i] / poly.h[i]))
                for i in rows.dropped)
    assert worst > 0.999


def test_a_binding_row_is_kept(sand):
    """A lateral capacity row at half what the cone implies is not redundant (kept), and
    neither is any rigid-ground cone row."""
    poly = ground_model(sand, MPCConfig()).polytope
    h = poly.h.copy()
    lateral = [i for i in range(poly.G.shape[0])
               if poly.h[i] > 0 and poly.G[i, 2] == 0.0 and poly.G[i, 0] == 0.0]
    h[lateral] *= 0.5
    tighter = ForcePolytope(poly.G, h, poly.f_max)
    assert mpc_polytope_rows(tighter, 2).dropped == ()
    others = [j for j in range(poly.G.shape[0]) if j != lateral[0]]
    assert not row_is_redundant(tighter, lateral[0], others, 2)
    assert row_is_redundant(poly, lateral[0], others, 2)


def test_rigid_ground_keeps_every_row(rigid):
    poly = ground_model(rigid, MPCConfig()).polytope
    rows = mpc_polytope_rows(poly, 2)
    assert rows.dropped == () and rows.cone.shape[0] == poly.G.shape[0]


def test_scaled_rows_is_scaled_with_fewer_rows(sand):
    """``scaled_rows`` is the ``scaled`` numerics with ``drop_implied_rows``: 2 rows fewer
    per block, the same variables."""
    a, b = QP_SETTINGS["scaled"], QP_SETTINGS["scaled_rows"]
    assert (a.backend, a.scaled, a.mu_in_reset, a.eps_abs, a.eps_primal_inf) == \
        (b.backend, b.scaled, b.mu_in_reset, b.eps_abs, b.eps_primal_inf)
    assert b.drop_implied_rows and not a.drop_implied_rows
    full, lean = make(sand), make(sand).with_qp("scaled_rows")
    assert lean.nu == full.nu and lean.n_in == full.n_in - 2 * full.max_pairs


@pytest.mark.parametrize("assembly", ["compiled", "numpy"])
def test_scaled_rows_plans_the_full_qps_optimum(sand, assembly):
    """Along 30 warm-started ticks, with and without the sinkage cost, the ``scaled_rows``
    plan is the optimum of the FULL QP (every polytope row; a tight cold ProxSuite solve,
    eps_abs 1e-9): median within 0.006 N as ``scaled`` is (test_mpc_qp.py), and its
    tight cold solve equals the full QP's to 1e-4 N; the plan satisfies every dropped row."""
    import dataclasses
    for w_sink in (0.0, 1e3):
        lean = dataclasses.replace(make(sand, w_sink).with_qp("scaled_rows"),
                                   assembly=assembly)
        data = lean.new_data()
        ref = make(sand, w_sink)
        poly = ref.ground.polytope
        errors = []
        for kw in walk_ticks(30, seed=2):
            plan = lean.solve(data, **kw)
            _, ref_data = tight(ref)
            best = ref.solve(ref_data, **kw)
            mpc_t, lean_data = tight(lean)
            best_lean = mpc_t.solve(lean_data, **kw)
            assert plan.status.ok and plan.fallback == "" and best.status.ok
            assert best_lean.status.ok
            np.testing.assert_allclose(best_lean.forces, best.forces, rtol=0, atol=1e-4)
            errors.append(float(np.abs(plan.forces - best.forces).max()))
            foot = plan.forces.sum(axis=2)                       # (N, 2, 3) in W
            yaw = kw["x_ref"][0, 2]
            c, s = np.cos(yaw), np.sin(yaw)
            local = foot.copy()
            local[..., 0] = c * foot[..., 0] + s * foot[..., 1]
            local[..., 1] = -s * foot[..., 0] + c * foot[..., 1]
            share = np.clip(kw["capacity"] / poly.f_max, 0.0, 1.0)
            for i in lean.polytope_rows.dropped:
                assert np.all(local @ poly.G[i] <= poly.h[i] * share + 1e-3)
        assert data.failures == 0
        assert np.median(errors) <= 0.006
