"""Reading run-log rows into the numbers the scene draws.

One extracted row is a flat vector: the configuration ``q`` (``nq``, Pinocchio order:
base position [m, W], base quaternion (x, y, z, w), joint angles [rad]) followed, per side
in :data:`~granular_mpc.robot.model.SIDES` order, by seven numbers: ``contact`` (0/1),
``grf_x, grf_y, grf_z`` (force of the ground on the foot [N, W]) and ``px, py, pz``
(contact point ``C`` [m, W]). Column names come from :mod:`granular_mpc.columns`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable, Mapping

import numpy as np
import pinocchio as pin

from ...columns import (BASE_POSITION, BASE_QUATERNION, FOOT_CONTACT, FOOT_POINT, GRF_COLUMNS,
                        TIME, foot_column, joint_columns)
from ...exceptions import DataFormatError, DataProblem
from ...robot.model import SIDES, Biped

BASE_Q_COLUMNS = BASE_POSITION + BASE_QUATERNION[1:] + BASE_QUATERNION[:1]
"""Log columns of ``q[0:7]``: position, then the quaternion in Pinocchio's (x, y, z, w) order."""
FOOT_KEYS = (FOOT_CONTACT,) + GRF_COLUMNS + FOOT_POINT
"""Per-foot names (with :func:`~granular_mpc.columns.foot_column`) of one side's seven numbers."""
FOOT_STRIDE = len(FOOT_KEYS)
"""Numbers per side after ``q`` in an extracted row."""


class LogColumns:
    """Maps log columns to extracted rows, for dict rows and DataFrames.

    Args:
        biped: the robot (joint names, ``nq``, Pinocchio index of each joint angle).
        available: the log's columns; if given, missing columns are reported at once
            (per-foot columns are optional, but all seven of a side or none).
        source: name of the log in error messages.

    Raises:
        DataFormatError: a base-pose or joint-angle column is missing, or a side has only
            some of its per-foot columns.
    """

    def __init__(self, biped: Biped, available: Iterable[str] | None = None,
                 source: str = "log") -> None:
        self.biped = biped
        self.joint_cols = joint_columns(biped.joint_names, "q")
        required = list(BASE_Q_COLUMNS) + self.joint_cols
        self.sides: list[str] = []
        if available is None:
            self.sides = list(SIDES)
        else:
            have = set(available)
            problems = [DataProblem(source, "required column is missing", column=c)
                        for c in required if c not in have]
            for side in SIDES:
                cols = [foot_column(side, k) for k in FOOT_KEYS]
                present = [c for c in cols if c in have]
                if len(present) == len(cols):
                    self.sides.append(side)
                elif present:  # some but not all: a broken log, say so
                    problems += [DataProblem(source, "per-foot column is missing", column=c)
                                 for c in cols if c not in have]
            if problems:
                raise DataFormatError(problems, root=source)
        self.nq = biped.model.nq

    @property
    def width(self) -> int:
        """Length of one extracted row."""
        return self.nq + FOOT_STRIDE * len(SIDES)

    def from_row(self, row: Mapping[str, Any]) -> np.ndarray:
        """Extract one row (a mapping such as a dict or a pandas Series).

        Raises:
            DataFormatError: a base-pose or joint-angle column is missing.
        """
        b = self.biped
        out = np.zeros(self.width)
        q = out[: self.nq]
        q[:] = pin.neutral(b.model)
        try:
            for i, c in enumerate(BASE_Q_COLUMNS):
                q[i] = float(row[c])
            for i, c in enumerate(self.joint_cols):
                q[b.idx_q[i]] = float(row[c])
            for k, side in enumerate(SIDES):
                if side not in self.sides:
                    continue
                o = self.nq + FOOT_STRIDE * k
                for j, key in enumerate(FOOT_KEYS):
                    out[o + j] = float(row.get(foot_column(side, key), 0.0))
        except KeyError as exc:
            raise DataFormatError([DataProblem("row", "required column is missing",
                                               column=str(exc.args[0]))]) from None
        return out

    def from_frame(self, df) -> np.ndarray:
        """Extract every row of a DataFrame: array (rows, :attr:`width`)."""
        b = self.biped
        out = np.zeros((len(df), self.width))
        out[:, : self.nq] = pin.neutral(b.model)
        out[:, 0:7] = df[list(BASE_Q_COLUMNS)].to_numpy(dtype=float)
        out[:, b.idx_q] = df[self.joint_cols].to_numpy(dtype=float)
        for k, side in enumerate(SIDES):
            if side in self.sides:
                o = self.nq + FOOT_STRIDE * k
                cols = [foot_column(side, key) for key in FOOT_KEYS]
                out[:, o:o + FOOT_STRIDE] = df[cols].to_numpy(dtype=float)
        return out


@dataclass(frozen=True)
class LogArrays:
    """A whole log, extracted.

    Attributes:
        columns: the :class:`LogColumns` used (``columns.sides``: feet with per-foot data).
        times: log times [s], shape (n,), finite and non-decreasing.
        values: extracted rows, shape (n, ``columns.width``).
    """

    columns: LogColumns
    times: np.ndarray
    values: np.ndarray


def log_arrays(biped: Biped, log_df, source: str = "log") -> LogArrays:
    """Check a log's time column and extract every row.

    Raises:
        DataFormatError: no rows, no ``time``, non-finite or decreasing time, missing columns.
    """
    if log_df is None or len(log_df) == 0:
        raise DataFormatError([DataProblem(source, "the log has no rows")], root=source)
    if TIME not in log_df.columns:
        raise DataFormatError([DataProblem(source, "required column is missing", column=TIME)],
                              root=source)
    cols = LogColumns(biped, log_df.columns, source=source)
    times = log_df[TIME].to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(times))
    if bad.size:
        raise DataFormatError([DataProblem(source, "time is not finite", column=TIME,
                                           row=int(bad[0]))], root=source)
    back = np.flatnonzero(np.diff(times) < 0)
    if back.size:
        raise DataFormatError([DataProblem(source, "time goes backwards", column=TIME,
                                           row=int(back[0]) + 1)], root=source)
    return LogArrays(cols, times, cols.from_frame(log_df))


def touchdowns(values: np.ndarray, times: np.ndarray,
               nq: int) -> list[tuple[float, str, float, float]]:
    """Touchdowns in extracted rows: a foot's contact going 0 → 1 (or 1 in the first row).

    Returns:
        ``(time [s], side, x [m], y [m])`` of the contact point ``C`` at each touchdown, in
        time order.
    """
    out = []
    for k, side in enumerate(SIDES):
        o = nq + FOOT_STRIDE * k
        c = values[:, o] > 0.5
        starts = np.flatnonzero(c & ~np.concatenate([[False], c[:-1]]))
        for i in starts:
            x, y = values[i, o + 4], values[i, o + 5]
            if np.isfinite(x) and np.isfinite(y):
                out.append((float(times[i]), side, float(x), float(y)))
    out.sort(key=lambda e: e[0])
    return out


__all__ = ["LogColumns", "LogArrays", "log_arrays", "touchdowns", "BASE_Q_COLUMNS", "FOOT_KEYS",
           "FOOT_STRIDE"]
