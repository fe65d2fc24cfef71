"""Every check of one trial, in order: :func:`check_frame`.

The checks, one file each: :mod:`.checks_columns` (header, numbers, stance labels),
:mod:`.checks_time`, :mod:`.checks_trunk` (orientation, position, velocities),
:mod:`.checks_joints`, :mod:`.checks_contact`, :mod:`.checks_stance` (left/right swapped
against the kinematics); :mod:`.checks_rates` compares velocities
with derivatives for the last three. A new check is a new ``checks_<what>.py`` called
from here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...columns import FOOT_SIDES, STANCE, foot_column
from ...exceptions import DataProblem
from .channels import ChannelSet
from .checks_columns import check_header, numeric_values, stance_problems
from .checks_contact import check_contact
from .checks_joints import check_joints
from .checks_stance import check_stance_sides
from .checks_time import check_time
from .checks_trunk import check_base, check_orientation
from .robot_facts import RobotFacts
from .stance_derive import StanceDerivation, derive_stance
from .tolerances import FormatTolerances
from .trial_check import TrialCheck


@dataclass(frozen=True)
class CheckedTrial:
    """One trial that passed every check.

    Attributes:
        frame: a copy with the format columns as float64 and ``stance`` as text.
        stance: how the ``stance`` labels were derived, or None if the file has them.
    """

    frame: pd.DataFrame
    stance: StanceDerivation | None = None


def check_frame(df: pd.DataFrame, rows: np.ndarray, *, file: str, strict_types: bool,
                facts: RobotFacts | None, fs: float | None, speed: float | None,
                tol: FormatTolerances, problems: list[DataProblem],
                channels: ChannelSet | None = None) -> CheckedTrial | None:
    """Run every check on one trial; return the checked trial, or None if it has problems.

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
        channels: the measured groups (default: all, undeclared). With declared
            channels a missing ``stance`` column is derived (:mod:`.stance_derive`).

    Returns:
        The checked trial, or None.
    """
    channels = channels or ChannelSet.all()
    t = TrialCheck(file, df, np.asarray(rows, dtype=np.int64), strict_types)
    required = check_header(t, facts, channels)
    if len(df) < 2:
        t.add(f"has {len(df)} data row(s); a trial needs at least 2")
    present = [c for c in required if c in df.columns and c != STANCE]
    if len(df):
        for col in present:
            numeric_values(t, col)
    labels = None
    derived: tuple[np.ndarray, StanceDerivation] | None = None
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
        if STANCE not in df.columns and channels.declared and not t.problems:
            derived = _derive(t, facts, channels)
        check_contact(t, labels if derived is None else derived[0], facts, speed, time_ok, tol)
        if labels is not None and not t.problems:
            check_stance_sides(t, labels, facts)
    problems += t.problems
    if t.problems:
        return None
    out = df.copy()
    for col in present:
        if out[col].dtype != np.float64:
            out[col] = t.values[col]
    if derived is None:
        out[STANCE] = out[STANCE].astype(str)
        return CheckedTrial(out)
    out.insert(min(1, len(out.columns)), STANCE, derived[0].astype(str))
    return CheckedTrial(out, derived[1])


def _derive(t: TrialCheck, facts: RobotFacts | None,
            channels: ChannelSet) -> tuple[np.ndarray, StanceDerivation] | None:
    """Derived stance labels of a trial without a ``stance`` column (problems added to t)."""
    per_foot = [foot_column(s, "grf_z") for s in FOOT_SIDES]
    if all(c in t.df.columns for c in per_foot):
        for col in per_foot:
            numeric_values(t, col)
        if t.problems:
            return None
    found = derive_stance(t.values, facts, channels)
    if isinstance(found, str):
        t.add(f"the stance column is missing and cannot be derived: {found}", STANCE)
        return None
    return found


__all__ = ["CheckedTrial", "check_frame"]
