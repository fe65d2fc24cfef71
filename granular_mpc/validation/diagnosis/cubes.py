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
    """(C, B) phase-bin means of ``values`` over one window (NaN where empty)."""
    b = np.clip(np.searchsorted(edges, w.phase, side="right") - 1, 0, len(edges) - 2)
    out = np.full((len(channels), len(edges) - 1), np.nan)
    for c, ch in enumerate(channels):
        v = np.asarray(values[ch], dtype=float)
        for k in range(len(edges) - 1):
            m = (b == k) & np.isfinite(v)
            if m.any():
                out[c, k] = v[m].mean()
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
