"""The KSG mutual-information estimate equals scikit-learn's bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.feature_selection import mutual_info_regression

from granular_mpc.validation.diagnosis.mutual_info import mutual_info, within


@pytest.mark.parametrize("seed", range(8))
def test_equals_sklearn(seed):
    rng = np.random.default_rng(seed)
    n, f = int(rng.integers(40, 600)), int(rng.integers(1, 6))
    X = rng.standard_normal((n, f)) * rng.uniform(0.01, 100.0, f)
    if seed % 2:
        X = np.round(X, 1)                 # ties: the noise breaks them
    y = X[:, 0] ** 2 + 0.3 * rng.standard_normal(n)
    if seed % 3 == 0:
        y = np.round(y)
    expected = mutual_info_regression(X, y, random_state=seed)
    got = mutual_info(X, y, random_state=seed)
    assert np.array_equal(got, expected)


def test_dependent_feature_scores_higher():
    rng = np.random.default_rng(3)
    x = rng.uniform(-1, 1, 500)
    X = np.column_stack([x, rng.uniform(-1, 1, 500)])
    mi = mutual_info(X, np.sin(3 * x) + 0.05 * rng.standard_normal(500), random_state=0)
    assert mi[0] > 1.0 and mi[1] < 0.1


def test_within_counts_rounded_distances():
    rng = np.random.default_rng(5)
    v = rng.standard_normal(300)
    r = np.abs(rng.standard_normal(300)) * 0.2
    r[:20] = np.abs(v[20:40] - v[:20])     # radius exactly at another point's distance
    brute = (np.abs(v[None, :] - v[:, None]) <= r[:, None]).sum(axis=1)
    assert np.array_equal(within(np.sort(v), v, r), brute.astype(float))
