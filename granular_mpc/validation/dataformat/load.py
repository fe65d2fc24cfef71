"""Loading a data set folder: :func:`load_dataset` (or every problem at once) and
:func:`check_dataset` (the problems only)."""

from __future__ import annotations

from pathlib import Path
from types import MappingProxyType

import pandas as pd
import yaml

from ...columns import META_FILE
from ...exceptions import DataFormatError, DataProblem, GranularMpcError
from .checks import check_frame
from .checks_meta import check_meta
from .dataset import Dataset
from .meta import SUFFIXES
from .readers import read_trial_file
from .stance_derive import StanceDerivation, StanceSource
from .robot_facts import load_robot_facts
from .tolerances import FormatTolerances

_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)     # libyaml when available


def _resolve_folder(path: str | Path) -> Path:
    """The data set folder, given the folder or its ``meta.yaml``."""
    p = Path(path).expanduser()
    if p.is_file() and p.name == META_FILE:
        return p.parent
    return p


def _load(path: str | Path,
          tol: FormatTolerances | None) -> tuple[Dataset | None, list[DataProblem], Path]:
    """Check everything; return (the data set if it has no problem, the problems, the folder)."""
    folder = _resolve_folder(path)
    tol = tol or FormatTolerances()
    problems: list[DataProblem] = []
    if not folder.is_dir():
        problems.append(DataProblem(str(folder), "data set folder not found"))
        return None, problems, folder
    meta_path = folder / META_FILE
    if not meta_path.is_file():
        problems.append(DataProblem(META_FILE, f"{META_FILE} is missing: a data set folder needs "
                                    "it (docs/data-format.md)"))
        return None, problems, folder
    try:
        raw = yaml.load(meta_path.read_text(encoding="utf-8"), Loader=_YAML_LOADER)
    except (OSError, UnicodeDecodeError) as exc:
        problems.append(DataProblem(META_FILE, f"cannot read: {exc}"))
        return None, problems, folder
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        problems.append(DataProblem(META_FILE, f"malformed YAML{where}: {problem}"))
        return None, problems, folder
    if not isinstance(raw, dict):
        problems.append(DataProblem(META_FILE, "top level must be a mapping of keys, got "
                                    f"{type(raw).__name__}"))
        return None, problems, folder
    view = check_meta(raw, tol, problems)
    if view is None:
        return None, problems, folder
    facts = None
    if view.robot is not None:
        try:
            facts = load_robot_facts(view.robot, folder)
        except GranularMpcError as exc:
            text = str(exc)
            text = text if text.startswith("robot") else f"robot: {text}"
            problems.append(DataProblem(META_FILE, f"{text}; joint columns not checked"))
    listed = {f.lower() for _, f, _ in view.trials}
    for p in sorted(folder.iterdir()):
        if p.is_file() and p.suffix.lower() in SUFFIXES.values() and p.name.lower() not in listed:
            problems.append(DataProblem(p.name, "trial file is not listed under trials in "
                                        f"{META_FILE} (list it, or move it out of the folder)"))
    frames: dict[str, pd.DataFrame] = {}
    derivations: dict[str, StanceDerivation] = {}
    for name, file, speed in view.trials:
        p = folder / file
        if not p.is_file():
            problems.append(DataProblem(file, f"trial file of trial {name!r} not found in "
                                        f"{folder}"))
            continue
        (df, rows, read_problems), strict_types = read_trial_file(p, file)
        problems += read_problems
        if df is None:
            continue
        out = check_frame(df, rows, file=file, strict_types=strict_types,
                          facts=facts, fs=view.sample_rate_hz, speed=speed, tol=tol,
                          problems=problems, channels=view.channels)
        if out is not None and not read_problems:
            frames[name] = out.frame
            if out.stance is not None:
                derivations[name] = out.stance
    source = _stance_source(view.trials, frames, derivations, problems)
    if problems or view.meta is None or facts is None:
        return None, problems, folder
    return Dataset(path=folder.resolve(), meta=view.meta, trials=MappingProxyType(frames),
                   joint_names=facts.joints, channels=view.channels, stance_source=source,
                   stance_derivations=MappingProxyType(derivations)), problems, folder


def _stance_source(trials: list[tuple[str, str, float | None]], frames: dict[str, pd.DataFrame],
                   derivations: dict[str, StanceDerivation],
                   problems: list[DataProblem]) -> StanceSource:
    """One stance source for the data set; a mix is a problem of the unlabelled files."""
    sources = {name: (derivations[name].source if name in derivations else "measured")
               for name in frames}
    kinds = set(sources.values())
    if len(kinds) > 1:
        files = dict((n, f) for n, f, _ in trials)
        counts = {k: sum(v == k for v in sources.values()) for k in sorted(kinds)}
        text = ", ".join(f"{k}: {c} trial(s)" for k, c in counts.items())
        for name, src in sources.items():
            if src != "measured" or "measured" not in kinds:
                problems.append(DataProblem(
                    files[name], f"stance labels come from {src} here but not in other trials "
                    f"({text}): give every trial a stance column, or none", "stance"))
        return "measured"
    return kinds.pop() if kinds else "measured"



def check_dataset(path: str | Path, *, tolerances: FormatTolerances | None = None) -> list[DataProblem]:
    """Every problem of the data set in folder ``path`` (empty list: it loads cleanly).

    Args:
        path: the data set folder (or its ``meta.yaml``).
        tolerances: thresholds of the checks (default :class:`FormatTolerances`).
    """
    return _load(path, tolerances)[1]


def load_dataset(path: str | Path, *, tolerances: FormatTolerances | None = None) -> Dataset:
    """Load and check a format-v1 data set.

    Args:
        path: the data set folder (or its ``meta.yaml``).
        tolerances: thresholds of the checks (default :class:`FormatTolerances`).

    Returns:
        The data set, every check passed.

    Raises:
        DataFormatError: listing every problem found (file, column, first row, message).
    """
    dataset, problems, folder = _load(path, tolerances)
    if problems or dataset is None:
        raise DataFormatError(problems, root=str(folder))
    return dataset


__all__ = ["check_dataset", "load_dataset"]
