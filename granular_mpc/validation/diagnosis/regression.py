"""Bounded least squares on a :class:`~.design.Design` with trial-grouped cross-validation,
AICc, covariance and forward selection (``docs/validation.md`` §3.3)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np
from scipy.optimize import lsq_linear
from sklearn.model_selection import GroupKFold

from ..prepare import StanceWindow
from .bounded_lsq import ReducedSystem
from .design import Design, GeometryRows, build_design
from .thresholds import MAX_DELTA_AICC


def fit_bounded(X: np.ndarray, y: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """β minimising ‖y − Xβ‖² within lb ≤ β ≤ ub (BVLS on column-normalised X).

    The reference solver (``scipy.optimize.lsq_linear``) on the full rows; the screening's
    many fits on the same rows use :class:`~.bounded_lsq.ReducedSystem` instead
    (:meth:`Regression.fit`, :meth:`Regression.cv`; the same solution)."""
    if X.shape[1] == 0:
        return np.zeros(0)
    scale = np.sqrt((X ** 2).sum(axis=0))
    scale[scale == 0] = 1.0
    res = lsq_linear(X / scale, y, bounds=(lb * scale, ub * scale), method="bvls")
    return res.x / scale


def aicc(rss: float, n: float, k: int) -> float:
    """AICc = n ln(RSS/n) + 2k + 2k(k+1)/(n−k−1) (n at least k + 2)."""
    n = max(n, k + 2.0)
    return n * math.log(max(rss, 1e-300) / n) + 2 * k + 2 * k * (k + 1) / (n - k - 1)


@dataclass(frozen=True)
class Rows:
    """The finite rows of a design: mask ``ok`` over the design's rows, the residual
    ``y``, the columns ``cols`` and the groups on those rows."""

    ok: np.ndarray
    y: np.ndarray
    cols: Mapping[str, np.ndarray]
    groups: np.ndarray

    @classmethod
    def of(cls, design: Design) -> "Rows":
        ok = np.isfinite(design.y)
        for v in design.X.values():
            ok &= np.isfinite(v)
        return cls(ok, design.y[ok], {k: v[ok] for k, v in design.X.items()}, design.groups[ok])


@dataclass(frozen=True)
class CVScore:
    """Held-out SSE of the fitted rows (total and per fold) and of the held-out trials'
    stance rows under the same fits (NaN without stance rows)."""

    sse: float
    folds: tuple[float, ...]
    sse_stance: float


class Regression:
    """Bounded least squares on a :class:`Design` with CV, AICc and bootstrap tools.

    ``design`` holds the rows that are fitted (the systematic, stance-averaged rows);
    ``stance_design`` (optional) holds the stance-by-stance rows on which the same fit is
    also scored. Cross-validation folds are whole groups (trials) shared by both.
    """

    def __init__(self, design: Design, bounds: Mapping[str, tuple[float, float]],
                 nuisance: Sequence[str], *, stance_design: Design | None = None,
                 n_splits: int = 5, seed: int = 0) -> None:
        self.design = design
        self.bounds = dict(bounds)
        self.nuisance = list(nuisance)
        rows = Rows.of(design)
        self.ok, self.y, self.cols, self.groups = rows.ok, rows.y, rows.cols, rows.groups
        ug = np.unique(self.groups)
        self.splits: list[tuple[np.ndarray, np.ndarray]] = []
        self.stance_splits: list[np.ndarray] = []
        self.stance: Rows | None = None
        if stance_design is not None:
            self.stance = Rows.of(stance_design)
            self.stance_channel = stance_design.channel[self.stance.ok]
            self.stance_bin = stance_design.phase_bin[self.stance.ok]
        if ug.size >= 2:
            gkf = GroupKFold(n_splits=min(n_splits, ug.size))
            for _, te_g in gkf.split(ug, groups=ug):
                test = ug[te_g]
                te = np.isin(self.groups, test)
                self.splits.append((np.flatnonzero(~te), np.flatnonzero(te)))
                if self.stance is not None:
                    ste = np.isin(self.stance.groups, test)
                    self.stance_splits.append(np.flatnonzero(ste))
        self.seed = seed
        # every column's index in one (n, P) matrix, and the reduced systems of the row
        # sets fitted repeatedly (all rows, each CV fold, the current bootstrap resample)
        self.column_index = {k: i for i, k in enumerate(self.cols)}
        self._all = (np.column_stack(list(self.cols.values())) if self.cols
                     else np.zeros((self.y.size, 0)))
        self._reduced: dict = {}
        self._resample: tuple = (None, None)

    def reduced(self, rows=None, *, fold: int | None = None) -> ReducedSystem:
        """The QR-reduced system (:class:`~.bounded_lsq.ReducedSystem`) of every column on
        ``rows`` (default: all fitted rows; ``fold``: the training rows of that CV fold),
        cached for all rows, the folds and the last resample (the same ``rows`` object):
        the bootstrap's forward selection and refits, and every candidate's CV, share one
        factorisation per set of rows."""
        if fold is not None:
            if fold not in self._reduced:
                tr = self.splits[fold][0]
                self._reduced[fold] = ReducedSystem.of(self._all[tr], self.y[tr])
            return self._reduced[fold]
        if rows is None:
            if "all" not in self._reduced:
                self._reduced["all"] = ReducedSystem.of(self._all, self.y)
            return self._reduced["all"]
        if self._resample[0] is not rows:
            self._resample = (rows, ReducedSystem.of(self._all[rows], self.y[rows]))
        return self._resample[1]

    def _bounded(self, keys: Sequence[str], system: ReducedSystem) -> tuple[np.ndarray, float]:
        """(β, RSS) of the bounded fit of ``keys`` on a reduced system."""
        cols = np.array([self.column_index[k] for k in keys], dtype=int)
        lb = np.array([self.bounds[k][0] for k in keys], dtype=float)
        ub = np.array([self.bounds[k][1] for k in keys], dtype=float)
        return system.fit(cols, lb, ub)

    def matrix(self, keys: Sequence[str], rows=None, cols=None):
        """(X, lower, upper) of the columns ``keys`` on ``rows`` (default: all) of ``cols``
        (default: the fitted rows' columns)."""
        cols = self.cols if cols is None else cols
        n = next(iter(cols.values())).size if cols else 0
        if not keys:
            return np.zeros((n if rows is None else len(rows), 0)), np.zeros(0), np.zeros(0)
        X = np.column_stack([cols[k] for k in keys])
        lb = np.array([self.bounds[k][0] for k in keys])
        ub = np.array([self.bounds[k][1] for k in keys])
        return (X if rows is None else X[rows]), lb, ub

    def fit(self, keys: Sequence[str], rows=None) -> tuple[np.ndarray, float]:
        """(β, RSS) of the bounded fit of ``keys`` on ``rows``.

        On all rows (the estimates that start the replay refinement, whose replays turn
        even last-bit differences of a start into visible ones) the reference solver
        :func:`fit_bounded` on the full rows; on a resample of rows (the bootstrap) the
        same fit on the resample's reduced system (:meth:`reduced`)."""
        if rows is None or not len(keys):
            X, lb, ub = self.matrix(keys, rows)
            y = self.y if rows is None else self.y[rows]
            beta = fit_bounded(X, y, lb, ub)
            r = y - X @ beta if len(keys) else y
            return beta, float(r @ r)
        return self._bounded(keys, self.reduced(rows))

    def cv(self, keys: Sequence[str]) -> CVScore:
        """Held-out SSE of the fitted rows (total and per fold) and, with a stance design,
        of the stance rows of the held-out trials under the same fit (each fold's fit on
        its training rows' reduced system, :meth:`reduced`)."""
        per, per_st = [], []
        X, _, _ = self.matrix(keys)
        if self.stance is not None:
            Xs, _, _ = self.matrix(keys, cols=self.stance.cols)
        for k, (tr, te) in enumerate(self.splits):
            beta = self._bounded(keys, self.reduced(fold=k))[0] if len(keys) else np.zeros(0)
            r = self.y[te] - X[te] @ beta if len(keys) else self.y[te]
            per.append(float(r @ r))
            if self.stance is not None:
                ste = self.stance_splits[k]
                ys = self.stance.y[ste]
                rs = ys - Xs[ste] @ beta if len(keys) else ys
                per_st.append(float(rs @ rs))
        return CVScore(float(sum(per)), tuple(per),
                       float(sum(per_st)) if per_st else float("nan"))

    def practical_size(self, keys: Sequence[str], beta: np.ndarray) -> float:
        """Largest stance-averaged change of the prediction that ``beta`` on ``keys``
        makes in any channel × phase cell, in units of that channel's stance-to-stance
        scatter σ (geometry rows: RMS over the touchdowns)."""
        if self.stance is None or not len(keys):
            return float("nan")
        X, _, _ = self.matrix(keys, cols=self.stance.cols)
        v = X @ beta
        out = 0.0
        for ch in np.unique(self.stance_channel):
            m = self.stance_channel == ch
            if ch == "touchdown_z":
                out = max(out, float(np.sqrt(np.mean(v[m] ** 2))))
                continue
            bins = self.stance_bin[m]
            for b in np.unique(bins):
                out = max(out, abs(float(v[m][bins == b].mean())))
        return out

    def n_eff(self, rows=None) -> float:
        """Effective number of the fitted rows (autocorrelation-corrected)."""
        n = self.y.size if rows is None else len(rows)
        return n * self.design.n_eff_factor

    def aicc(self, keys: Sequence[str], rows=None) -> float:
        """AICc of the fit of ``keys`` on ``rows``."""
        _, rss = self.fit(keys, rows)
        return aicc(rss, self.n_eff(rows), len(keys))

    def covariance(self, keys: Sequence[str], beta: np.ndarray) -> np.ndarray:
        """s² (XᵀX)⁻¹ with s² inflated by N / N_eff (NaN where singular)."""
        X, _, _ = self.matrix(keys)
        r = self.y - X @ beta
        dof = max(self.y.size - len(keys), 1)
        s2 = float(r @ r) / dof / max(self.design.n_eff_factor, 1e-3)
        try:
            return np.linalg.inv(X.T @ X) * s2
        except np.linalg.LinAlgError:
            return np.full((len(keys), len(keys)), np.nan)


def forward_selection(reg: Regression, cand_keys: Mapping[str, list[str]], base_keys: list[str],
                      rows=None, max_terms: int = 3) -> list[str]:
    """Forward selection by AICc (entry: ΔAICc ≤ MAX_DELTA_AICC), on ``rows``."""
    chosen: list[str] = []
    keys = list(base_keys)
    cur = reg.aicc(keys, rows)
    for _ in range(max_terms):
        best, best_a = None, cur
        for name, cols in cand_keys.items():
            if name in chosen:
                continue
            a = reg.aicc(keys + cols, rows)
            if a - cur <= MAX_DELTA_AICC and a < best_a:
                best, best_a = name, a
        if best is None:
            break
        chosen.append(best)
        keys = keys + cand_keys[best]
        cur = best_a
    return chosen


@dataclass(frozen=True, eq=False)
class Regressions:
    """A regression on the systematic rows scored also on the stance rows, and both designs
    (with fewer than 3 trials both are the stance rows and stances are the CV units)."""

    regression: Regression
    systematic: Design
    stance: Design


@dataclass(frozen=True, eq=False)
class RegressionBuilder:
    """Builds :class:`Regressions` on one data set's windows, channels and scatter.

    Attributes:
        windows: the stance windows; channels: scored channels; sigma: channel → σ_c.
        group_unit: ``"trial"`` (≥ 3 trials: systematic rows, trial-grouped CV) or
            ``"stance"``.
        seed: the regressions' seed.
    """

    windows: Sequence[StanceWindow]
    channels: Sequence[str]
    sigma: Mapping[str, float]
    group_unit: str
    seed: int = 0

    def build(self, R: np.ndarray, sens: Mapping[str, np.ndarray], geo: GeometryRows,
              bounds: Mapping[str, tuple[float, float]], keys: Sequence[str]) -> Regressions:
        """Systematic rows (stance-averaged per trial and side) scored also stance by
        stance; with fewer than 3 trials, stances are the units (no averaging)."""
        d_s = build_design("stance", self.windows, R, sens, self.channels, self.sigma, geo)
        if self.group_unit == "stance":
            d_s = replace(d_s, groups=d_s.window.astype(str))
            return Regressions(Regression(d_s, bounds, keys, stance_design=d_s, seed=self.seed),
                               d_s, d_s)
        d_g = build_design("group", self.windows, R, sens, self.channels, self.sigma, geo)
        return Regressions(Regression(d_g, bounds, keys, stance_design=d_s, seed=self.seed),
                           d_g, d_s)


__all__ = ["Regression", "Regressions", "RegressionBuilder", "Rows", "CVScore", "fit_bounded",
           "aicc", "forward_selection"]
