"""Residual and prediction cubes: per stance window, channel and stance-phase bin.

A *cube* is a (W, C, B) array: W stance windows, C channels (format-v1 names, in
``channels`` order), B stance-phase bins (``edges`` [%], B + 1 values); each entry is the
mean of the window's samples in that bin (NaN where the bin is empty). Channel units.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..prepare import StanceWindow


def bin_means(w: StanceWindow, values: Mapping[str, np.ndarray], channels: Sequence[str],
              edges: np.ndarray) -> np.ndarray:
    """(C, B) phase-bin means of ``values`` over one window (NaN where empty).

    Bit-identical to ``v[(bin == k) & isfinite(v)].mean()`` per channel and bin: the
    samples are put in bin order (stable, so a bin keeps its samples' order) and each
    bin's sum is one pairwise ``np.add.reduce`` over a contiguous run, for every channel
    without non-finite values at once.
    """
    B = len(edges) - 1
    b = np.clip(np.searchsorted(edges, w.phase, side="right") - 1, 0, B - 1)
    out = np.full((len(channels), B), np.nan)
    if not len(channels):
        return out
    V = np.array([np.asarray(values[ch], dtype=float) for ch in channels], dtype=float)
    if b.size > 1 and np.any(b[1:] < b[:-1]):
        order = np.argsort(b, kind="stable")
        V, b = V[:, order], b[order]
    bounds = np.searchsorted(b, np.arange(B + 1), side="left")
    finite = np.isfinite(V)
    clean = finite.all(axis=1)
    if clean.all():
        for k in range(B):
            s, e = int(bounds[k]), int(bounds[k + 1])
            if e > s:
                out[:, k] = np.add.reduce(V[:, s:e], axis=1) / (e - s)
        return out
    rows = np.flatnonzero(clean)
    Vc = V[rows]
    for k in range(B):
        s, e = int(bounds[k]), int(bounds[k + 1])
        if e <= s:
            continue
        if rows.size:
            out[rows, k] = np.add.reduce(Vc[:, s:e], axis=1) / (e - s)
        for c in np.flatnonzero(~clean):
            seg = V[c, s:e][finite[c, s:e]]
            if seg.size:
                out[c, k] = np.add.reduce(seg) / seg.size
    return out


def residual_cube(windows: Sequence[StanceWindow], preds: Sequence[Mapping[str, np.ndarray]],
                  channels: Sequence[str], edges: np.ndarray) -> np.ndarray:
    """(W, C, B) binned residual measured − predicted."""
    out = np.empty((len(windows), len(channels), len(edges) - 1))
    for i, w in enumerate(windows):
        diff = {c: w.meas[c] - np.asarray(preds[i][c], dtype=float) for c in channels}
        out[i] = bin_means(w, diff, channels, edges)
    return out


def pred_cube(windows: Sequence[StanceWindow], preds: Sequence[Mapping[str, np.ndarray]],
              channels: Sequence[str], edges: np.ndarray) -> np.ndarray:
    """(W, C, B) binned predictions."""
    out = np.empty((len(windows), len(channels), len(edges) - 1))
    for i, w in enumerate(windows):
        out[i] = bin_means(w, preds[i], channels, edges)
    return out


def group_keys(windows: Sequence[StanceWindow]) -> np.ndarray:
    """Stance groups of the systematic-structure rows: ``"<trial>|<side>"`` per window."""
    return np.array([f"{w.trial}|{w.side}" for w in windows])


__all__ = ["bin_means", "residual_cube", "pred_cube", "group_keys"]
