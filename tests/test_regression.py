"""Regression (validation/diagnosis/regression.py): the fits on resampled rows and the CV
folds, solved on QR-reduced systems, against the reference bounded fit on the full rows."""

from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.validation.diagnosis.design import Design
from granular_mpc.validation.diagnosis.regression import Regression, fit_bounded


def _regression(seed):
    rng = np.random.default_rng(seed)
    n = 600
    keys = ["base", "a", "b", "c"]
    scales = {"base": 1.0, "a": 1e-3, "b": 1e3, "c": 5.0}
    X = {k: rng.normal(size=n) * s for k, s in scales.items()}
    y = 0.8 * X["base"] + 400.0 * X["a"] - 2e-4 * X["b"] + rng.normal(size=n)
    y[rng.integers(n, size=5)] = np.nan                    # non-finite rows are dropped
    bounds = {"base": (-5.0, 5.0), "a": (0.0, 300.0), "b": (-1.0, 0.0), "c": (0.0, 0.05)}
    groups = np.repeat(np.array([f"t{i}" for i in range(6)]), n // 6)
    d = Design(y, X, groups, np.arange(n), np.full(n, "grf_z"), np.zeros(n, int),
               {"grf_z": 1.0}, 0.5)
    return Regression(d, bounds, ["base"]), keys, bounds


@pytest.mark.parametrize("seed", range(5))
def test_resampled_fits_match_the_reference_on_the_full_rows(seed):
    reg, keys, _ = _regression(seed)
    rng = np.random.default_rng(seed)
    gs = np.unique(reg.groups)
    for _ in range(5):
        rows = np.concatenate([np.flatnonzero(reg.groups == g)
                               for g in rng.choice(gs, gs.size, replace=True)])
        for sel in (["base"], ["base", "a"], ["base", "a", "b"], keys):
            beta, rss = reg.fit(sel, rows)
            X, lb, ub = reg.matrix(sel, rows)
            ref = fit_bounded(X, reg.y[rows], lb, ub)
            np.testing.assert_allclose(beta, ref, rtol=1e-9,
                                       atol=1e-12 * np.max(np.abs(ref)))
            r = reg.y[rows] - X @ ref
            assert rss == pytest.approx(float(r @ r), rel=1e-9)
    # the bounds bind (the unbounded solution leaves them): the BVLS path is exercised
    X, lb, ub = reg.matrix(keys, rows)
    free = np.linalg.lstsq(X, reg.y[rows], rcond=None)[0]
    assert not np.all((free >= lb) & (free <= ub))
    beta, _ = reg.fit(keys, rows)
    tol = 1e-12 * np.abs(beta)
    assert np.all(beta >= lb - tol) and np.all(beta <= ub + tol)


def test_all_rows_fit_is_the_reference_bit_for_bit():
    reg, keys, _ = _regression(11)
    X, lb, ub = reg.matrix(keys)
    beta, _ = reg.fit(keys)
    assert np.array_equal(beta, fit_bounded(X, reg.y, lb, ub))


def test_cv_matches_reference_fold_fits():
    reg, keys, _ = _regression(3)
    X, lb, ub = reg.matrix(keys)
    score = reg.cv(keys)
    ref = []
    for tr, te in reg.splits:
        b = fit_bounded(X[tr], reg.y[tr], lb, ub)
        r = reg.y[te] - X[te] @ b
        ref.append(float(r @ r))
    assert len(score.folds) == len(ref) >= 2
    np.testing.assert_allclose(score.folds, ref, rtol=1e-9)
