"""Bounded least squares on a QR-reduced system (validation/diagnosis/bounded_lsq.py)
against ``scipy.optimize.lsq_linear(method="bvls")`` on the full rows."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear
from threadpoolctl import threadpool_info

from granular_mpc.validation.diagnosis.bounded_lsq import (ReducedSystem, bvls, lstsq_solution,
                                                          one_blas_thread)


def _reference(X, y, lb, ub):
    """The former fit: lsq_linear's BVLS on unit-norm columns of the full rows."""
    if X.shape[1] == 0:
        return np.zeros(0), float(y @ y)
    scale = np.sqrt((X ** 2).sum(axis=0))
    scale[scale == 0] = 1.0
    beta = lsq_linear(X / scale, y, bounds=(lb * scale, ub * scale), method="bvls").x / scale
    r = y - X @ beta
    return beta, float(r @ r)


def _problem(seed):
    rng = np.random.default_rng(seed)
    n, P = int(rng.integers(20, 1500)), int(rng.integers(1, 12))
    units = 10.0 ** rng.uniform(-4, 4, P)           # columns in very different units
    A = rng.normal(size=(n, P)) * units
    beta = rng.normal(size=P) / units
    y = A @ beta + rng.uniform(0.01, 2.0) * rng.normal(size=n)
    # bounds around 0 that the unbounded solution often violates
    lb = np.where(rng.random(P) < 0.3, -np.inf, -np.abs(beta) * rng.uniform(0, 1.5, P))
    ub = np.where(rng.random(P) < 0.3, np.inf, np.abs(beta) * rng.uniform(0, 1.5, P))
    ub = np.maximum(ub, lb + 1e-6 / units)
    return A, y, lb, ub


@pytest.mark.parametrize("seed", range(60))
def test_reduced_fit_matches_lsq_linear_on_the_full_rows(seed):
    A, y, lb, ub = _problem(seed)
    rng = np.random.default_rng(1000 + seed)
    red = ReducedSystem.of(A, y)
    for _ in range(5):
        k = int(rng.integers(0, A.shape[1] + 1))
        cols = np.sort(rng.choice(A.shape[1], k, replace=False))
        beta, rss = red.fit(cols, lb[cols], ub[cols])
        ref, rss_ref = _reference(A[:, cols], y, lb[cols], ub[cols])
        np.testing.assert_allclose(beta, ref, rtol=1e-9, atol=1e-12 * np.max(np.abs(ref),
                                                                                initial=1.0))
        assert rss == pytest.approx(rss_ref, rel=1e-9)
        tol = 1e-12 * np.abs(beta)
        assert np.all(beta >= lb[cols] - tol) and np.all(beta <= ub[cols] + tol)


@pytest.mark.parametrize("seed", range(30))
def test_bvls_matches_lsq_linear(seed):
    rng = np.random.default_rng(seed)
    m, k = int(rng.integers(5, 80)), int(rng.integers(1, 8))
    A = rng.normal(size=(m, k))
    b = rng.normal(size=m) * 3
    lb = -rng.uniform(0, 0.3, k)
    ub = rng.uniform(0, 0.3, k)
    ref = lsq_linear(A, b, bounds=(lb, ub), method="bvls").x
    np.testing.assert_allclose(bvls(A, b, lb, ub), ref, rtol=1e-12, atol=1e-14)


def test_reduced_system_keeps_the_residual_outside_the_columns():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(300, 3))
    y = rng.normal(size=300)
    red = ReducedSystem.of(A, y)
    full = np.linalg.lstsq(A, y, rcond=None)
    assert red.rss_outside == pytest.approx(float(full[1][0]), rel=1e-12)
    beta, rss = red.fit(np.arange(0), np.zeros(0), np.zeros(0))
    assert beta.size == 0 and rss == pytest.approx(float(y @ y), rel=1e-12)
    zero = ReducedSystem.of(np.column_stack([A, np.zeros(300)]), y)
    b4, _ = zero.fit(np.arange(4), np.full(4, -np.inf), np.full(4, np.inf))
    np.testing.assert_allclose(b4[:3], full[0], rtol=1e-10)
    assert b4[3] == 0.0


def test_repeated_fit_is_the_first_fit():
    """A fit asked for again on the same reduced system (the bootstrap's forward selection
    and refits) returns the first one's β and RSS bit for bit, as a new array each time;
    other columns or bounds are fitted anew."""
    rng = np.random.default_rng(4)
    A = rng.standard_normal((300, 6))
    y = A @ np.array([1.0, -2.0, 0.5, 0.0, 3.0, -1.0]) + 0.1 * rng.standard_normal(300)
    fresh = ReducedSystem.of(A, y)
    memo = ReducedSystem.of(A, y)
    cols, lb, ub = np.array([0, 1, 4]), np.full(3, -np.inf), np.array([np.inf, 0.0, 2.0])
    b1, r1 = memo.fit(cols, lb, ub)
    b1[:] = 99.0                          # the caller's copy
    b2, r2 = memo.fit(cols, lb, ub)
    b0, r0 = fresh.fit(cols, lb, ub)
    assert np.array_equal(b2, b0) and r2 == r0 and not np.any(b2 == 99.0)
    b3, _ = memo.fit(cols, lb, np.array([np.inf, 0.0, 5.0]))
    assert b3[2] > 2.5                    # a new bound: a new fit (β_4 ≈ 3 unbounded)


@pytest.mark.parametrize("seed", range(6))
def test_lstsq_solution_is_numpys_lstsq_bit_for_bit(seed):
    rng = np.random.default_rng(700 + seed)
    for t in range(150):
        m, n = int(rng.integers(1, 60)), int(rng.integers(1, 30))
        A = rng.normal(size=(m, n)) * rng.uniform(1e-4, 1e4, size=n)
        if t % 4 == 0 and n > 2:                  # rank deficient: minimum norm
            A[:, 1] = 3.0 * A[:, 0]
        if t % 5 == 0:                            # a non-contiguous view
            A = A[:, ::-1]
        b = rng.normal(size=m) * rng.uniform(1e-3, 1e3)
        rcond = -1.0 if t % 2 else np.finfo(float).eps * max(m, n)
        assert np.array_equal(lstsq_solution(A, b, rcond),
                              np.linalg.lstsq(A, b, rcond=rcond)[0])


def test_one_blas_thread_limits_and_restores_the_blas_threads():
    def blas_threads():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    before = blas_threads()
    with one_blas_thread():
        assert all(n == 1 for n in blas_threads())
    assert blas_threads() == before
