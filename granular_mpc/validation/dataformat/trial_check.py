"""The working state of the checks of one trial file, and how its problems are worded.

Every check of :mod:`.checks` receives one :class:`TrialCheck`, reads the converted
columns from it and adds its problems to it. Rows are 1-based *data* row numbers (row 1
is the first row after the header); repeated problems of one kind in one column are
grouped into one problem listing the runs of rows (:func:`rows_phrase`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ...exceptions import DataProblem

RAD_PER_DEG = math.pi / 180.0
"""One degree in radians (the checks' unit-mistake hints)."""
_MAX_RUNS = 10        # runs of rows spelled out per problem


def rows_phrase(rows: np.ndarray) -> str:
    """``"row 7"`` or ``"rows 12–40, 57 (30 rows)"``; long lists end in ``… and N more runs``.

    Args:
        rows: 1-based data row numbers (any order, repeats allowed).
    """
    rows = np.unique(np.asarray(rows, dtype=np.int64))
    if rows.size == 1:
        return f"row {rows[0]}"
    breaks = np.flatnonzero(np.diff(rows) != 1)
    starts = np.r_[rows[0], rows[breaks + 1]]
    ends = np.r_[rows[breaks], rows[-1]]
    parts = [f"{a}" if a == b else f"{a}–{b}" for a, b in
             zip(starts[:_MAX_RUNS].tolist(), ends[:_MAX_RUNS].tolist())]
    if starts.size > _MAX_RUNS:
        parts.append(f"… and {starts.size - _MAX_RUNS} more runs")
    return f"rows {', '.join(parts)} ({rows.size} rows)"


@dataclass
class TrialCheck:
    """Working state of the checks of one trial file.

    Attributes:
        file: trial file name (as in ``meta.yaml``), named by every problem.
        df: the trial as read.
        rows: 1-based data row number of each frame row.
        strict_types: Parquet / in-memory: numbers must have numeric dtypes.
        problems: problems found so far.
        values: column → float64 values, NaN where a cell is bad.
        clean: columns that are fully finite.
        flagged: columns with a (suspected) unit or sign problem.
        degrees: angle columns found to be in degrees.
    """

    file: str
    df: pd.DataFrame
    rows: np.ndarray
    strict_types: bool
    problems: list[DataProblem] = field(default_factory=list)
    values: dict[str, np.ndarray] = field(default_factory=dict)
    clean: set[str] = field(default_factory=set)
    flagged: set[str] = field(default_factory=set)
    degrees: set[str] = field(default_factory=set)

    def add(self, message: str, column: str = "", row: int | None = None) -> None:
        """One problem of this file."""
        self.problems.append(DataProblem(self.file, message, column,
                                         None if row is None else int(row)))

    def add_rows(self, column: str, what: str, mask: np.ndarray, detail: str = "") -> None:
        """One problem for every row where ``mask`` is true: ``"<what> in rows …<detail>"``."""
        idx = np.flatnonzero(mask)
        if idx.size:
            rows = self.rows[idx]
            self.add(f"{what} in {rows_phrase(rows)}{detail}", column, int(rows.min()))

    def ok(self, *columns: str) -> bool:
        """True if every column is present, fully finite and not suspected of a wrong unit."""
        return all(c in self.clean and c not in self.flagged for c in columns)


__all__ = ["RAD_PER_DEG", "rows_phrase", "TrialCheck"]
