"""Figures of one run folder that the paper's claims are compared with.

Each function reads a run folder (``summary.json`` and the log) and computes one figure
with the package's analysis functions (:mod:`granular_mpc.analysis`): stances from contact
(touchdown to lift-off), the CoT readings of ``summary.json``, cumulative CoT per stance,
the rolling angle Δθ_r and its plateaus, the effective rolling radius. Stances are the
complete ones that touch down inside the summary's averaging window (steady walking).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis import (contact_segments, plateau_by_stance, reading_mode, rolling_from_log,
                        stance_cumulative_cot)
from ..columns import COM_VELOCITY, SUMMARY_FILE, foot_column
from ..runlog import read_log

#: phase grid of the stance curves [% of stance]
PHASE = np.linspace(0.0, 100.0, 101)
#: the CoT reading of every figure (docs/analysis.md §1)
READING = "abs_per_joint"


def read_summary(run_dir: str | Path) -> dict:
    """The run's ``summary.json``."""
    return json.loads((Path(run_dir) / SUMMARY_FILE).read_text(encoding="utf-8"))


def run_weight(summary: dict) -> float:
    """The robot's weight W_r [N] the run's CoT used: E / (CoT d)."""
    return float(summary["energy_J"]) / (float(summary["cot"]) * float(summary["distance_m"]))


def steady_segments(log: pd.DataFrame, t_start: float, source: str = "auto") -> pd.DataFrame:
    """Complete stances touching down at or after ``t_start`` [s].

    ``source`` is the stance source of :func:`contact_segments` (``"auto"``: the plant's
    contact state, touchdown to lift-off, whose 20 ms debounce merges the landing bounce on
    rigid ground into its stance; ``"force"``, ``"planned"``: the other definitions, for the
    segmentation ablation of ``bench/paper_gaps.py``)."""
    seg = contact_segments(log, source=source)
    return seg[seg["t_start"] >= t_start].reset_index(drop=True)


@dataclass(frozen=True)
class StanceCurves:
    """Stance-phase figures of one run (means over its steady stances).

    Attributes:
        run: the run folder.
        n_stances: stances averaged.
        cot_cum: mean cumulative CoT on :data:`PHASE` (``normalise="final"``: E(t) / (W d(stance)),
            ending at the stance's CoT), default reading.
        dtheta_r_deg: mean Δθ_r on :data:`PHASE` [deg].
        plateau_share: share of stances with a Δθ_r plateau [-].
        plateau_onset_pct: median onset of the first plateau [% stance] (NaN if none).
        plateau_fraction: mean share of the stance covered by plateaus [-].
        r_eff_contact_m: median R_eff = ‖v_s‖/|θ̇_r| with the contact-point velocity [m].
        r_eff_com_m: median ‖v_CoM‖/|θ̇_r| (the CoM's velocity as the numerator) [m].
        h_com_m: the run's CoM height above the sole [m] (``summary.json``).
    """

    run: Path
    n_stances: int
    cot_cum: np.ndarray
    dtheta_r_deg: np.ndarray
    plateau_share: float
    plateau_onset_pct: float
    plateau_fraction: float
    r_eff_contact_m: float
    r_eff_com_m: float
    h_com_m: float


def _mean_on_phase(df: pd.DataFrame, column: str) -> np.ndarray:
    curves = [np.interp(PHASE, g["phase_pct"].to_numpy(), g[column].to_numpy(dtype=float))
              for _, g in df.groupby("stance_id", sort=True)]
    return np.nanmean(np.stack(curves), axis=0) if curves else np.full(PHASE.shape, np.nan)


def stance_curves(run_dir: str | Path, *, source: str = "auto",
                  reading: str = READING) -> StanceCurves:
    """The stance-phase figures of a run (see :class:`StanceCurves`).

    Args:
        run_dir: the run folder.
        source: stance source (:func:`steady_segments`).
        reading: CoT reading of the cumulative curve (``analysis.COT_READINGS``).
    """
    summary = read_summary(run_dir)
    log = read_log(run_dir)
    seg = steady_segments(log, float(summary["window_s"][0]), source)
    w = run_weight(summary)
    cum = stance_cumulative_cot(log, weight=w, segments=seg, mode=reading_mode(reading),
                                normalise="final")
    roll = rolling_from_log(log, segments=seg)
    plat = plateau_by_stance(roll)
    has = plat["n_plateaus"] > 0
    # the CoM-velocity variant of R_eff on the rolling samples
    com = log.set_index("time")[list(COM_VELOCITY)]
    v_com = np.hypot(com.loc[roll["time"], COM_VELOCITY[0]].to_numpy(),
                     com.loc[roll["time"], COM_VELOCITY[2]].to_numpy())
    rate = np.abs(roll["dtheta_r_rate"].to_numpy(dtype=float))
    ok = np.isfinite(roll["r_eff"].to_numpy(dtype=float))
    return StanceCurves(
        run=Path(run_dir), n_stances=int(len(seg)),
        cot_cum=_mean_on_phase(cum, "cot_cum"),
        dtheta_r_deg=np.degrees(_mean_on_phase(roll, "dtheta_r")),
        plateau_share=float(has.mean()) if len(plat) else float("nan"),
        plateau_onset_pct=float(plat.loc[has, "onset_pct"].median()) if has.any() else float("nan"),
        plateau_fraction=float(plat["fraction"].mean()) if len(plat) else float("nan"),
        r_eff_contact_m=float(np.nanmedian(roll["r_eff"])) if ok.any() else float("nan"),
        r_eff_com_m=float(np.median(v_com[ok] / rate[ok])) if ok.any() else float("nan"),
        h_com_m=float(summary["h_com_m"]))


def opening_phase(sand: np.ndarray, rigid: np.ndarray, share: float = 0.1) -> float:
    """First phase [%] where the sand − rigid gap of the cumulative CoT reaches ``share``
    of its end-of-stance value (NaN if sand does not end above rigid)."""
    gap = np.asarray(sand) - np.asarray(rigid)
    final = gap[-1]
    if not np.isfinite(final) or final <= 0:
        return float("nan")
    idx = np.flatnonzero(gap >= share * final)
    return float(PHASE[idx[0]]) if idx.size else float("nan")


def late_share(curve: np.ndarray, from_pct: float = 90.0) -> float:
    """Share of a stance's cost spent after ``from_pct`` % of it (uniform cost: 0.1)."""
    c = np.asarray(curve)
    return float((c[-1] - np.interp(from_pct, PHASE, c)) / c[-1]) if c[-1] else float("nan")


@dataclass(frozen=True)
class SpeedShape:
    """Order-2 fit of CoT against speed (the paper's Fig. 6d fit).

    Attributes:
        speeds: the speeds fitted [m/s].
        cots: their CoT (default reading).
        a: quadratic coefficient [s²/m²].
        vertex_mps: speed of the fit's minimum/maximum [m/s].
        u_shaped: a > 0 and the vertex inside the speed range.
    """

    speeds: tuple[float, ...]
    cots: tuple[float, ...]
    a: float
    vertex_mps: float
    u_shaped: bool

    @property
    def trend(self) -> str:
        if self.u_shaped:
            return f"U-shaped, minimum at {self.vertex_mps:.2f} m/s"
        slope = np.polyfit(self.speeds, self.cots, 1)[0]
        return "decreasing" if slope < 0 else "increasing"


def speed_shape(speeds, cots) -> SpeedShape:
    """:class:`SpeedShape` of CoT values ``cots`` at ``speeds`` [m/s] (finite ones only)."""
    v = np.asarray(speeds, dtype=float)
    c = np.asarray(cots, dtype=float)
    ok = np.isfinite(c)
    v, c = v[ok], c[ok]
    if v.size < 3:
        return SpeedShape(tuple(v), tuple(c), float("nan"), float("nan"), False)
    a, b, _ = np.polyfit(v, c, 2)
    vertex = -b / (2 * a) if a != 0 else float("nan")
    return SpeedShape(tuple(v), tuple(c), float(a), float(vertex),
                      bool(a > 0 and v.min() < vertex < v.max()))


def first_touchdown_on(run_dir: str | Path, x_edge: float) -> float:
    """Time of the first touchdown with the contact point at x ≥ ``x_edge`` [s] (NaN if none)."""
    log = read_log(run_dir)
    times = []
    for side in ("left", "right"):
        on = (log[foot_column(side, "contact")] > 0.5) & (log[foot_column(side, "px")] >= x_edge)
        if on.any():
            times.append(float(log.loc[on.idxmax(), "time"]))
    return min(times) if times else float("nan")


__all__ = ["PHASE", "READING", "read_summary", "run_weight", "steady_segments", "StanceCurves",
           "stance_curves", "opening_phase", "late_share", "SpeedShape", "speed_shape",
           "first_touchdown_on"]
