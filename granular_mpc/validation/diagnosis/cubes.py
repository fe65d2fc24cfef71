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

    For a window whose phases are in order, bit-identical to
    ``v[(bin == k) & isfinite(v)].mean()`` per channel and bin: each bin's sum is one
    pairwise ``np.add.reduce`` over a contiguous run, for every channel without non-finite
    values at once. A window out of phase order is first put in bin order (stable, so a
    bin keeps its samples' order); that reordered copy is Fortran-ordered, so its sums are
    not pairwise and can differ from ``mean()`` in the last bits (kept: changing them
    would change every diagnosis that meets such a window).
    """
    B = len(edges) - 1
    out = np.full((len(channels), B), np.nan)
    if not len(channels):
        return out
    V = np.array([np.asarray(values[ch], dtype=float) for ch in channels], dtype=float)
    order, bounds = _bin_order(w, edges)
    if order is not None:
        V = V[:, order]
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


def _bin_order(w: StanceWindow, edges: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """(stable order that sorts the window's samples by phase bin, or None when they are
    already in bin order; the B + 1 run bounds of the bins in that order)."""
    B = len(edges) - 1
    phase = np.asarray(w.phase)
    if phase.size < 2 or (phase[1:] >= phase[:-1]).all():
        # phases in order (and none NaN): bin k ≥ 1 starts at the first phase ≥ edges[k]
        bounds = np.empty(B + 1, dtype=np.intp)
        bounds[0], bounds[B] = 0, phase.size
        bounds[1:B] = np.searchsorted(phase, edges[1:B], side="left")
        return None, bounds
    b = np.clip(np.searchsorted(edges, phase, side="right") - 1, 0, B - 1)
    order = None
    if np.any(b[1:] < b[:-1]):
        order = np.argsort(b, kind="stable")
        b = b[order]
    return order, np.searchsorted(b, np.arange(B + 1), side="left")


def cube(windows: Sequence[StanceWindow], values: Sequence[Mapping[str, np.ndarray]],
         channels: Sequence[str], edges: np.ndarray) -> np.ndarray:
    """(W, C, B) phase-bin means of ``values[i]`` over window ``i``: :func:`bin_means` of
    every window, bit for bit, in a handful of reductions.

    The windows in phase order whose channels are all finite are laid side by side; their
    (window, bin) runs of equal length L are gathered into one (C, runs, L) array and
    summed along L by one pairwise ``np.add.reduce`` (the same summation, run by run, as
    :func:`bin_means` makes). Windows with a non-finite sample or out of phase order go
    through :func:`bin_means`.
    """
    W, C, B = len(windows), len(channels), len(edges) - 1
    out = np.full((W, C, B), np.nan)
    if not C or not W:
        return out
    blocks, starts, lengths, wi, ki = [], [], [], [], []
    offset = 0
    for i, w in enumerate(windows):
        V = np.array([np.asarray(values[i][ch], dtype=float) for ch in channels], dtype=float)
        order, bounds = _bin_order(w, edges)
        if order is not None or not np.isfinite(V).all():
            # (out of phase order: bin_means sums a reordered copy in its own way)
            out[i] = bin_means(w, values[i], channels, edges)
            continue
        blocks.append(V)
        n = bounds[1:] - bounds[:-1]
        ks = np.flatnonzero(n)
        starts.append(offset + bounds[ks])
        lengths.append(n[ks])
        wi.append(np.full(ks.size, i))
        ki.append(ks)
        offset += V.shape[1]
    if not blocks:
        return out
    big = np.concatenate(blocks, axis=1)
    starts, lengths = np.concatenate(starts), np.concatenate(lengths)
    wi, ki = np.concatenate(wi), np.concatenate(ki)
    for L in np.unique(lengths):
        sel = lengths == L
        idx = starts[sel][:, None] + np.arange(L)
        runs = np.ascontiguousarray(big[:, idx])    # (C, runs, L), L innermost: pairwise
        sums = np.add.reduce(runs, axis=2) / int(L)
        out[wi[sel], :, ki[sel]] = sums.T
    return out


def residual_cube(windows: Sequence[StanceWindow], preds: Sequence[Mapping[str, np.ndarray]],
                  channels: Sequence[str], edges: np.ndarray) -> np.ndarray:
    """(W, C, B) binned residual measured − predicted."""
    diffs = [{c: w.meas[c] - np.asarray(preds[i][c], dtype=float) for c in channels}
             for i, w in enumerate(windows)]
    return cube(windows, diffs, channels, edges)


def pred_cube(windows: Sequence[StanceWindow], preds: Sequence[Mapping[str, np.ndarray]],
              channels: Sequence[str], edges: np.ndarray) -> np.ndarray:
    """(W, C, B) binned predictions."""
    return cube(windows, preds, channels, edges)


def group_keys(windows: Sequence[StanceWindow]) -> np.ndarray:
    """Stance groups of the systematic-structure rows: ``"<trial>|<side>"`` per window."""
    return np.array([f"{w.trial}|{w.side}" for w in windows])


__all__ = ["bin_means", "cube", "residual_cube", "pred_cube", "group_keys"]
