"""Checks of a trial's columns and cells: header, numeric values, stance labels."""

from __future__ import annotations

import difflib
import math
from typing import Iterable

import numpy as np
import pandas as pd

from ...columns import JOINT_PREFIXES, META_FILE, STANCE, STANCE_LABELS, TIME, format_columns
from .channels import ChannelGroup, ChannelSet
from ...exceptions import DataProblem
from .robot_facts import RobotFacts
from .trial_check import TrialCheck, rows_phrase

#: Cell texts that the CSV reader turns into "missing" (pyarrow's default null values).
_NULL_WORDS = frozenset({"", "#n/a", "#n/a n/a", "#na", "-1.#ind", "-1.#qnan", "-nan", "1.#ind",
                         "1.#qnan", "n/a", "na", "null", "nan"})
_MAX_LABELS = 5       # distinct bad stance labels reported one by one


def close_hint(name: str, candidates: Iterable[str]) -> str:
    """A did-you-mean hint for column ``name`` among ``candidates``, or ``""``."""
    candidates = list(candidates)
    for c in candidates:
        if c.strip().lower() == name.lower():
            return f"; column {c!r} differs only in case or spaces"
    match = difflib.get_close_matches(name, candidates, n=1, cutoff=0.75)
    return f"; did you mean {match[0]!r}?" if match else ""


def check_header(t: TrialCheck, facts: RobotFacts | None,
                 channels: ChannelSet | None = None) -> list[str]:
    """Column names: non-text or empty names, missing format columns, unknown joints, and
    columns of channel groups that ``meta.yaml`` does not declare.

    Args:
        t: the trial's working state (problems are added to it).
        facts: the robot (None: unknown, joint columns not required).
        channels: the measured groups (None or undeclared: every format column is
            required, ``stance`` included; declared: ``time`` and the declared groups'
            columns, ``stance`` optional, undeclared groups' columns forbidden).

    Returns:
        The format columns required of this trial (without the joint columns when the
        robot is unknown).
    """
    cols = list(t.df.columns)
    for i, c in enumerate(cols):
        if not isinstance(c, str):
            t.add(f"column {i + 1} has a non-text name {c!r}", str(c))
        elif not c.strip():
            t.add(f"column {i + 1} has an empty name (a trailing comma in the header?)", c)
    names = [c for c in cols if isinstance(c, str)]
    joints = facts.joints if facts is not None else ()
    present = set(names)
    if channels is None or not channels.declared:
        required = format_columns(joints)
        for col in required:
            if col not in present:
                t.add(f"required column is missing"
                      f"{close_hint(col, [c for c in names if c not in required])}", col)
    else:
        required = [TIME] + channels.columns(joints)
        _declared_groups(t, channels, joints, names, required)
    if facts is not None:
        for col in names:
            for prefix in JOINT_PREFIXES:
                if col.startswith(prefix):
                    joint = col[len(prefix):]
                    if joint not in facts.joints:
                        t.add(f"'{joint}' is not an actuated joint of robot {facts.name!r} "
                              f"(joints: {', '.join(facts.joints)}){close_hint(joint, facts.joints)}",
                              col)
                    break
    return required


def _declared_groups(t: TrialCheck, channels: ChannelSet, joints: tuple[str, ...],
                     names: list[str], required: list[str]) -> None:
    """Declared groups must be complete, undeclared ones absent (``meta.yaml`` channels)."""
    present = set(names)
    if TIME not in present:
        t.add(f"required column is missing{close_hint(TIME, names)}", TIME)
    for group in ChannelGroup:
        cols = group.columns(joints)
        have = [c for c in cols if c in present]
        if group in channels:
            if not have and cols:
                t.add(f"channel group '{group.value}' is declared in {META_FILE} channels but "
                      f"the file has none of its columns ({', '.join(cols)}): remove it from "
                      "channels or add the columns", ",".join(cols))
                continue
            for col in cols:
                if col not in present:
                    t.add(f"required column of the declared channel group '{group.value}' "
                          f"({META_FILE} channels) is missing"
                          f"{close_hint(col, [c for c in names if c not in required])}", col)
        elif have:
            t.add(f"channel group '{group.value}' is not declared in {META_FILE} channels but "
                  f"the file has its column(s) {', '.join(have)}: add '{group.value}' to "
                  "channels, or remove the columns (a channel that was not measured is absent, "
                  "never zero-filled)", ",".join(have))


def numeric_values(t: TrialCheck, col: str) -> None:
    """Convert one numeric column to float64 and report non-numeric, empty/NaN, ±inf cells.

    CSV columns holding text are parsed cell by cell (to name the bad cells); in Parquet
    and in-memory frames a numeric column must have a numeric type.
    """
    s = t.df[col]
    first = int(t.rows[0]) if len(s) else None
    bad_text = np.zeros(len(s), dtype=bool)
    if pd.api.types.is_bool_dtype(s.dtype):
        t.add("holds true/false values; format v1 wants numbers", col, first)
        return
    if pd.api.types.is_numeric_dtype(s.dtype) and not pd.api.types.is_complex_dtype(s.dtype):
        v = s.to_numpy(dtype=np.float64, na_value=np.nan)
    elif t.strict_types:
        cells = s.astype(object).to_numpy()
        if not all(x is None or (isinstance(x, (int, float, np.integer, np.floating))
                                 and not isinstance(x, (bool, np.bool_))) for x in cells):
            t.add(f"has type {s.dtype}; format v1 wants a floating-point column", col, first)
            return
        v = np.array([np.nan if x is None else float(x) for x in cells], dtype=np.float64)
    else:
        text = np.array(["" if x is None or (isinstance(x, float) and math.isnan(x))
                         else str(x).strip() for x in s.astype(object).to_numpy()], dtype=object)
        null_like = np.array([x.lower() in _NULL_WORDS for x in text], dtype=bool)
        parsed = pd.to_numeric(pd.Series(np.where(null_like, None, text), dtype=object),
                               errors="coerce")
        v = parsed.to_numpy(dtype=np.float64, na_value=np.nan)
        bad_text = np.isnan(v) & ~null_like
        if bad_text.any():
            examples = ", ".join(repr(x) for x in list(dict.fromkeys(text[bad_text]))[:3])
            t.add_rows(col, f"non-numeric values (e.g. {examples})", bad_text)
    t.add_rows(col, "empty or NaN values", np.isnan(v) & ~bad_text)
    t.add_rows(col, "infinite values", np.isinf(v))
    t.values[col] = v
    if np.isfinite(v).all():
        t.clean.add(col)


def stance_problems(labels: np.ndarray, rows: np.ndarray, file: str) -> list[DataProblem]:
    """Bad or missing stance labels, one problem per distinct bad label (up to a few)."""
    out: list[DataProblem] = []
    missing = np.array([x is None or (isinstance(x, float) and math.isnan(x))
                        or (isinstance(x, str) and not x.strip()) for x in labels], dtype=bool)
    if missing.any():
        r = rows[missing]
        out.append(DataProblem(file, f"empty stance label in {rows_phrase(r)}", STANCE, int(r.min())))
    text = np.array([str(x) for x in labels], dtype=object)
    bad = ~missing & ~np.isin(text, STANCE_LABELS)
    distinct = list(dict.fromkeys(text[bad]))
    for k, label in enumerate(distinct):
        mask = bad & (text == label) if k < _MAX_LABELS else bad & ~np.isin(text, distinct[:_MAX_LABELS])
        r = rows[mask]
        if k < _MAX_LABELS:
            hint = (" (labels are lower case)" if label.strip().lower() in STANCE_LABELS
                    else "")
            what = f"stance label {label!r} is not left, right or none{hint}"
        else:
            what = f"{len(distinct) - _MAX_LABELS} more stance labels that are not left, right or none"
        out.append(DataProblem(file, f"{what} in {rows_phrase(r)}", STANCE, int(r.min())))
        if k >= _MAX_LABELS:
            break
    return out


__all__ = ["close_hint", "check_header", "numeric_values", "stance_problems"]
