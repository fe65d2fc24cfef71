"""Which candidate effects the measured channels can tell apart: assessability by
identifiability, not by size alone (``docs/import.md`` "Which effects can be assessed").

A candidate's **signature** is what its columns do, at the library's nominal magnitude
(the column's finite-difference step), to the stance-averaged prediction of every measured
channel × phase cell, in units of that channel's stance-to-stance scatter σ_c (the
quantity of the diagnosis's practical-size test), plus, where the trunk position was
measured, its touchdown-height rows (scaled so that their block counts with its RMS, as in
:func:`~.coverage.detectable_size`).

The regression fits the calibration's nuisance columns (ζ, the touchdown depth) on every
data set, and it adds one candidate at a time. So the part of a candidate's signature the
data can attribute to *it* is what remains after the least-squares projection onto

* the nuisance columns alone — its **identifiable size** (:attr:`Identifiability.size`);
* the nuisance columns and one other candidate B — its size **given B**.

With the size measured as the practical-size test measures it (the largest |cell|, or the
touchdown block's RMS), a candidate is **identifiable** when its identifiable size and its
size given every other assessable candidate are ≥ the threshold (1 σ,
``thresholds.MIN_EFFECT_SIZE``): otherwise B, or the nuisance, fits everything it does to
the measured channels within less than the practical size, and a fit of B on data made by
it cannot be told from B. Such a candidate is reported **indistinguishable with the
measured channels from B** and cannot be assessed; an addition of B is then *ambiguous*
(it may be the other one's doing) and the verdict says so instead of presenting B as the
answer (:mod:`.verdict`). The projection is onto one candidate at a time because the
diagnosis adds candidates one at a time and what it must not do is present one candidate
for another; the span of every other candidate together (≈ 15 columns in ≈ 60 cells)
explains most of any signature, also those the diagnosis does identify.

The functions here are pure array code (tested on constructed signatures,
``tests/test_identifiability.py``); :func:`~.coverage.assess_candidates` applies them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from .thresholds import MIN_EFFECT_SIZE


@dataclass(frozen=True)
class Signature:
    """A candidate's (or the nuisance's) signature columns.

    Attributes:
        cells: (N_cells, k) stance-mean change per column at its nominal step [σ_c] (NaN:
            empty cell).
        rows: (N_rows, k) touchdown-height change per column at its step [σ_geometry],
            (0, k) when the trunk position was not measured.
        weights: (N_cells,) weight of each cell in the least-squares fit (the regression's
            √n_group; None: 1).
    """

    cells: np.ndarray
    rows: np.ndarray
    weights: np.ndarray | None = None

    @property
    def k(self) -> int:
        """Number of columns."""
        return int(self.cells.shape[1])


@dataclass(frozen=True)
class Identifiability:
    """What of one candidate's signature the measured channels attribute to it.

    Attributes:
        name: the candidate.
        size: its identifiable size: the largest part of a column's signature not explained
            by the nuisance columns [σ].
        given: other candidate → its size given that candidate and the nuisance [σ].
        threshold: the practical size [σ].
    """

    name: str
    size: float
    given: Mapping[str, float]
    threshold: float = MIN_EFFECT_SIZE

    @property
    def absorbed_by(self) -> tuple[str, ...]:
        """The candidates that explain its signature within less than the threshold."""
        return tuple(sorted(b for b, v in self.given.items() if v < self.threshold))

    @property
    def identifiable(self) -> bool:
        """Its signature has a part ≥ the threshold nothing else explains."""
        return self.size >= self.threshold and not self.absorbed_by


def _stack(sig: Signature, mask: np.ndarray) -> np.ndarray:
    """One (N, k) matrix: the finite cells, then the touchdown rows / √N_rows."""
    rows = sig.rows
    scale = 1.0 / np.sqrt(max(rows.shape[0], 1))
    return np.vstack([np.nan_to_num(sig.cells[mask]), np.nan_to_num(rows) * scale])


def _fit_weights(sig: Signature, mask: np.ndarray) -> np.ndarray:
    """Weights of the stacked rows: the cells' (default 1), then the block's, chosen so
    that the touchdown block weighs as one cell of average weight."""
    w = np.ones(int(mask.sum())) if sig.weights is None else np.asarray(sig.weights)[mask]
    mean = float(w.mean()) if w.size else 1.0
    return np.concatenate([w, np.full(sig.rows.shape[0], mean)])


def _size(r: np.ndarray, n_cells: int) -> float:
    """The practical-size measure of a residual column: largest |cell|, or the RMS of the
    touchdown block (its norm, as stacked), whichever is larger."""
    cells = np.abs(r[:n_cells])
    block = float(np.linalg.norm(r[n_cells:])) if r.size > n_cells else 0.0
    return max(float(cells.max()) if cells.size else 0.0, block)


def residual_size(target: np.ndarray, basis: np.ndarray, n_cells: int,
                  weights: np.ndarray | None = None) -> float:
    """Largest practical size over ``target``'s columns of what the (weighted)
    least-squares fit on ``basis``'s columns leaves (``basis`` with no column: the target
    itself)."""
    if basis.shape[1]:
        w = np.ones(target.shape[0]) if weights is None else np.asarray(weights, float)
        coef, *_ = np.linalg.lstsq(basis * w[:, None], target * w[:, None], rcond=None)
        target = target - basis @ coef
    return max((_size(target[:, j], n_cells) for j in range(target.shape[1])), default=0.0)


def identifiability(signatures: Mapping[str, Signature], nuisance: Signature | None = None,
                    among: Sequence[str] | None = None,
                    threshold: float = MIN_EFFECT_SIZE) -> dict[str, Identifiability]:
    """Every candidate's identifiable size and its size given each other candidate.

    Args:
        signatures: candidate → its signature (same cells and rows for all).
        nuisance: the nuisance columns' signature (None: none).
        among: the candidates another one is checked against (default: all); those too
            small to be assessed are left out (a term the ranking never sees cannot be
            presented in another's place).
        threshold: the practical size [σ].

    Returns:
        candidate → :class:`Identifiability`.
    """
    names = list(signatures)
    if not names:
        return {}
    ref = signatures[names[0]]
    cells_all = [s.cells for s in signatures.values()]
    if nuisance is not None:
        cells_all.append(nuisance.cells)
    mask = np.all(np.isfinite(np.hstack(cells_all)), axis=1)
    n_cells = int(mask.sum())
    mats = {n: _stack(s, mask) for n, s in signatures.items()}
    N = _stack(nuisance, mask) if nuisance is not None and nuisance.k else \
        np.zeros((n_cells + ref.rows.shape[0], 0))
    w = _fit_weights(ref, mask)
    others = list(among) if among is not None else names
    out = {}
    for a in names:
        size = residual_size(mats[a], N, n_cells, w)
        given = {b: residual_size(mats[a], np.hstack([N, mats[b]]), n_cells, w)
                 for b in others if b != a and b in mats}
        out[a] = Identifiability(a, size, given, threshold)
    return out


def confused_pairs(ident: Mapping[str, Identifiability]) -> tuple[tuple[str, str], ...]:
    """(absorbed candidate, the candidate that absorbs it), sorted."""
    return tuple(sorted((a, b) for a, i in ident.items() for b in i.absorbed_by))


__all__ = ["Signature", "Identifiability", "identifiability", "residual_size",
           "confused_pairs"]
