"""Stances from touchdown to lift-off: from the contact state, the force, or the plan.

A **stance** of a foot is a maximal run of log rows in which that foot is on the ground.
Three sources say when, in this order of preference (``source="auto"``):

* ``"contact"`` — the plant's contact state, run-log columns ``left_contact`` /
  ``right_contact`` (0/1; the plant's geometry, not the plan). Both feet may be in stance at
  once (double support); the stances of one foot never overlap.
* ``"force"`` — measured data: the foot is on the ground while its vertical ground reaction
  force exceeds a threshold: per-foot ``left_grf_z`` / ``right_grf_z`` [N], or, with only the
  format-v1 columns, the ``stance`` label's foot while ``grf_z`` (force on the labelled stance
  foot) exceeds it. Default threshold: 5 % of the robot's weight, estimated as the
  time-mean of the total vertical force (the vertical impulse balance: over a walk the mean
  of ΣF_z is m g up to m Δv_z / T), or ``force_threshold_N`` [N] when given.
* ``"planned"`` — the gait schedule's stance label: column ``planned_stance`` if the log has
  one, else ``stance`` (in run logs ``stance`` is the *planned* stance, see
  ``docs/log-format.md``). With ``require_contact`` (default) a planned stance row also needs
  the foot's ``<side>_contact == 1`` when that column exists — exactly the segmentation
  :func:`granular_mpc.analysis.metrics.segment_stances` has always used. A planned stance
  starts when the plan says so, not at touchdown: on sand the plan is ``none`` during load
  transfer, so a planned stance begins with the foot already deep in the sand.

**Debounce** (``"contact"`` and ``"force"``; default 20 ms, at least one sample): in each
foot's on-ground mask, off-ground gaps of at most that many samples between two on-ground
runs are filled, then on-ground runs of at most that many samples are removed. Reason: at
touchdown and lift-off the foot grazes the surface (a contact penetration or a force
within noise of zero) and single logged samples flip; on rigid ground the landing foot
bounces (a 2–4 ms contact, ≈ 10 ms in the air, then the stance). Undebounced, this splits
a stance in two (a second "touchdown" with its own phase 0 %) or creates a stance of a few
samples. The touchdown is the first contact of the merged run. 20 ms is far shorter than
any real swing or stance (≥ 0.1 s), so the debounce cannot merge two real stances nor drop
a real one. The planned source is a schedule label and is not debounced (it does not
chatter). Runs shorter than ``min_samples`` (default 3) are dropped afterwards.

**Times.** ``t_touchdown`` and ``t_liftoff`` [s] are the times of the first and the last
sample of the run (the true events lie within one sample period before / after). A run
that starts on the first log row has no observed touchdown, one that ends on the last row
no observed lift-off; they are kept with ``touchdown_seen`` / ``liftoff_seen`` False
(``complete`` False) and left out of per-stance figures by default. For the contact and
force sources a run starting within the first ``min_samples`` rows is treated the same
way (a *standing start*: a run log begins with the robot settling onto both feet one
sample after t = 0, and that stance — standing, then the first step — is not a walking
touchdown).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pandas as pd
from scipy.integrate import trapezoid

from ..columns import FOOT_SIDES, PLANNED_STANCE, STANCE, TIME, foot_column

STANCE_SOURCES = ("contact", "force", "planned")
"""Where a stance comes from (see the module docstring)."""
SOURCE_OPTIONS = ("auto",) + STANCE_SOURCES
DEFAULT_DEBOUNCE = 1
"""Least number of samples of on/off chatter removed from contact and force masks."""
DEFAULT_DEBOUNCE_S = 0.02
"""On/off chatter removed from contact and force masks [s] (at least
:data:`DEFAULT_DEBOUNCE` samples): a foot landing on rigid ground bounces (a 2–4 ms
contact, ≈ 10 ms off, then the stance), which must not start a stance of its own."""
DEFAULT_FORCE_FRACTION = 0.05
"""Default force threshold as a fraction of the robot weight [-]."""
DEFAULT_MIN_SAMPLES = 3
SOURCE_COL = "stance_source"
"""Column naming the stance source in per-stance tables."""


@dataclass(frozen=True)
class Stance:
    """One stance of one foot.

    Attributes:
        side: ``"left"`` or ``"right"``.
        t_touchdown: time of the first sample on the ground [s].
        t_liftoff: time of the last sample on the ground [s].
        row_start: positional index of the first row.
        row_stop: positional index one past the last row (exclusive).
        source: ``"contact"``, ``"force"`` or ``"planned"``.
        touchdown_seen: False if the stance starts on the first log row (touchdown not
            recorded).
        liftoff_seen: False if the stance ends on the last log row.
    """

    side: str
    t_touchdown: float
    t_liftoff: float
    row_start: int
    row_stop: int
    source: str
    touchdown_seen: bool = True
    liftoff_seen: bool = True

    @property
    def complete(self) -> bool:
        """Both touchdown and lift-off lie inside the log."""
        return self.touchdown_seen and self.liftoff_seen

    @property
    def n_samples(self) -> int:
        return self.row_stop - self.row_start

    @property
    def duration_s(self) -> float:
        """t_liftoff − t_touchdown [s]."""
        return self.t_liftoff - self.t_touchdown

    @property
    def rows(self) -> slice:
        """Positional slice of the stance's rows."""
        return slice(self.row_start, self.row_stop)


# --------------------------------------------------------------------------- masks
def true_runs(mask: Sequence[bool] | np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) positional index pairs (stop exclusive) of the True runs of ``mask``."""
    m = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    d = np.diff(m.astype(np.int8))
    starts = np.flatnonzero(d == 1)
    stops = np.flatnonzero(d == -1)
    return list(zip(starts.tolist(), stops.tolist()))


def debounce(mask: Sequence[bool] | np.ndarray, samples: int = DEFAULT_DEBOUNCE) -> np.ndarray:
    """Remove on/off chatter of at most ``samples`` samples from a boolean mask.

    First False gaps of length ≤ ``samples`` *between* two True runs are filled (a gap at
    either end of the mask is not: the state outside the record is unknown), then True runs
    of length ≤ ``samples`` are cleared. ``samples = 0`` returns the mask unchanged.
    """
    m = np.asarray(mask, dtype=bool).copy()
    k = int(samples)
    if k < 0:
        raise ValueError(f"debounce samples must be >= 0, got {samples!r}")
    if k == 0 or m.size == 0:
        return m
    for a, b in true_runs(~m):
        if a > 0 and b < m.size and b - a <= k:
            m[a:b] = True
    for a, b in true_runs(m):
        if b - a <= k:
            m[a:b] = False
    return m


def _time(log: pd.DataFrame) -> np.ndarray:
    if TIME not in log.columns:
        raise ValueError(f"the log has no {TIME!r} column")
    t = log[TIME].to_numpy(dtype=float)
    if t.size > 1 and not np.all(np.diff(t) > 0):
        bad = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise ValueError(f"time is not strictly increasing at row {bad}")
    return t


def _has(log: pd.DataFrame, name: str) -> bool:
    return all(foot_column(s, name) in log.columns for s in FOOT_SIDES)


def planned_column(log: pd.DataFrame) -> str:
    """The planned-stance column of a log: ``planned_stance`` if present, else ``stance``."""
    for c in (PLANNED_STANCE, STANCE):
        if c in log.columns:
            return c
    raise ValueError(f"the log has no {PLANNED_STANCE!r} or {STANCE!r} column")


def resolve_source(log: pd.DataFrame, source: str = "auto") -> str:
    """The stance source used for ``log``: ``source`` itself, or for ``"auto"`` the first
    available of ``contact`` (``<side>_contact`` columns), ``force`` (``<side>_grf_z``, or
    ``grf_z`` with ``stance``) and ``planned``."""
    if source not in SOURCE_OPTIONS:
        raise ValueError(f"source must be one of {SOURCE_OPTIONS}, got {source!r}")
    if source != "auto":
        return source
    if _has(log, "contact"):
        return "contact"
    if _has(log, "grf_z") or {"grf_z", STANCE} <= set(log.columns):
        return "force"
    return "planned"


def force_threshold(log: pd.DataFrame, fraction: float = DEFAULT_FORCE_FRACTION) -> float:
    """Default on-ground force threshold [N]: ``fraction`` × the time-mean of ΣF_z.

    ΣF_z is ``left_grf_z + right_grf_z`` (or ``grf_z``); its time-mean over a walk is the
    robot weight up to m Δv_z / T. Raises ValueError if that mean is not positive.
    """
    t = _time(log)
    fz = (log[foot_column("left", "grf_z")].to_numpy(dtype=float)
          + log[foot_column("right", "grf_z")].to_numpy(dtype=float)
          if _has(log, "grf_z") else log["grf_z"].to_numpy(dtype=float))
    mean = float(trapezoid(fz, t) / (t[-1] - t[0])) if t.size > 1 else float(fz.mean())
    if not (np.isfinite(mean) and mean > 0):
        raise ValueError("cannot estimate the weight from the vertical GRF (mean ΣF_z <= 0); "
                         "give force_threshold_N")
    return fraction * mean


def on_ground_mask(log: pd.DataFrame, side: str, source: str, *,
                   force_threshold_N: float | None = None,
                   require_contact: bool = True) -> np.ndarray:
    """Raw (not debounced) per-row mask of ``side``'s foot on the ground for one source."""
    if side not in FOOT_SIDES:
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    n = len(log)
    if source == "contact":
        col = foot_column(side, "contact")
        if col not in log.columns:
            raise ValueError(f"source='contact' needs the column {col!r}")
        return log[col].to_numpy(dtype=float) > 0.5
    if source == "force":
        thr = force_threshold(log) if force_threshold_N is None else float(force_threshold_N)
        col = foot_column(side, "grf_z")
        if col in log.columns:
            return log[col].to_numpy(dtype=float) > thr
        if {"grf_z", STANCE} <= set(log.columns):
            label = log[STANCE].astype(str).to_numpy()
            return (label == side) & (log["grf_z"].to_numpy(dtype=float) > thr)
        raise ValueError(f"source='force' needs {col!r} or 'grf_z' with 'stance'")
    if source == "planned":
        mask = log[planned_column(log)].astype(str).to_numpy() == side
        ccol = foot_column(side, "contact")
        if require_contact and ccol in log.columns:
            mask &= log[ccol].to_numpy(dtype=float) > 0.5
        return mask
    raise ValueError(f"source must be one of {STANCE_SOURCES}, got {source!r}")


# --------------------------------------------------------------------------- stances
def find_stances(log: pd.DataFrame, source: str = "auto", *,
                 debounce_samples: int | None = None,
                 force_threshold_N: float | None = None,
                 min_samples: int = DEFAULT_MIN_SAMPLES,
                 require_contact: bool = True) -> tuple[Stance, ...]:
    """Every stance of both feet, ordered by touchdown row (then left before right).

    Args:
        log: run log or measurement DataFrame with ``time`` [s] and the source's columns.
        source: ``"auto"``, ``"contact"``, ``"force"`` or ``"planned"`` (module docstring).
        debounce_samples: chatter removed by :func:`debounce`; default
            :data:`DEFAULT_DEBOUNCE_S` in samples of the log's median time step (at least
            :data:`DEFAULT_DEBOUNCE`) for contact/force, and 0 for planned.
        force_threshold_N: on-ground vertical force [N] for ``"force"``; default
            :func:`force_threshold`.
        min_samples: runs with fewer rows are dropped (at least 2 are needed for a phase).
        require_contact: planned source only: also require ``<side>_contact``.

    Returns:
        A tuple of :class:`Stance`, incomplete ones (cut by the log's ends) included.

    Raises:
        ValueError: missing columns, time not strictly increasing, unknown source.
    """
    src = resolve_source(log, source)
    masks = {side: on_ground_mask(log, side, src, force_threshold_N=force_threshold_N,
                                  require_contact=require_contact) for side in FOOT_SIDES}
    t = _time(log)
    if debounce_samples is not None:
        k = int(debounce_samples)
    elif src == "planned":
        k = 0
    else:
        step = float(np.median(np.diff(t))) if len(t) > 1 else DEFAULT_DEBOUNCE_S
        k = max(DEFAULT_DEBOUNCE, int(round(DEFAULT_DEBOUNCE_S / step)))
    n = len(log)
    out = []
    m_min = max(int(min_samples), 2)
    for side in FOOT_SIDES:
        for a, b in true_runs(debounce(masks[side], k)):
            if b - a < m_min:
                continue
            # a standing start (the foot on the ground within the first rows) is no touchdown
            seen = a >= (m_min if src != "planned" else 1)
            out.append(Stance(side, float(t[a]), float(t[b - 1]), a, b, src, seen, b < n))
    out.sort(key=lambda s: (s.row_start, FOOT_SIDES.index(s.side)))
    return tuple(out)


STANCE_TABLE_COLUMNS = ["stance_id", "side", "row_start", "row_stop", "t_start", "t_end",
                        "duration_s", "n_samples", "complete", SOURCE_COL]
"""Columns of :func:`stance_table` (``t_start`` = touchdown, ``t_end`` = lift-off)."""


def stance_table(stances: Sequence[Stance], *, include_incomplete: bool = False,
                 source: str | None = None) -> pd.DataFrame:
    """Stances as the segment table of :func:`~granular_mpc.analysis.metrics.segment_stances`.

    Args:
        stances: from :func:`find_stances`.
        include_incomplete: keep stances cut by the log's ends.
        source: recorded in ``attrs["stance_source"]`` (so that an empty table still says
            which source found nothing); default: the stances' own source.

    Returns:
        One row per stance (incomplete ones only with ``include_incomplete``), columns
        :data:`STANCE_TABLE_COLUMNS`; ``stance_id`` numbers the kept rows 0, 1, … in order.
    """
    rows = [(s.side, s.row_start, s.row_stop, s.t_touchdown, s.t_liftoff, s.duration_s,
             s.n_samples, s.complete, s.source)
            for s in stances if include_incomplete or s.complete]
    out = pd.DataFrame(rows, columns=STANCE_TABLE_COLUMNS[1:])
    out.insert(0, "stance_id", np.arange(len(out), dtype=int))
    out = out.astype({"row_start": int, "row_stop": int, "n_samples": int, "complete": bool})
    srcs = sorted({s.source for s in stances})
    out.attrs[SOURCE_COL] = source or (srcs[0] if len(srcs) == 1 else "mixed" if srcs
                                       else "none")
    return out


def table_source(segments: pd.DataFrame) -> str:
    """The stance source of a segment table: its ``stance_source`` values (``"mixed"`` if
    several), else ``attrs["stance_source"]``, else ``"planned"`` (a table built by hand or
    before the column existed)."""
    vals = (sorted(set(segments[SOURCE_COL].astype(str))) if SOURCE_COL in segments.columns
            else [])
    if len(vals) == 1:
        return vals[0]
    if len(vals) > 1:
        return "mixed"
    return str(segments.attrs.get(SOURCE_COL, "planned"))


__all__ = [
    "Stance", "STANCE_SOURCES", "SOURCE_OPTIONS", "SOURCE_COL", "STANCE_TABLE_COLUMNS",
    "DEFAULT_DEBOUNCE", "DEFAULT_DEBOUNCE_S", "DEFAULT_FORCE_FRACTION", "DEFAULT_MIN_SAMPLES", "true_runs",
    "debounce", "planned_column", "resolve_source", "force_threshold", "on_ground_mask",
    "find_stances", "stance_table", "table_source",
]
