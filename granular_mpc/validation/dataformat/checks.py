"""Every check of one trial, in order: :func:`check_frame`.

The checks, one file each: :mod:`.checks_columns` (header, numbers, stance labels),
:mod:`.checks_time`, :mod:`.checks_trunk` (orientation, position, velocities),
:mod:`.checks_joints`, :mod:`.checks_contact`; :mod:`.checks_rates` compares velocities
with derivatives for the last three. A new check is a new ``checks_<what>.py`` called
from here.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...columns import STANCE
from ...exceptions import DataProblem
from .checks_columns import check_header, numeric_values, stance_problems
from .checks_contact import check_contact
from .checks_joints import check_joints
from .checks_time import check_time
from .checks_trunk import check_base, check_orientation
from .robot_facts import RobotFacts
from .tolerances import FormatTolerances
from .trial_check import TrialCheck


def check_frame(df: pd.DataFrame, rows: np.ndarray, *, file: str, strict_types: bool,
                facts: RobotFacts | None, fs: float | None, speed: float | None,
                tol: FormatTolerances, problems: list[DataProblem]) -> pd.DataFrame | None:
    """Run every check on one trial; return the normalised frame, or None if it has problems.

    Args:
        df: the trial as read (not modified).
        rows: 1-based data row number of each frame row.
        file: trial file name, named by every problem.
        strict_types: numbers must have numeric dtypes (Parquet, in-memory frames).
        facts: the robot (None: unknown, the joint checks are skipped).
        fs: nominal sample rate [Hz] (None: unknown).
        speed: commanded speed [m/s] (None: unknown).
        tol: thresholds.
        problems: where the problems found are appended.

    Returns:
        A copy with the format columns as float64 and ``stance`` as text, or None.
    """
    t = TrialCheck(file, df, np.asarray(rows, dtype=np.int64), strict_types)
    required = check_header(t, facts)
    if len(df) < 2:
        t.add(f"has {len(df)} data row(s); a trial needs at least 2")
    present = [c for c in required if c in df.columns and c != STANCE]
    if len(df):
        for col in present:
            numeric_values(t, col)
    labels = None
    if STANCE in df.columns and len(df):
        raw = df[STANCE].astype(object).to_numpy()
        label_problems = stance_problems(raw, t.rows, file)
        t.problems += label_problems
        if not label_problems:
            labels = raw.astype(str)
    if len(df) >= 2:
        time_ok = check_time(t, fs, tol)
        quat_ok = check_orientation(t, tol)
        if facts is not None:
            check_joints(t, facts, time_ok, tol)
        check_base(t, time_ok, quat_ok, tol)
        check_contact(t, labels, facts, speed, time_ok, tol)
    problems += t.problems
    if t.problems:
        return None
    out = df.copy()
    for col in present:
        if out[col].dtype != np.float64:
            out[col] = t.values[col]
    out[STANCE] = out[STANCE].astype(str)
    return out


__all__ = ["check_frame"]
