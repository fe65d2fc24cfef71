"""Assessability by identifiability (``validation.diagnosis.identifiability``): what of a
candidate's signature on the measured channels no other candidate and no nuisance column
explains."""
from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.validation.diagnosis.identifiability import (Identifiability, Signature,
                                                               confused_pairs,
                                                               identifiability,
                                                               residual_size)


def _sig(*cols, rows=None):
    cells = np.array(cols, dtype=float).T
    r = np.zeros((0, cells.shape[1])) if rows is None else np.array(rows, float).T
    return Signature(cells, r)


def test_collinear_signatures_are_both_indistinguishable_and_an_orthogonal_one_is_not():
    a = [0.0, 1.5, 0.5, 0.0, 0.0]
    b = [0.0, 3.0, 1.0, 0.0, 0.0]                     # 2 × a: collinear
    c = [0.0, 0.0, 0.0, 2.0, -1.0]                    # orthogonal to both
    out = identifiability({"A": _sig(a), "B": _sig(b), "C": _sig(c)})
    assert out["A"].absorbed_by == ("B",) and out["B"].absorbed_by == ("A",)
    assert not out["A"].identifiable and not out["B"].identifiable
    assert out["A"].given["B"] == pytest.approx(0.0, abs=1e-12)
    assert out["C"].identifiable and out["C"].absorbed_by == ()
    assert out["C"].size == pytest.approx(2.0)
    assert out["C"].given["A"] == pytest.approx(2.0) == out["C"].given["B"]
    assert confused_pairs(out) == (("A", "B"), ("B", "A"))


def test_a_small_signature_inside_a_large_one_is_absorbed_one_way():
    """B = A + a large part of its own: B explains A (A cannot be assessed), A leaves B's
    own part (B can)."""
    a = [1.2, 0.4, 0.0]
    b = [3.0, 1.0, 2.0]                                # 2.5 × a + (0, 0, 2)
    out = identifiability({"A": _sig(a), "B": _sig(b)})
    assert out["A"].absorbed_by == ("B",)
    assert out["A"].given["B"] == pytest.approx(0.5714, abs=1e-4)     # (0.34, 0.11, −0.57)
    assert out["B"].identifiable and out["B"].given["A"] == pytest.approx(2.0)


def test_the_nuisance_is_always_fitted_and_among_limits_the_competitors():
    a = [1.5, 1.5, 0.0]
    nuis = [1.0, 1.0, 0.0]                             # the nuisance explains A entirely
    out = identifiability({"A": _sig(a), "B": _sig([0.0, 0.0, 4.0])}, _sig(nuis))
    assert out["A"].size == pytest.approx(0.0, abs=1e-12) and not out["A"].identifiable
    assert out["A"].absorbed_by == ("B",)             # B + nuisance explain it as well
    only = identifiability({"A": _sig(a), "B": _sig([0.0, 0.0, 4.0])}, among=["A"])
    assert only["A"].given == {} and only["A"].identifiable
    assert only["B"].given == {"A": pytest.approx(4.0)}


def test_weights_and_touchdown_rows():
    """The fit is weighted; the touchdown block counts with its RMS."""
    assert residual_size(np.array([[2.0], [0.0]]), np.zeros((2, 0)), 2) == 2.0
    # basis (1, 1) fitted to (2, 0): unweighted leaves ±1; weight 3:1 leaves 0.2, 1.8
    tgt, basis = np.array([[2.0], [0.0]]), np.array([[1.0], [1.0]])
    assert residual_size(tgt, basis, 2) == pytest.approx(1.0)
    assert residual_size(tgt, basis, 2, np.array([3.0, 1.0])) == pytest.approx(1.8)
    rows = _sig([0.0, 0.0], rows=[[0.0, 3.0, 4.0, 0.0]])   # RMS over 4 rows: 2.5
    out = identifiability({"A": rows})
    assert out["A"].size == pytest.approx(2.5) and out["A"].identifiable
    assert Identifiability("X", 0.5, {}).identifiable is False
