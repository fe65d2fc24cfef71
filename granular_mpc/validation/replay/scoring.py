"""Scoring replays against measurements: RMSE tables and stance/swing role channels."""

from __future__ import annotations

import json
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ...analysis.metrics import rmse_table
from ...columns import GRF_COLUMNS, INTRUSION_COLUMNS
from ...robot.model import SIDES
from ..prepare import StanceWindow, windows_frame


def role_channels(w: StanceWindow, values: Mapping[str, np.ndarray],
                  joint_names: Sequence[str]) -> dict:
    """Channels renamed into stance/swing roles (``q_stance_knee``, ``q_swing_hip_pitch``),
    plus the window's measured ``grf_*`` / ``intrusion_*`` channels."""
    out = {}
    for j in joint_names:
        side, _, rest = j.partition("_")
        if side in SIDES:
            role = "stance" if side == w.side else "swing"
            out[f"q_{role}_{rest}"] = values[f"q_{j}"]
        else:
            out[f"q_{j}"] = values[f"q_{j}"]
    for c in GRF_COLUMNS + INTRUSION_COLUMNS:
        if c in w.meas:                  # measured channels only (Dataset.channels)
            out[c] = values[c]
    return out


def rmse_tables(windows: Sequence[StanceWindow], predictions: Sequence[dict],
                channels: Sequence[str], *, phase_bins: int = 10, n_boot: int = 1000,
                seed: int = 0) -> dict[str, pd.DataFrame]:
    """RMSE tables of one model: ``by_speed_phase`` (speed × channel × phase bin),
    ``by_speed`` (whole stance, Fig. 5), ``by_phase`` (all speeds pooled), ``overall``.

    The interval unit is the trial when every speed has at least two trials, else the
    stance (``interval_unit`` column)."""
    meas = windows_frame(windows, None, channels)
    pred = windows_frame(windows, list(predictions), channels)
    per_speed = meas.groupby("commanded_speed_mps")["trial"].nunique()
    unit = "trial" if len(per_speed) and per_speed.min() >= 2 else "stance_id"
    meas["unit"] = meas[unit].astype(str)
    pred["unit"] = meas["unit"]
    kw = dict(trial_col="unit", n_boot=n_boot, seed=seed)
    out = {
        "by_speed_phase": rmse_table(pred, meas, channels, phase_bins=phase_bins, **kw),
        "by_speed": rmse_table(pred, meas, channels, phase_bins=None, **kw),
        "by_phase": rmse_table(pred, meas, channels, group_cols=(), phase_bins=phase_bins, **kw),
        "overall": rmse_table(pred, meas, channels, group_cols=(), phase_bins=None, **kw),
    }
    for t in out.values():
        t["interval_unit"] = "trial" if unit == "trial" else "stance"
    return out


def table_records(df: pd.DataFrame) -> list[dict]:
    """A table as JSON records (10 significant digits)."""
    return json.loads(df.to_json(orient="records", double_precision=10))


__all__ = ["role_channels", "rmse_tables", "table_records"]
