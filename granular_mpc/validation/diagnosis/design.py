"""The weighted regression rows: residual cubes and sensitivity columns stacked into a
design (``docs/validation.md`` §3.2).

Two row sets: *systematic* rows (per trial and stance side, the mean over its stances,
weight √n_g / σ_c) and *stance* rows (every stance, weight 1 / σ_c); the touchdown-height
rows of the geometric equation are appended to both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from ..prepare import StanceWindow
from .cubes import group_keys


@dataclass(frozen=True)
class GeometryRows:
    """The geometric equation: touchdown heights vs. the surface (one free height per trial).

    Attributes:
        y: touchdown height minus its trial mean, per window [m], (W,).
        sigma: robust scatter of the heights after a plane fit [m].
        sens: per geometry column key, the predicted change of ``y`` per unit parameter.
    """

    y: np.ndarray
    sigma: float
    sens: Mapping[str, np.ndarray]

    def shifted(self, values: Mapping[str, float], neutral: Mapping[str, float]) -> "GeometryRows":
        """The rows at other parameter values: ``y − Σ sens_k (values_k − neutral_k)`` over
        the keys of ``values`` that have a geometry column (linear in them)."""
        gy = self.y.copy()
        for k, v in values.items():
            if k in self.sens:
                gy = gy - self.sens[k] * (v - neutral[k])
        return replace(self, y=gy)


@dataclass(frozen=True)
class Design:
    """Stacked weighted regression problem (replay rows, then geometry rows).

    Attributes:
        y: weighted residual, (N,).
        X: column key → weighted column, (N,) each.
        groups: trial of each row (the cross-validation groups).
        window: window index of each row (−1: none).
        channel: channel name of each row (``"touchdown_z"`` for geometry).
        phase_bin: phase bin of each row (−1 for geometry rows).
        sigma: channel → weight scale (channel units).
        n_eff_factor: N_eff / N.
    """

    y: np.ndarray
    X: Mapping[str, np.ndarray]
    groups: np.ndarray
    window: np.ndarray
    channel: np.ndarray
    phase_bin: np.ndarray
    sigma: Mapping[str, float]
    n_eff_factor: float


def lag1_factor(Z: np.ndarray) -> float:
    """N_eff / N from the lag-1 autocorrelation along the phase bins of Z (rows, C, B)."""
    Zc = Z - np.nanmean(Z, axis=(0, 2), keepdims=True)
    a, b = Zc[:, :, 1:], Zc[:, :, :-1]
    m = np.isfinite(a) & np.isfinite(b)
    den = float(np.nansum(Zc ** 2))
    rho = float(np.sum(a[m] * b[m]) / den) if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.95)
    return (1.0 - rho) / (1.0 + rho)


def build_design(level: str, windows: Sequence[StanceWindow], R: np.ndarray,
                 sens: Mapping[str, np.ndarray], channels: Sequence[str],
                 sigma: Mapping[str, float], geo: GeometryRows) -> Design:
    """Weighted rows for the regression.

    ``level="stance"``: one row per stance × channel × phase bin (weight 1/σ_c).
    ``level="group"``: one row per (trial, side) group × channel × bin, the mean over the
    group's stances (weight √n_g/σ_c) — the *systematic* structure: random replay drift
    (noisy initial states) averages out, so a term that only damps that drift gains
    nothing here. Geometry rows (touchdown heights) are appended in both.

    Args:
        R: residual cube (W, C, B); sens: column key → sensitivity cube (W, C, B).
        sigma: channel → stance-to-stance scatter (channel units).
    """
    W, C, B = R.shape
    trials = np.array([w.trial for w in windows])
    sig = np.array([sigma[ch] for ch in channels])
    if level == "stance":
        Rg = R
        cubes = dict(sens)
        scale = np.ones(W)
        gtrial = trials
        gwin = np.arange(W)
    else:
        gk = group_keys(windows)
        keys = np.unique(gk)
        Rg = np.stack([np.nanmean(R[gk == k], axis=0) for k in keys])
        cubes = {c: np.stack([np.nanmean(S[gk == k], axis=0) for k in keys]) for c, S in sens.items()}
        scale = np.array([math.sqrt((gk == k).sum()) for k in keys])
        gtrial = np.array([k.split("|")[0] for k in keys])
        gwin = np.full(len(keys), -1)
    G = Rg.shape[0]
    w_idx = np.repeat(np.arange(G), C * B)
    ch_idx = np.tile(np.repeat(np.arange(C), B), G)
    b_idx = np.tile(np.arange(B), G * C)
    wvec = scale[w_idx] / sig[ch_idx]
    y = np.concatenate([Rg.ravel() * wvec, geo.y / geo.sigma])
    X = {}
    for k, S in cubes.items():
        g = geo.sens.get(k, np.zeros(W))
        X[k] = np.concatenate([S.ravel() * wvec, g / geo.sigma])
    groups = np.concatenate([gtrial[w_idx], trials])
    Z = Rg * scale[:, None, None] / sig[None, :, None]
    return Design(y, X, groups, np.concatenate([gwin[w_idx], np.arange(W)]),
                  np.concatenate([np.array(channels)[ch_idx], np.full(W, "touchdown_z")]),
                  np.concatenate([b_idx, np.full(W, -1)]), dict(sigma) | {"touchdown_z": geo.sigma},
                  lag1_factor(Z))


__all__ = ["GeometryRows", "Design", "build_design", "lag1_factor"]
