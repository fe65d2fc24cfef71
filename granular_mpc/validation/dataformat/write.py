"""Writing a data set (:func:`write_dataset`), and checking in-memory trials before
writing them (:func:`check_trials`)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal, Mapping

import numpy as np
import pandas as pd
import yaml

from ...columns import META_FILE
from ...config import validate
from ...exceptions import ConfigError, DataFormatError, DataProblem, OutputError
from .channels import ChannelSet
from .checks import check_frame
from .meta import SUFFIXES, DatasetMeta
from .robot_facts import load_robot_facts
from .tolerances import FormatTolerances


def check_trials(meta: DatasetMeta | Mapping[str, Any], trials: Mapping[str, pd.DataFrame], *,
                 tolerances: FormatTolerances | None = None) -> list[DataProblem]:
    """Every format-v1 problem of in-memory trials (before writing them).

    Numeric columns must have numeric dtypes here (as in Parquet). Problems name the
    trial file given in ``meta`` and 1-based data rows (row 1 = ``df.iloc[0]``).

    Args:
        meta: the data set's meta (validated with :class:`DatasetMeta`).
        trials: trial name → DataFrame; the names must be those of ``meta.trials``.
        tolerances: thresholds of the checks.

    Raises:
        ConfigError: ``meta`` is invalid.
        ConfigError, ModelError: the robot cannot be loaded.
    """
    meta = meta if isinstance(meta, DatasetMeta) else validate(DatasetMeta, dict(meta),
                                                               source="meta")
    tol = tolerances or FormatTolerances()
    facts = load_robot_facts(meta.robot, None)
    problems: list[DataProblem] = []
    for name in trials:
        if name not in meta.trials:
            problems.append(DataProblem(str(name), "trial has data but no entry under trials "
                                        "in the meta"))
    for name, entry in meta.trials.items():
        if name not in trials:
            problems.append(DataProblem(entry.file, f"trial {name!r} is listed in the meta but "
                                        "has no data"))
            continue
        df = trials[name]
        if not isinstance(df, pd.DataFrame):
            problems.append(DataProblem(entry.file, f"trial {name!r} is a {type(df).__name__}, "
                                        "not a pandas DataFrame"))
            continue
        check_frame(df, np.arange(1, len(df) + 1), file=entry.file, strict_types=True,
                    facts=facts, fs=meta.sample_rate_hz, speed=entry.commanded_speed_mps,
                    tol=tol, problems=problems, channels=ChannelSet.of(meta.channels))
    return problems


def write_dataset(path: str | Path, meta: DatasetMeta | Mapping[str, Any],
                  trials: Mapping[str, pd.DataFrame],
                  format: Literal["csv", "parquet"] = "csv", *, overwrite: bool = False,
                  check: bool = True, tolerances: FormatTolerances | None = None) -> Path:
    """Write a format-v1 data set: ``meta.yaml`` plus ``<trial>.csv`` or ``<trial>.parquet``.

    Trial files are named after their trials; the ``file`` entries of ``meta`` are set
    accordingly (so a CSV data set's meta can be written as Parquet). Columns are written
    in the DataFrame's order, without its index; CSV floats are written with enough
    digits to read back bit-for-bit. Each file is written to a temporary name and
    renamed; ``meta.yaml`` is written last, so an interrupted write never looks complete.
    The caller's objects are not modified.

    Args:
        path: the data set folder (created if needed).
        meta: the meta (``trials`` entries may omit ``file``).
        trials: trial name → DataFrame with the format-v1 columns (extra columns allowed).
        format: ``"csv"`` or ``"parquet"``.
        overwrite: replace ``meta.yaml`` and trial files already in the folder. Other
            ``*.csv`` / ``*.parquet`` files there are left alone (and the loader will
            report them as unlisted).
        check: run :func:`check_trials` first and refuse to write a data set that would
            not load. Turn off only to produce deliberately broken data (tests).
        tolerances: thresholds of the checks.

    Returns:
        The data set folder.

    Raises:
        ConfigError: invalid ``meta`` or ``format``.
        DataFormatError: ``check`` found problems (nothing was written).
        OutputError: the folder or a file cannot be written, or exists and not ``overwrite``.
    """
    if format not in SUFFIXES:
        raise ConfigError(f"unknown data set format {format!r}", key="format",
                          value=format, allowed="csv, parquet")
    suffix = SUFFIXES[format]
    data = meta.model_dump(mode="json") if isinstance(meta, DatasetMeta) else dict(meta)
    entries = data.get("trials")
    if isinstance(entries, Mapping):
        data["trials"] = {name: ({**dict(entry), "file": f"{name}{suffix}"}
                                 if isinstance(entry, Mapping) else entry)
                          for name, entry in entries.items()}
    meta_obj = validate(DatasetMeta, data, source="write_dataset meta")
    if check:
        problems = check_trials(meta_obj, trials, tolerances=tolerances)
        if problems:
            raise DataFormatError(problems, root=str(path))
    else:
        mismatch = ([DataProblem(f"{n}{suffix}", f"trial {n!r} is listed in the meta but has no "
                                 "data") for n in meta_obj.trials if n not in trials]
                    + [DataProblem(str(n), "trial has data but no entry under trials in the meta")
                       for n in trials if n not in meta_obj.trials])
        if mismatch:
            raise DataFormatError(mismatch, root=str(path))
    folder = Path(path).expanduser()
    targets = [folder / META_FILE] + [folder / e.file for e in meta_obj.trials.values()]
    existing = [p.name for p in targets if p.exists()]
    if existing and not overwrite:
        raise OutputError(f"{folder} already holds {', '.join(existing)} (--overwrite, or "
                          "overwrite=True from Python, replaces them)")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        for name, entry in meta_obj.trials.items():
            target = folder / entry.file
            tmp = folder / f".{entry.file}.tmp"
            df = trials[name]
            if format == "csv":
                df.to_csv(tmp, index=False, encoding="utf-8", lineterminator="\n")
            else:
                df.to_parquet(tmp, index=False)
            os.replace(tmp, target)
        tmp = folder / f".{META_FILE}.tmp"
        tmp.write_text(yaml.safe_dump(meta_obj.model_dump(mode="json", exclude_defaults=True),
                                      sort_keys=False, allow_unicode=True), encoding="utf-8")
        os.replace(tmp, folder / META_FILE)
    except OSError as exc:
        raise OutputError(f"cannot write the data set {folder}: {exc}") from None
    return folder


__all__ = ["check_trials", "write_dataset"]
