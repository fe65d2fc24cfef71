"""Reading one trial file (CSV or Parquet) into a DataFrame, with its data row numbers.

Readers never repair: a malformed CSV line, a blank line or a duplicated column name is
reported as a :class:`DataProblem` naming the file and the row, and the rows that could
be read keep their row numbers in the file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from ...columns import STANCE
from ...exceptions import DataProblem
from .trial_check import rows_phrase

TrialRead = tuple[pd.DataFrame | None, np.ndarray, list[DataProblem]]
"""(frame or None if unreadable, 1-based data row number of each frame row, problems)."""


def read_csv(path: Path, file: str) -> TrialRead:
    """Read one CSV file with pyarrow; rows with the wrong number of fields are reported.

    Returns:
        (frame or None, data row number of each frame row, problems).
    """
    problems: list[DataProblem] = []
    invalid: list[Any] = []

    def on_invalid(row: Any) -> str:
        invalid.append(row)
        return "skip"

    try:
        raw = path.read_bytes()
    except OSError as exc:
        problems.append(DataProblem(file, f"cannot read: {exc.strerror or exc}"))
        return None, np.zeros(0, dtype=np.int64), problems
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        problems.append(DataProblem(file, f"not UTF-8 text: byte {exc.start} (line {line}) is "
                                    f"0x{raw[exc.start]:02x}; is this a CSV file? Save it as "
                                    "UTF-8 (or plain ASCII)"))
        return None, np.zeros(0, dtype=np.int64), problems
    try:
        size = len(raw)
        table = pacsv.read_csv(
            pa.BufferReader(raw),                # the bytes already read and checked
            # one block: column types are inferred from the whole file, and row numbers are known
            read_options=pacsv.ReadOptions(use_threads=False,
                                           block_size=int(min(max(size + 1, 1 << 16), 2**31 - 1))),
            parse_options=pacsv.ParseOptions(invalid_row_handler=on_invalid,
                                             ignore_empty_lines=False),
            convert_options=pacsv.ConvertOptions(strings_can_be_null=False,
                                                 column_types={STANCE: pa.string()}))
    except (OSError, pa.ArrowException, ValueError) as exc:
        text = str(exc).strip()
        if "Empty CSV file" in text:
            text = "file is empty (not even a header line)"
        problems.append(DataProblem(file, f"cannot read as CSV: {text}"))
        return None, np.zeros(0, dtype=np.int64), problems
    names = table.column_names
    if len(names) == 1 and any(sep in names[0] for sep in (";", "\t", "|")):
        problems.append(DataProblem(file, f"the header is one column {names[0][:60]!r}: fields "
                                    "must be separated by commas"))
        return None, np.zeros(0, dtype=np.int64), problems
    skipped = []
    for row in invalid:
        number = getattr(row, "number", None)
        data_row = None if number is None else int(number) - 1      # line 1 is the header
        if data_row is not None:
            skipped.append(data_row)
        problems.append(DataProblem(
            file, f"malformed CSV line: {row.actual_columns} field(s) where the header has "
            f"{row.expected_columns}", "", data_row))
    n_total = table.num_rows + len(skipped)
    rows = np.setdiff1d(np.arange(1, n_total + 1), np.array(skipped, dtype=np.int64))
    if rows.size != table.num_rows:        # row numbers unknown (quoted line breaks): positions
        rows = np.arange(1, table.num_rows + 1)
    if len(set(names)) != len(names):
        df, rows, problems = _table_to_frame_with_duplicates(table, file, rows, problems)
    else:
        df = table.to_pandas()
    # a blank line reads as a row of empty cells: report it as such, not as 40 empty values
    blank = np.zeros(len(df), dtype=bool)
    if len(df.columns):
        first = df.iloc[:, 0]
        blank = (first.isna() | (first.astype(object) == "")).to_numpy(dtype=bool, copy=True)
        for k in range(1, len(df.columns)):
            if not blank.any():
                break
            cells = df.iloc[:, k]
            blank &= (cells.isna() | (cells.astype(object) == "")).to_numpy(dtype=bool)
    if blank.any():
        r = rows[blank]
        problems.append(DataProblem(file, f"blank line in {rows_phrase(r)}", "", int(r.min())))
        df = df.loc[~blank].reset_index(drop=True)
        rows = rows[~blank]
    return df, rows, problems


def _table_to_frame_with_duplicates(table: Any, file: str, rows: np.ndarray,
                                    problems: list[DataProblem]) -> TrialRead:
    """Report each repeated column name; keep its first column."""
    names = table.column_names
    for name in sorted({n for n in names if names.count(n) > 1}):
        problems.append(DataProblem(file, f"column name appears {names.count(name)} times in "
                                    "the header", name))
    keep = [i for i, n in enumerate(names) if names.index(n) == i]
    return table.select(keep).to_pandas(), rows, problems


def read_parquet(path: Path, file: str) -> TrialRead:
    """Read one Parquet file; a stored pandas index is kept as a column (it is data)."""
    problems: list[DataProblem] = []
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowException, ValueError) as exc:
        problems.append(DataProblem(file, f"cannot read as Parquet: {str(exc).strip()}"))
        return None, np.zeros(0, dtype=np.int64), problems
    rows = np.arange(1, table.num_rows + 1)
    names = table.column_names
    if len(set(names)) != len(names):
        return _table_to_frame_with_duplicates(table, file, rows, problems)
    df = table.to_pandas()
    if not isinstance(df.index, pd.RangeIndex) or df.index.start != 0 or df.index.step != 1:
        df = df.reset_index()        # a stored pandas index is data: keep it as a column
    return df, rows, problems


def read_trial_file(path: Path, file: str) -> tuple[TrialRead, bool]:
    """Read a trial file with the reader its suffix calls for.

    Returns:
        (:func:`read_csv` or :func:`read_parquet` result, whether the file's column
        types are binding: True for Parquet, whose numbers must have numeric types).
    """
    if path.suffix.lower() == ".csv":
        return read_csv(path, file), False
    return read_parquet(path, file), True


__all__ = ["TrialRead", "read_csv", "read_parquet", "read_trial_file"]
