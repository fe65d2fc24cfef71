"""Sparse regression for proposed terms: sequentially thresholded least squares (STLSQ)
with unpenalised nuisance columns, the threshold chosen by trial-grouped cross-validation,
and stability selection over resampled stances (``docs/validation.md`` §3.6).

STLSQ (the SINDy algorithm: least squares, zero the coefficients below a threshold,
refit on the rest, repeat) is written here rather than taken from PySINDy because the
problem is not x' = f(x): the target is a force residual, the calibration's ζ column must
stay in every model unpenalised, and the folds must hold out whole trials — none of which
PySINDy's optimisers and ``SINDy.fit`` express without working around them. Features are
standardised (unit RMS) so one threshold serves all of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .bounded_lsq import lstsq_solution, one_blas_thread

#: thresholds tried (standardised coefficient, in units of the target's RMS)
THRESHOLDS = np.geomspace(0.01, 1.0, 21)
#: a sparser model is preferred while its CV error is within this factor of the best
CV_TOLERANCE = 1.02
#: stability selection: resamples, and the share of them a feature must be selected in
N_STABILITY = 100
MIN_FREQUENCY = 0.7
#: a feature whose part not explained by the nuisance and the features before it is
#: less than this share of its norm (standardised) is a near-duplicate and left out of
#: the fit on those rows. Its own part then lives on a handful of samples (|v_h| and v_h
#: on sinking samples where the sole almost never slides back: 0.0–0.5 % on the hard-layer
#: data of bench/out_of_library.py), and a fit that uses it puts coefficients of ±10⁴ on
#: the pair and predicts a held-out trial 10⁴ times worse than no feature at all. The
#: features a proposal is made of kept ≥ 2.1 % on every fold of four benchmark data sets
#: (vertical damping, quadratic drag, sole Coulomb, hard layer; session 28); 1 % lies
#: between. Checked on each fold's training rows too (:func:`cv_sse_path`).
MIN_INDEPENDENT_SHARE = 0.01


@dataclass(frozen=True, eq=False)
class Factored:
    """One least-squares system y ≈ [N, X] β, QR-factored once: [N, X] = Q R, z = Qᵀ y.

    For any subset S of the columns, ‖y − [N, X]_S β‖² = ‖z − R_S β‖² + ‖(I − QQᵀ) y‖²,
    so the least squares on S is the small (≤ K + F rows) problem on R_S and z: the
    refits of STLSQ and of every threshold on the same rows share one factorisation.

    Attributes:
        R: (min(n, K + F), K + F) triangular factor; z: Qᵀ y (its first rows).
        n: rows of the system; K: nuisance columns (first in R); F: features.
    """

    R: np.ndarray
    z: np.ndarray
    n: int
    K: int
    F: int
    #: column set → solution: the thresholds of :func:`cv_sse_path` on one fold start from
    #: the same column sets (every feature active, then the same prunings)
    _solved: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def of(cls, X: np.ndarray, N: np.ndarray, y: np.ndarray) -> "Factored":
        """Factor [N, X] (rows n) and project y: the triangular factor of [N, X, y]
        holds R and z (Q is never formed)."""
        p = N.shape[1] + X.shape[1]
        with one_blas_thread():
            Ra = np.linalg.qr(np.hstack([N, X, np.reshape(y, (-1, 1))]), mode="r")
        return cls(Ra[:p, :p], Ra[:p, p], int(y.size), int(N.shape[1]), int(X.shape[1]))

    def solve(self, cols: np.ndarray) -> np.ndarray:
        """Minimum-norm least squares on the columns ``cols`` (indices into [N, X]), with
        the singular-value cutoff ``np.linalg.lstsq(..., rcond=None)`` would use on the
        full rows (ε · max(n, |cols|))."""
        if not cols.size:
            return np.zeros(0)
        key = cols.tobytes()
        sol = self._solved.get(key)
        if sol is None:
            rcond = np.finfo(float).eps * max(self.n, cols.size)
            sol = self._solved[key] = lstsq_solution(self.R[:, cols], self.z, rcond)
        return sol.copy()


def stlsq_factored(fac: Factored, threshold: float,
                   iterations: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """:func:`stlsq` on a factored system (same iterations, same selection)."""
    F, K = fac.F, fac.K
    active = np.ones(F, bool)
    xi = np.zeros(F)
    nu = np.zeros(K)
    for _ in range(iterations):
        sol = fac.solve(np.concatenate([np.arange(K), K + np.flatnonzero(active)]))
        nu = sol[:K]
        xi = np.zeros(F)
        xi[active] = sol[K:]
        keep = active & (np.abs(xi) >= threshold)
        if keep.sum() == active.sum():
            break
        active = keep
        xi[~active] = 0.0
    return xi, nu


def stlsq(X: np.ndarray, N: np.ndarray, y: np.ndarray, threshold: float,
          iterations: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """STLSQ of y on [N, X] with N unpenalised.

    Each refit is the least squares on the kept columns (minimum norm where they are
    dependent), solved on one QR factorisation of [N, X] (:class:`Factored`).

    Args:
        X: (n, F) standardised features; N: (n, K) nuisance columns; y: (n,) target.
        threshold: |coefficient| below which a feature is dropped.

    Returns:
        (ξ (F,), ν (K,)): feature and nuisance coefficients.
    """
    return stlsq_factored(Factored.of(X, N, y), threshold, iterations)


def folds(groups: np.ndarray, n_splits: int = 5) -> list[tuple[np.ndarray, np.ndarray]]:
    """Grouped K-fold (whole groups held out; at most ``n_splits`` folds)."""
    from sklearn.model_selection import GroupKFold

    k = min(n_splits, int(np.unique(groups).size))
    if k < 2:
        return []
    return list(GroupKFold(n_splits=k).split(np.zeros(groups.size), groups=groups))


def cv_sse_path(X: np.ndarray, N: np.ndarray, y: np.ndarray, splits,
                thresholds) -> np.ndarray:
    """:func:`cv_sse` at every threshold of ``thresholds`` (one factorisation per fold).
    A feature that is a near-duplicate on a fold's training rows (:func:`independent`) is
    left out of that fold's fit."""
    sse = np.zeros(len(thresholds))
    for tr, te in splits:
        keep = independent(X[tr], N[tr])
        fac = Factored.of(np.where(keep, X[tr], 0.0), N[tr], y[tr])
        for i, t in enumerate(thresholds):
            xi, nu = stlsq_factored(fac, t)
            sse[i] += float(np.sum((y[te] - N[te] @ nu - X[te] @ xi) ** 2))
    return sse


def cv_sse(X: np.ndarray, N: np.ndarray, y: np.ndarray, splits, threshold: float) -> float:
    """Held-out SSE of STLSQ at ``threshold`` over ``splits`` (selection inside each fold)."""
    return float(cv_sse_path(X, N, y, splits, [threshold])[0])


@dataclass(frozen=True, eq=False)
class SparseFit:
    """A sparse fit of one target.

    Attributes:
        coef: (F,) coefficients in the features' own units (0: not selected).
        frequency: (F,) share of the stability resamples that selected each feature.
        selected: (F,) bool: selected (frequency ≥ :data:`MIN_FREQUENCY`).
        threshold: the chosen standardised threshold.
        heldout_reduction: 1 − SSE_CV(nuisance + STLSQ) / SSE_CV(nuisance), the selection
            redone inside each fold (whole groups held out).
        heldout_reduction_selected: the same for a plain refit on the stable features.
        rmse_before, rmse_after: in-sample RMS of the target after the nuisance fit, and
            with the stable features too (target units).
        stderr: (F,) standard errors of ``coef`` (OLS on the stable features; NaN else).
    """

    coef: np.ndarray
    frequency: np.ndarray
    selected: np.ndarray
    threshold: float
    heldout_reduction: float
    heldout_reduction_selected: float
    rmse_before: float
    rmse_after: float
    stderr: np.ndarray


def independent(X: np.ndarray, N: np.ndarray,
                tol: float = MIN_INDEPENDENT_SHARE) -> np.ndarray:
    """(F,) bool: the features, in order, that are not (nearly) in the span of the
    nuisance columns and the features kept before them: the part of each outside that
    span must be ≥ ``tol`` of its norm (on sinking samples |v_h| = v_h and sign(v_h) = 1
    but for the few samples where the sole slides back: such duplicates would share one
    coefficient between them, fitted to those samples; :data:`MIN_INDEPENDENT_SHARE`)."""
    keep = np.zeros(X.shape[1], bool)
    for k in range(X.shape[1]):
        A = np.hstack([N, X[:, keep]])
        x = X[:, k]
        r = x - A @ np.linalg.lstsq(A, x, rcond=None)[0] if A.shape[1] else x
        keep[k] = float(np.linalg.norm(r)) > tol * max(float(np.linalg.norm(x)), 1e-300)
    return keep


def _ols_cv(A: np.ndarray, y: np.ndarray, splits, n_nuisance: int | None = None) -> float:
    """Held-out SSE of least squares on the columns of ``A`` over ``splits``; with
    ``n_nuisance``, the columns after the first ``n_nuisance`` that are near-duplicates on
    a fold's training rows (:func:`independent`) are left out of that fold's fit."""
    sse = 0.0
    for tr, te in splits:
        cols = A
        if n_nuisance is not None and A.shape[1] > n_nuisance:
            keep = np.concatenate([np.ones(n_nuisance, bool),
                                   independent(A[tr, n_nuisance:], A[tr, :n_nuisance])])
            cols = A[:, keep]
        b = np.linalg.lstsq(cols[tr], y[tr], rcond=None)[0] if cols.shape[1] else np.zeros(0)
        sse += float(np.sum((y[te] - cols[te] @ b) ** 2))
    return sse


def sparse_fit(Phi: np.ndarray, N: np.ndarray, y: np.ndarray, groups: np.ndarray,
               units: np.ndarray, *, seed: int = 0) -> SparseFit:
    """STLSQ with CV-chosen threshold and stability selection.

    Args:
        Phi: (n, F) features (own units); N: (n, K) nuisance columns (unpenalised).
        y: (n,) target; groups: CV groups (trials); units: resampling units (stances).
        seed: seed of the stability resamples.
    """
    F = Phi.shape[1]
    scale = np.sqrt(np.mean(Phi ** 2, axis=0))
    scale[scale == 0] = 1.0
    ys = float(np.sqrt(np.mean(y ** 2))) or 1.0
    Nn = N / np.where(np.sqrt(np.mean(N ** 2, axis=0)) > 0, np.sqrt(np.mean(N ** 2, axis=0)), 1.0)
    usable = independent(Phi / scale, Nn)
    X, yy = np.where(usable, Phi / scale, 0.0), y / ys
    splits = folds(groups)
    if not splits:
        splits = folds(units)
    base = _ols_cv(Nn, yy, splits)
    errs = cv_sse_path(X, Nn, yy, splits, THRESHOLDS)
    ok = np.flatnonzero(errs <= CV_TOLERANCE * errs.min())
    thr = float(THRESHOLDS[ok.max()])
    rng = np.random.default_rng(seed)
    uniq = np.unique(units)
    members = {u: np.flatnonzero(units == u) for u in uniq}
    count = np.zeros(F)
    for _ in range(N_STABILITY):
        pick = rng.choice(uniq, uniq.size, replace=True)
        ii = np.concatenate([members[u] for u in pick])
        xi, _ = stlsq(X[ii], Nn[ii], yy[ii], thr)
        count += xi != 0
    freq = np.where(usable, count / N_STABILITY, 0.0)
    sel = usable & (freq >= MIN_FREQUENCY)
    A = np.hstack([Nn, X[:, sel]])
    b = np.linalg.lstsq(A, yy, rcond=None)[0]
    r_after = yy - A @ b
    r_before = yy - Nn @ np.linalg.lstsq(Nn, yy, rcond=None)[0]
    coef = np.zeros(F)
    coef[sel] = b[Nn.shape[1]:] * ys / scale[sel]
    dof = max(yy.size - A.shape[1], 1)
    s2 = float(r_after @ r_after) / dof
    se = np.full(F, np.nan)
    try:
        cov = np.linalg.inv(A.T @ A) * s2
        se[sel] = np.sqrt(np.abs(np.diag(cov)[Nn.shape[1]:])) * ys / scale[sel]
    except np.linalg.LinAlgError:
        pass
    cv_stl = float(errs[ok.max()])
    cv_sel = _ols_cv(A, yy, splits, Nn.shape[1])
    red = 1.0 - cv_stl / base if base > 0 else 0.0
    red_sel = 1.0 - cv_sel / base if base > 0 else 0.0
    return SparseFit(coef, freq, sel, thr, red, red_sel,
                     float(np.sqrt(np.mean(r_before ** 2))) * ys,
                     float(np.sqrt(np.mean(r_after ** 2))) * ys, se)


__all__ = ["stlsq", "stlsq_factored", "Factored", "sparse_fit", "SparseFit", "folds",
           "cv_sse", "cv_sse_path", "THRESHOLDS",
           "MIN_FREQUENCY", "N_STABILITY", "MIN_INDEPENDENT_SHARE", "independent"]
