"""Checks of ``meta.yaml``: every problem as a :class:`DataProblem`, and what can be salvaged.

When ``meta.yaml`` is invalid, the trial files are still checked as far as the meta
allows (:class:`MetaView`), so that one load reports every problem at once.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from typing import Any

from pydantic import ValidationError

from ...columns import META_FILE
from ...config import format_location, model_fields_at
from ...exceptions import DataProblem
from .channels import ChannelSet
from .meta import SCHEMA_VERSION, DatasetMeta, file_name_error, shared_files
from .tolerances import FormatTolerances


@dataclass
class MetaView:
    """What the trial checks need from meta.yaml — also when meta.yaml has problems.

    Attributes:
        meta: the validated meta, or None if it has problems.
        robot: robot name, if one could be read.
        sample_rate_hz: nominal sample rate [Hz], if a valid one could be read.
        trials: (name, file, commanded speed [m/s] or None) of every readable trial entry.
        channels: the declared channel groups (all, undeclared, when ``channels`` is
            absent or unreadable).
    """

    meta: DatasetMeta | None
    robot: str | None
    sample_rate_hz: float | None
    trials: list[tuple[str, str, float | None]]
    channels: ChannelSet = field(default_factory=ChannelSet.all)


def _salvage_channels(raw: Any) -> ChannelSet:
    """The ``channels`` list of an invalid meta, if it is readable on its own."""
    try:
        return ChannelSet.of(raw) if isinstance(raw, list) and raw else ChannelSet.all()
    except (TypeError, ValueError):
        return ChannelSet.all()


def pydantic_problems(exc: ValidationError, file: str) -> list[DataProblem]:
    """One DataProblem per pydantic error, worded like :func:`granular_mpc.config.validate`."""
    out = []
    for err in exc.errors():
        loc = list(err["loc"])
        typ = err["type"]
        if loc and loc[-1] == "[key]":
            key = format_location(loc[:-2])
            msg = (f"trial name {loc[-2]!r} is not valid: use letters, digits, '_', '-' and "
                   "'.', starting with a letter or a digit")
        else:
            key = format_location(loc)
            if typ == "extra_forbidden":
                valid = model_fields_at(DatasetMeta, loc[:-1])
                close = difflib.get_close_matches(str(loc[-1]), valid, n=1, cutoff=0.5)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                msg = f"unknown key '{loc[-1]}'{hint} (valid keys here: {', '.join(valid)})"
            elif typ == "missing":
                msg = "required key is missing"
            elif typ == "value_error":
                msg = str(err["msg"]).removeprefix("Value error, ")
            else:
                msg = f"{err['msg']} (got {err.get('input')!r})"
        out.append(DataProblem(file, f"{key}: {msg}" if key else msg))
    return out


def _finite_number(value: Any) -> float | None:
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def check_meta(raw: dict[str, Any], tol: FormatTolerances,
               problems: list[DataProblem]) -> MetaView | None:
    """Validate the meta mapping; salvage what the trial checks need if it is invalid.

    Args:
        raw: the parsed ``meta.yaml``.
        tol: thresholds (``max_commanded_speed``).
        problems: where the problems found are appended.

    Returns:
        What the trial checks can use, or None when the schema version is missing or
        unsupported (then nothing else is checked).
    """
    version = raw.get("schema_version")
    if "schema_version" not in raw:
        problems.append(DataProblem(META_FILE, "schema_version: required key is missing "
                                    f"(this is format v{SCHEMA_VERSION}: write "
                                    f"'schema_version: {SCHEMA_VERSION}')"))
        return None
    if type(version) is not int or version != SCHEMA_VERSION:
        problems.append(DataProblem(META_FILE, f"schema_version: {version!r} is not supported "
                                    f"(this loader reads format v{SCHEMA_VERSION})"))
        return None
    try:
        meta = DatasetMeta.model_validate(raw)
    except ValidationError as exc:
        problems += pydantic_problems(exc, META_FILE)
        meta = None
    if meta is not None:
        view = MetaView(meta, meta.robot, meta.sample_rate_hz,
                        [(n, t.file, t.commanded_speed_mps) for n, t in meta.trials.items()],
                        ChannelSet.of(meta.channels))
    else:
        robot = raw.get("robot") if isinstance(raw.get("robot"), str) and raw["robot"] else None
        rate = _finite_number(raw.get("sample_rate_hz"))
        trials = []
        entries = raw.get("trials")
        if isinstance(entries, dict):
            for name, entry in entries.items():
                if isinstance(entry, dict) and isinstance(entry.get("file"), str) \
                        and not file_name_error(entry["file"]):
                    trials.append((str(name), entry["file"],
                                   _finite_number(entry.get("commanded_speed_mps"))))
        view = MetaView(None, robot, rate if rate and rate > 0 else None, trials,
                        _salvage_channels(raw.get("channels")))
        reported = " ".join(p.message for p in problems)
        for text in shared_files((n, f) for n, f, _ in trials):
            if text not in reported:
                problems.append(DataProblem(META_FILE, f"trials: {text}"))
        first_use: dict[str, tuple[str, str, float | None]] = {}
        for trial in trials:                     # check a shared file once
            first_use.setdefault(trial[1].lower(), trial)
        view.trials = list(first_use.values())
    for name, _, speed in view.trials:
        if speed is not None and abs(speed) > tol.max_commanded_speed:
            problems.append(DataProblem(
                META_FILE, f"trials.{name}.commanded_speed_mps: {speed:g} is implausible for "
                f"m/s (limit {tol.max_commanded_speed:g} m/s): cm/s or mm/s?"))
    return view


__all__ = ["MetaView", "pydantic_problems", "check_meta"]
