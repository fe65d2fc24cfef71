"""Stance-phase segmentation, phase resampling, mean ± sd bands and RMSE with bootstrap.

Definitions (also in ``docs/analysis.md``):

* **Stance segment**: one foot's stance, from :mod:`granular_mpc.analysis.stances`. The
  per-stance functions here (:func:`stance_phase`, :func:`resample_stances`,
  :func:`stance_peaks`) default to touchdown → lift-off (:func:`contact_segments`: the
  plant's ``<side>_contact``, else the vertical force, else the plan). The table function
  :func:`segment_stances` keeps its historical default ``source="planned"``: a maximal
  run of rows whose planned ``stance`` label is one side *and* whose ``<side>_contact``
  flag is 1 (the contact test is skipped when the per-foot column is absent). A segment
  that touches the first or the last row of the log may be cut short by the recording
  and is marked ``complete = False``; such segments are left out by default. Every
  segment table and per-stance result carries a ``stance_source`` column.
* **Stance-foot channels**: the format-v1 ``grf_*`` / ``intrusion_*`` columns follow the
  planned stance foot in run logs; per stance they are read from the segment foot's own
  ``<side>_grf_*`` / ``<side>_intrusion_*`` when present (:func:`stance_column`).
* **Stance phase**: ``phase_pct = 100 (t − t_start) / (t_end − t_start)`` with ``t_start``
  and ``t_end`` the times of the first and last sample of the segment, so every segment
  runs from 0 % to 100 % exactly.
* **Resampling**: every channel of every segment is linearly interpolated onto a common
  phase grid (``n_phase`` points over 0–100 %); phases outside a segment's samples are NaN.
* **Roles**: channel names may be written in *role space*: the token ``stance`` stands
  for the side of the segment and ``swing`` for the other side, e.g. ``q_swing_knee`` is
  ``q_right_knee`` during a left stance and ``stance_grf_z`` is ``left_grf_z``. This is
  how the paper's Fig. 4a relabels the legs (swing leg q1–3, stance leg q4–6).
* **Bands**: per phase point, the mean and the sample standard deviation (ddof = 1) over
  segments of each channel, NaN-aware; median and quartiles are given too.
* **RMSE table**: prediction and measurement are two row-aligned DataFrames with the
  same channels; per group (e.g. commanded speed), channel and stance-phase bin,
  ``RMSE = sqrt(mean((pred − meas)²))`` over every finite sample pooled over trials,
  ``bias = mean(pred − meas)``. Confidence intervals come from a percentile bootstrap
  that resamples *whole trials* with replacement (a cluster bootstrap: samples within a
  trial are correlated, trials are the independent units), seeded for repeatability.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np
import pandas as pd

from ..columns import FOOT_SIDES, GRF_COLUMNS, INTRUSION_COLUMNS, foot_column
from .stances import (DEFAULT_MIN_SAMPLES, SOURCE_COL, STANCE_TABLE_COLUMNS, find_stances,
                      resolve_source, stance_table, table_source)

SIDES = FOOT_SIDES
PHASE_COL = "phase_pct"
ID_COL = "stance_id"
_OTHER = {"left": "right", "right": "left"}

SEGMENT_COLUMNS = STANCE_TABLE_COLUMNS
V1_STANCE_FOOT_COLUMNS = GRF_COLUMNS + INTRUSION_COLUMNS
"""Format-v1 channels of "the stance foot" (read per foot by :func:`stance_column`)."""


# --------------------------------------------------------------------------- segmentation
def segment_stances(log: pd.DataFrame, *, source: str = "planned", require_contact: bool = True,
                    min_samples: int = DEFAULT_MIN_SAMPLES, include_incomplete: bool = False,
                    debounce_samples: int | None = None,
                    force_threshold_N: float | None = None) -> pd.DataFrame:
    """Split a log into single-foot stance segments (see :mod:`.stances`).

    With the default ``source="planned"`` a segment is, as it has always been, a maximal
    run of rows with ``stance == side`` (``planned_stance`` if the log has that column)
    and, if ``require_contact`` and the column exists, ``<side>_contact == 1``. With
    ``source="contact"`` / ``"force"`` / ``"auto"`` it runs from touchdown to lift-off of
    the foot (contact state or vertical force, debounced), which is what per-stance
    figures should use; :func:`contact_segments` is that call.

    Args:
        log: run log or measurement DataFrame with ``time`` [s] and the source's columns.
        source: ``"planned"`` (default), ``"contact"``, ``"force"`` or ``"auto"``.
        require_contact: planned source: also require the per-foot contact flag.
        min_samples: runs with fewer rows are dropped (contact flicker).
        include_incomplete: keep runs touching the first or last row of the log.
        debounce_samples, force_threshold_N: see :func:`.stances.find_stances`.

    Returns:
        One row per segment, in time order: ``stance_id`` (0, 1, … after filtering),
        ``side``, ``row_start`` / ``row_stop`` (positional, stop exclusive), ``t_start``,
        ``t_end`` [s] (first and last sample), ``duration_s``, ``n_samples``, ``complete``,
        ``stance_source`` (also in ``attrs["stance_source"]``).

    Raises:
        ValueError: if ``time`` or the source's columns are missing, or time is not
            increasing.
    """
    src = resolve_source(log, source)
    stances = find_stances(log, src, debounce_samples=debounce_samples,
                           force_threshold_N=force_threshold_N, min_samples=min_samples,
                           require_contact=require_contact)
    return stance_table(stances, include_incomplete=include_incomplete, source=src)


def contact_segments(log: pd.DataFrame, **kwargs) -> pd.DataFrame:
    """:func:`segment_stances` from touchdown to lift-off: ``source="auto"`` (the contact
    state if the log has ``<side>_contact``, else the vertical force, else the plan)."""
    kwargs.setdefault("source", "auto")
    return segment_stances(log, **kwargs)


def _segments(log: pd.DataFrame, segments: pd.DataFrame | None, kwargs: dict) -> pd.DataFrame:
    """``segments`` or, if None, the log's touchdown-to-lift-off segments."""
    return contact_segments(log, **kwargs) if segments is None else segments


def stance_column(name: str, side: str, columns: Iterable[str]) -> str:
    """Column holding channel ``name`` during a stance of ``side``.

    :func:`role_column` first; then a format-v1 stance-foot channel (``grf_x..z``,
    ``intrusion_x..z``) is read from the foot's own column ``<side>_<name>`` when the log
    has it. In run logs the v1 columns follow the *planned* stance foot, which during a
    contact stance may be the other foot (or none); the per-foot column is the same
    value whenever the plan agrees.
    """
    col = role_column(name, side)
    if col in V1_STANCE_FOOT_COLUMNS:
        own = foot_column(side, col)
        if own in set(columns):
            return own
    return col


def stance_phase(log: pd.DataFrame, segments: pd.DataFrame | None = None,
                 **segment_kwargs) -> pd.DataFrame:
    """Rows of ``log`` that lie in a stance segment, with ``stance_id``, ``phase_pct`` and
    ``stance_source``.

    Returns a new DataFrame (the input is not modified), index reset. Without
    ``segments`` the stances run from touchdown to lift-off (:func:`contact_segments`,
    ``segment_kwargs`` passed on; ``source="planned"`` gives the planned stances).
    """
    segments = _segments(log, segments, segment_kwargs)
    src = table_source(segments)
    parts = []
    t_all = log["time"].to_numpy(dtype=float)
    for seg in segments.itertuples(index=False):
        part = log.iloc[seg.row_start:seg.row_stop].copy()
        t = t_all[seg.row_start:seg.row_stop]
        part[ID_COL] = int(seg.stance_id)
        part[PHASE_COL] = 100.0 * (t - t[0]) / (t[-1] - t[0])
        part[SOURCE_COL] = src
        parts.append(part)
    if not parts:
        return log.iloc[0:0].assign(**{ID_COL: pd.Series(dtype=int),
                                       PHASE_COL: pd.Series(dtype=float),
                                       SOURCE_COL: pd.Series(dtype=object)})
    return pd.concat(parts, ignore_index=True)


@dataclass(frozen=True)
class StancePeaks:
    """Per-stance peaks of the stance foot's sinkage and slip, averaged over stances.

    Attributes:
        sinkage_peak_mm_mean: mean over stances of max z_s (``intrusion_z`` of the stance
            foot, depth below its touchdown point, positive deeper) [mm]; None without
            stances.
        slip_mm_mean: mean over stances of max ‖(x_s, y_s)‖ (horizontal displacement of
            the contact point from touchdown, sole rolling included) [mm]; None without
            stances.
        n_stances: stances averaged.
        source: stance source (``"contact"``, ``"force"``, ``"planned"``).
    """

    sinkage_peak_mm_mean: float | None
    slip_mm_mean: float | None
    n_stances: int
    source: str

    def summary_items(self) -> dict:
        """``sinkage_peak_mm_mean``, ``slip_mm_mean``, ``n_stances``, ``stance_source``."""
        return {"sinkage_peak_mm_mean": self.sinkage_peak_mm_mean,
                "slip_mm_mean": self.slip_mm_mean, "n_stances": self.n_stances,
                SOURCE_COL: self.source}


def stance_peaks(log: pd.DataFrame, t_start: float | None = None, *,
                 segments: pd.DataFrame | None = None, **segment_kwargs) -> StancePeaks:
    """Peak sinkage and slip per stance, averaged over the stances starting at or after
    ``t_start`` [s] (over all complete stances if none does).

    Stances: ``segments``, else touchdown to lift-off (:func:`contact_segments` with
    ``segment_kwargs``; ``source="planned"`` reproduces the runner's historical
    ``stance_metrics``). The channels are read per foot (:func:`stance_column`:
    ``<side>_intrusion_x/y/z`` when present, else the v1 ``intrusion_*``).
    """
    segs = _segments(log, segments, segment_kwargs)
    src = table_source(segs)
    if t_start is not None and len(segs):
        later = segs[segs["t_start"] >= t_start - 1e-9]
        if len(later):
            segs = later
    if len(segs) == 0:
        return StancePeaks(None, None, 0, src)
    sink, slip = [], []
    for seg in segs.itertuples(index=False):
        sl = slice(seg.row_start, seg.row_stop)

        def col(name: str) -> np.ndarray:
            return log[stance_column(name, seg.side, log.columns)].to_numpy(dtype=float)[sl]

        sink.append(col("intrusion_z").max())
        slip.append(np.hypot(col("intrusion_x"), col("intrusion_y")).max())
    return StancePeaks(1e3 * float(np.mean(sink)), 1e3 * float(np.mean(slip)), int(len(segs)),
                       src)


# --------------------------------------------------------------------------- roles
def role_column(name: str, side: str) -> str:
    """Resolve a role-space column name for a stance on ``side``.

    The ``_``-separated tokens ``stance`` and ``swing`` become ``side`` and the other
    side: ``role_column("q_swing_knee", "left") == "q_right_knee"``. Names without those
    tokens are returned unchanged.
    """
    if side not in _OTHER:
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    tokens = name.split("_")
    sub = {"stance": side, "swing": _OTHER[side]}
    return "_".join(sub.get(tok, tok) for tok in tokens)


def leg_joint_roles(columns: Iterable[str], prefix: str = "q_") -> tuple[list[str], list[str]]:
    """Role-space names of the swing- and stance-leg joints found in ``columns``.

    Joints are the ``<prefix>left_<name>`` columns (URDF order as they appear); returns
    (``[prefix + "swing_" + name …]``, ``[prefix + "stance_" + name …]``), i.e. the paper's
    q1–3 (swing leg) and q4–6 (stance leg) of Fig. 4a.
    """
    cols = list(columns)
    names = [c[len(prefix) + 5:] for c in cols if c.startswith(prefix + "left_")
             and (prefix + "right_" + c[len(prefix) + 5:]) in cols]
    return ([f"{prefix}swing_{n}" for n in names], [f"{prefix}stance_{n}" for n in names])


# --------------------------------------------------------------------------- resampling
def phase_grid(n_phase: int = 101) -> np.ndarray:
    """``n_phase`` equally spaced stance phases over 0–100 % [%]."""
    if n_phase < 2:
        raise ValueError("n_phase must be at least 2")
    return np.linspace(0.0, 100.0, int(n_phase))


def resample_by_phase(df: pd.DataFrame, channels: Sequence[str], *, id_col: str = ID_COL,
                      phase_col: str = PHASE_COL, n_phase: int = 101,
                      keep: Sequence[str] = ()) -> pd.DataFrame:
    """Interpolate each group of ``df`` (one per ``id_col`` value) onto a common phase grid.

    Linear interpolation in phase; grid points outside a group's sampled phase range are
    NaN (no extrapolation); NaN samples make the neighbouring interpolated points NaN.

    Args:
        df: long DataFrame with ``id_col``, ``phase_col`` [%] and the channels.
        channels: columns to interpolate.
        n_phase: grid size over 0–100 %.
        keep: per-group constant columns to carry along (first value of the group).

    Returns:
        Wide DataFrame ``[id_col, *keep, phase_col, *channels]``, ``n_phase`` rows per group.
    """
    grid = phase_grid(n_phase)
    missing = [c for c in [id_col, phase_col, *channels, *keep] if c not in df.columns]
    if missing:
        raise ValueError(f"resample_by_phase: missing columns {missing}")
    out = []
    for gid, g in df.groupby(id_col, sort=True):
        g = g.sort_values(phase_col)
        ph = g[phase_col].to_numpy(dtype=float)
        block = {id_col: np.full(grid.size, gid)}
        for k in keep:
            block[k] = np.full(grid.size, g[k].iloc[0], dtype=object)
        block[phase_col] = grid
        for c in channels:
            block[c] = np.interp(grid, ph, g[c].to_numpy(dtype=float), left=np.nan,
                                 right=np.nan)
        out.append(pd.DataFrame(block))
    if not out:
        return pd.DataFrame(columns=[id_col, *keep, phase_col, *channels])
    res = pd.concat(out, ignore_index=True)
    for k in keep:
        res[k] = res[k].infer_objects()
    return res


def resample_stances(log: pd.DataFrame, channels: Sequence[str], *,
                     segments: pd.DataFrame | None = None, n_phase: int = 101,
                     **segment_kwargs) -> pd.DataFrame:
    """Resample every stance segment of a log onto a common phase grid.

    Args:
        log: run log / measurement DataFrame (``time``, the stance source's columns and
            the channels).
        channels: column names, possibly in role space, resolved per stance by
            :func:`stance_column` (so ``grf_z`` is the stance foot's own ``<side>_grf_z``
            when the log has it); the output keeps the names as given.
        segments: from :func:`segment_stances`; if None, touchdown to lift-off
            (:func:`contact_segments` with ``segment_kwargs``).
        n_phase: grid size over 0–100 % stance phase.

    Returns:
        Wide DataFrame ``[stance_id, side, stance_source, phase_pct, *channels]``
        (``n_phase`` rows per stance), values in the units of the log.
    """
    segments = _segments(log, segments, segment_kwargs)
    src = table_source(segments)
    grid = phase_grid(n_phase)
    t_all = log["time"].to_numpy(dtype=float)
    out = []
    for seg in segments.itertuples(index=False):
        t = t_all[seg.row_start:seg.row_stop]
        ph = 100.0 * (t - t[0]) / (t[-1] - t[0])
        block = {ID_COL: np.full(grid.size, int(seg.stance_id)),
                 "side": np.full(grid.size, seg.side, dtype=object),
                 SOURCE_COL: np.full(grid.size, src, dtype=object), PHASE_COL: grid}
        for c in channels:
            col = stance_column(c, seg.side, log.columns)
            if col not in log.columns:
                raise ValueError(f"resample_stances: channel {c!r} → column {col!r} "
                                 f"is not in the log")
            y = log[col].to_numpy(dtype=float)[seg.row_start:seg.row_stop]
            block[c] = np.interp(grid, ph, y)
        out.append(pd.DataFrame(block))
    if not out:
        return pd.DataFrame(columns=[ID_COL, "side", SOURCE_COL, PHASE_COL, *channels])
    return pd.concat(out, ignore_index=True)


def phase_bands(resampled: pd.DataFrame, channels: Sequence[str], *, by: Sequence[str] = (),
                phase_col: str = PHASE_COL) -> pd.DataFrame:
    """Mean ± sd across stances per phase point and channel (tidy output).

    Args:
        resampled: wide DataFrame from :func:`resample_stances` / :func:`resample_by_phase`.
        channels: columns to summarise.
        by: extra grouping columns (e.g. ``source``, ``commanded_speed_mps``).

    Returns:
        Tidy DataFrame ``[*by, channel, phase_pct, n, mean, sd, median, q25, q75]``; ``n``
        counts the finite values, ``sd`` is the sample standard deviation (ddof = 1, NaN
        for n < 2); NaNs are ignored.
    """
    keys = [*by, phase_col]
    long = resampled.melt(id_vars=keys, value_vars=list(channels), var_name="channel",
                          value_name="value")
    long["value"] = long["value"].astype(float)
    g = long.groupby([*by, "channel", phase_col], sort=False)["value"]
    res = pd.DataFrame({
        "n": g.count(), "mean": g.mean(), "sd": g.std(ddof=1), "median": g.median(),
        "q25": g.quantile(0.25), "q75": g.quantile(0.75)}).reset_index()
    order = {c: i for i, c in enumerate(channels)}
    res["_o"] = res["channel"].map(order)
    res = res.sort_values([*by, "_o", phase_col], kind="stable").drop(columns="_o")
    return res.reset_index(drop=True)


# --------------------------------------------------------------------------- RMSE
def _bin_edges(phase_bins) -> np.ndarray | None:
    if phase_bins is None:
        return None
    if np.isscalar(phase_bins):
        nb = int(phase_bins)
        if nb < 1:
            raise ValueError("phase_bins must be >= 1")
        return np.linspace(0.0, 100.0, nb + 1)
    edges = np.asarray(phase_bins, dtype=float)
    if edges.ndim != 1 or edges.size < 2 or not np.all(np.diff(edges) > 0):
        raise ValueError("phase_bins edges must be a strictly increasing 1-D sequence")
    return edges


def _assign_bins(phase: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Bin index per sample, bins [lo, hi) with the last one closed; −1 outside."""
    idx = np.searchsorted(edges, phase, side="right") - 1
    idx[phase == edges[-1]] = edges.size - 2
    idx[(phase < edges[0]) | (phase > edges[-1]) | ~np.isfinite(phase)] = -1
    return idx


RMSE_COLUMNS = ["channel", "phase_bin", "phase_lo", "phase_hi", "n_trials", "n_samples",
                "rmse", "bias", "ci_lo", "ci_hi"]


def rmse_table(prediction: pd.DataFrame, measurement: pd.DataFrame,
               channels: Sequence[str], *, trial_col: str = "trial",
               group_cols: Sequence[str] = ("commanded_speed_mps",),
               phase_col: str = PHASE_COL, phase_bins: int | Sequence[float] | None = 10,
               n_boot: int = 2000, ci: float = 0.95, seed: int = 0) -> pd.DataFrame:
    """RMSE between row-aligned prediction and measurement by group × channel × phase bin.

    ``RMSE = sqrt(Σ (p − m)² / N)`` over the finite samples of all trials of a group in
    a bin; ``bias = Σ (p − m) / N``. The ``ci`` interval is a percentile bootstrap over
    trials: ``n_boot`` times, draw the group's trials with replacement (each drawn trial
    brings all its samples) and recompute the RMSE. With fewer than two trials in a group
    the interval is NaN (between-trial variability cannot be estimated).

    Args:
        prediction, measurement: DataFrames of equal length, row ``i`` of one aligned with
            row ``i`` of the other, holding ``channels`` (any unit; RMSE has that unit).
            Key columns (``trial_col``, ``group_cols``, ``phase_col``) are read from
            ``measurement``; if ``prediction`` has them too they must be equal.
        channels: columns to compare.
        trial_col: the independent unit resampled by the bootstrap (trial file, run or
            stance id).
        group_cols: grouping columns, e.g. ``("commanded_speed_mps",)``; may be empty.
        phase_col: stance phase [%] column; ignored when ``phase_bins`` is None.
        phase_bins: number of equal bins over 0–100 %, explicit edges, or None for one bin
            covering everything (whole-stance RMSE, as in the paper's Fig. 5).
        n_boot: bootstrap replicates (0 disables the interval).
        ci: interval coverage (e.g. 0.95 → 2.5th and 97.5th percentiles).
        seed: seed of the bootstrap generator (same seed → same intervals).

    Returns:
        Tidy DataFrame ``[*group_cols, channel, phase_bin, phase_lo, phase_hi, n_trials,
        n_samples, rmse, bias, ci_lo, ci_hi]``, one row per non-empty cell.

    Raises:
        ValueError: misaligned inputs, missing columns, bad arguments.
    """
    group_cols = list(group_cols)
    channels = list(channels)
    if len(prediction) != len(measurement):
        raise ValueError(f"rmse_table: prediction has {len(prediction)} rows, measurement "
                         f"{len(measurement)}; they must be row-aligned")
    if not 0.0 < ci < 1.0:
        raise ValueError("ci must be in (0, 1)")
    edges = _bin_edges(phase_bins)
    keys = [trial_col, *group_cols] + ([phase_col] if edges is not None else [])
    for name, frame, cols in (("measurement", measurement, keys + channels),
                              ("prediction", prediction, channels)):
        missing = [c for c in cols if c not in frame.columns]
        if missing:
            raise ValueError(f"rmse_table: {name} lacks columns {missing}")
    for k in keys:
        if k in prediction.columns:
            a, b = prediction[k].to_numpy(), measurement[k].to_numpy()
            same = (np.allclose(a.astype(float), b.astype(float), equal_nan=True)
                    if np.issubdtype(a.dtype, np.number) and np.issubdtype(b.dtype, np.number)
                    else np.array_equal(a.astype(str), b.astype(str)))
            if not same:
                raise ValueError(f"rmse_table: key column {k!r} differs between prediction "
                                 "and measurement; align the rows first")

    err = prediction[channels].to_numpy(dtype=float) - measurement[channels].to_numpy(dtype=float)
    if edges is None:
        bins = np.zeros(len(measurement), dtype=int)
        edges_used = np.array([0.0, 100.0])
    else:
        bins = _assign_bins(measurement[phase_col].to_numpy(dtype=float), edges)
        edges_used = edges
    nb = edges_used.size - 1

    frame = measurement[[trial_col, *group_cols]].copy()
    frame["_bin"] = bins
    frame = frame.reset_index(drop=True)
    groups = (frame.groupby(group_cols, sort=True).indices if group_cols
              else {(): np.arange(len(frame))})
    seeds = np.random.SeedSequence(seed).spawn(max(len(groups), 1))
    lo_q, hi_q = 100.0 * (1.0 - ci) / 2.0, 100.0 * (1.0 + ci) / 2.0
    rows = []
    for gi, (gkey, gidx) in enumerate(groups.items()):
        gkey = gkey if isinstance(gkey, tuple) else (gkey,)
        trials, tinv = np.unique(frame[trial_col].to_numpy()[gidx].astype(str),
                                 return_inverse=True)
        nt = trials.size
        gb = bins[gidx]
        ge = err[gidx]
        ok = np.isfinite(ge) & (gb >= 0)[:, None]
        e2 = np.where(ok, ge, 0.0)
        # per trial × (bin, channel): sum of squared errors, sum of errors, count
        sse = np.zeros((nt, nb, len(channels)))
        se = np.zeros_like(sse)
        cnt = np.zeros_like(sse)
        valid_bin = gb >= 0
        np.add.at(sse, (tinv[valid_bin], gb[valid_bin]), e2[valid_bin] ** 2)
        np.add.at(se, (tinv[valid_bin], gb[valid_bin]), e2[valid_bin])
        np.add.at(cnt, (tinv[valid_bin], gb[valid_bin]), ok[valid_bin].astype(float))
        tot_sse, tot_se, tot_n = sse.sum(0), se.sum(0), cnt.sum(0)
        ntr = (cnt > 0).sum(0)
        with np.errstate(invalid="ignore", divide="ignore"):
            rmse = np.sqrt(tot_sse / tot_n)
            bias = tot_se / tot_n
        ci_lo = np.full_like(rmse, np.nan)
        ci_hi = np.full_like(rmse, np.nan)
        if n_boot > 0 and nt >= 2:
            rng = np.random.default_rng(seeds[gi])
            w = rng.multinomial(nt, np.full(nt, 1.0 / nt), size=int(n_boot)).astype(float)
            b_sse = np.tensordot(w, sse, axes=(1, 0))   # (n_boot, nb, nch)
            b_n = np.tensordot(w, cnt, axes=(1, 0))
            with np.errstate(invalid="ignore", divide="ignore"):
                b_rmse = np.sqrt(b_sse / b_n)
            multi = ntr >= 2
            if multi.any():
                with warnings.catch_warnings():  # all-NaN cells (single-trial bins)
                    warnings.simplefilter("ignore", RuntimeWarning)
                    lo = np.nanpercentile(b_rmse, lo_q, axis=0)
                    hi = np.nanpercentile(b_rmse, hi_q, axis=0)
                ci_lo = np.where(multi, lo, np.nan)
                ci_hi = np.where(multi, hi, np.nan)
        for b in range(nb):
            for c, ch in enumerate(channels):
                if tot_n[b, c] == 0:
                    continue
                lo_e, hi_e = edges_used[b], edges_used[b + 1]
                label = "all" if edges is None else f"{lo_e:g}-{hi_e:g}"
                rows.append((*gkey, ch, label, lo_e, hi_e, int(ntr[b, c]), int(tot_n[b, c]),
                             rmse[b, c], bias[b, c], ci_lo[b, c], ci_hi[b, c]))
    return pd.DataFrame(rows, columns=[*group_cols, *RMSE_COLUMNS])


__all__ = [
    "segment_stances", "contact_segments", "stance_column", "StancePeaks", "stance_peaks",
    "V1_STANCE_FOOT_COLUMNS", "stance_phase", "role_column", "leg_joint_roles", "phase_grid",
    "resample_by_phase", "resample_stances", "phase_bands", "rmse_table", "SEGMENT_COLUMNS",
    "RMSE_COLUMNS", "PHASE_COL",
]
