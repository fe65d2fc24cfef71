"""Several data sets as one (``granular-mpc merge``): the trials of separate recordings —
one lab log imported per trial (``granular-mpc import``), or data sets recorded on
different days on the same sand — in one data set, so that ``diagnose`` can hold out whole
trials (it needs three; with fewer it falls back to holding out stances).

Only data sets that describe the same experiment merge: the same robot, sample rate,
measured channel groups and ground description (``terrain=`` names the merged ground when
the descriptions differ, e.g. "dry sand" and "dry play sand"). Anything else is refused
with one error naming both data sets and the two values. Trials keep their names; where
two sources share a name, each clashing trial is renamed ``<source folder>_<name>``. The
merged ``meta.yaml`` lists where every trial came from in its ``description``, and keeps
the synthetic generator's record only when all sources share it.
"""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path
from typing import Literal, Sequence

from ...columns import STANCE
from ...exceptions import ConfigError
from .dataset import Dataset
from .load import load_dataset
from .write import write_dataset


def _same(datasets: Sequence[Dataset], what: str, values: list) -> None:
    """One error naming the first source whose ``what`` differs from the first's."""
    for ds, v in zip(datasets[1:], values[1:]):
        if v != values[0]:
            raise ConfigError(f"merge: {ds.path} has {what} {v!r}, {datasets[0].path} has "
                              f"{values[0]!r}: only recordings of the same experiment merge",
                              key=what, value=str(v), allowed=str(values[0]))


def _prefix(path: Path) -> str:
    """A trial-name prefix from a source folder's name (letters, digits, ``_ . -``)."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", path.resolve().name).lstrip("_.-")
    return name or "source"


def merge_datasets(sources: Sequence[str | Path], out_dir: str | Path, *,
                   terrain: str | None = None,
                   format: Literal["csv", "parquet"] | None = None,
                   overwrite: bool = False) -> Path:
    """Write the trials of ``sources`` as one data set in ``out_dir``.

    Args:
        sources: two or more data set folders (each is loaded and checked).
        out_dir: the merged data set's folder.
        terrain: the merged ``terrain`` description (default: the sources', which must
            then agree).
        format: ``"csv"`` / ``"parquet"`` (default: the first source's).
        overwrite: replace a data set already in ``out_dir``.

    Returns:
        The merged data set's folder.

    Raises:
        ConfigError: fewer than two sources; a source listed twice; robot, sample rate,
            measured channel groups or (without ``terrain``) ground description differ.
        DataFormatError: a source fails its checks (the loader's error, naming file and
            row), or the merged data set would not load.
        OutputError: ``out_dir`` holds a data set and not ``overwrite``.
    """
    paths = [Path(s).expanduser() for s in sources]
    if len(paths) < 2:
        raise ConfigError("merge: give at least two data sets", key="sources",
                          value=len(paths))
    resolved = [p.resolve() for p in paths]
    twice = sorted({str(p) for p in resolved if resolved.count(p) > 1})
    if twice:
        raise ConfigError(f"merge: {twice[0]} is listed more than once", key="sources",
                          value=twice[0])
    if Path(out_dir).expanduser().resolve() in resolved:
        raise ConfigError("merge: the output folder is one of the sources", key="out",
                          value=str(out_dir))
    datasets = [load_dataset(p) for p in paths]
    _same(datasets, "robot", [d.meta.robot for d in datasets])
    _same(datasets, "sample_rate_hz", [d.meta.sample_rate_hz for d in datasets])
    _same(datasets, "channels", [str(d.channels) for d in datasets])
    _same(datasets, "torque_hold_s", [d.meta.torque_hold_s for d in datasets])
    if terrain is None:
        _same(datasets, "terrain", [d.meta.terrain for d in datasets])
    counts = Counter(n for d in datasets for n in d.trials)
    trials, entries, origin = {}, {}, []
    for d in datasets:
        names = []
        for n, df in d.trials.items():
            new = f"{_prefix(d.path)}_{n}" if counts[n] > 1 else n
            if new in entries:
                raise ConfigError(f"merge: trial name {new!r} is taken twice (sources with the "
                                  "same folder name and trial names); rename a folder",
                                  key="trials", value=new)
            # labels the loader derived are derived again from the merged files
            trials[new] = df.drop(columns=[STANCE]) if n in d.stance_derivations else df
            entries[new] = d.meta.trials[n].model_dump(exclude={"file"})   # file: write's
            names.append(new if new == n else f"{n} → {new}")
        origin.append(f"{d.path} ({', '.join(names)})")
    gens = [d.meta.generator for d in datasets]
    first = datasets[0].meta
    meta = {"schema_version": 1, "robot": first.robot,
            "terrain": first.terrain if terrain is None else terrain,
            "sample_rate_hz": first.sample_rate_hz, "trials": entries,
            "description": "merged from " + "; ".join(origin)}
    if first.channels is not None:
        meta["channels"] = [g.value for g in first.channels]
    if first.torque_hold_s is not None:
        meta["torque_hold_s"] = first.torque_hold_s
    if gens[0] is not None and all(g == gens[0] for g in gens):
        meta["generator"] = gens[0].model_dump(mode="json")
    fmt = format or ("parquet" if any(t.file.endswith(".parquet")
                                      for t in first.trials.values()) else "csv")
    return write_dataset(out_dir, meta, trials, fmt, overwrite=overwrite)


__all__ = ["merge_datasets"]
