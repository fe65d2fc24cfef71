"""A data set without some channel groups: what a lab without those sensors would have
recorded (``granular-mpc drop-channels``, ``bench/channels.py``)."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Literal

from ...columns import FOOT_SIDES, STANCE, foot_column
from ...exceptions import ConfigError
from .channels import ChannelGroup
from .load import load_dataset
from .write import write_dataset


def drop_channels(src_dir: str | Path, out_dir: str | Path,
                  groups: Iterable[ChannelGroup | str], *,
                  stance: Literal["auto", "keep", "drop"] = "auto",
                  format: Literal["csv", "parquet"] | None = None,
                  overwrite: bool = False) -> Path:
    """Write a copy of a data set without the channel ``groups`` (what a lab without those
    sensors would have recorded).

    The columns of the removed groups are deleted (not zeroed) and ``meta.yaml``'s
    ``channels`` lists the groups that remain; the copy is checked on writing. Per-foot
    force columns (``left_grf_z`` …) go with ``foot_force``.

    Args:
        src_dir: the data set.
        out_dir: the new data set's folder.
        groups: channel groups to remove (names or :class:`ChannelGroup`).
        stance: ``"keep"`` the ``stance`` column, ``"drop"`` it (the loader then derives
            the labels), or ``"auto"``: drop it when ``foot_force`` is removed — labels
            that came from contact sensing are not what a lab without foot sensors has.
        format: ``"csv"`` / ``"parquet"`` (default: the source's).
        overwrite: replace a data set already in ``out_dir``.

    Returns:
        The new data set's folder.

    Raises:
        ConfigError: an unknown group name, or nothing would remain.
        DataFormatError: the copy fails the data set checks (e.g. labels derived from
            what remains are impossible).
    """
    try:
        drop = {ChannelGroup(g) for g in groups}
    except ValueError as exc:
        raise ConfigError(f"unknown channel group: {exc}", key="groups",
                          allowed=", ".join(g.value for g in ChannelGroup)) from None
    ds = load_dataset(src_dir)
    keep = [g for g in ds.channels if g not in drop]
    if not keep:
        raise ConfigError("drop_channels: no channel group would remain", key="groups")
    cols: list[str] = []
    for g in drop:
        cols += g.columns(ds.joint_names)
    if ChannelGroup.FOOT_FORCE in drop:
        cols += [foot_column(s, f"grf_{a}") for s in FOOT_SIDES for a in "xyz"]
    if stance == "drop" or (stance == "auto" and ChannelGroup.FOOT_FORCE in drop):
        cols.append(STANCE)
    trials = {n: df.drop(columns=[c for c in cols if c in df.columns])
              for n, df in ds.trials.items()}
    if ds.stance_derivations and STANCE not in cols:
        trials = {n: df.drop(columns=[STANCE]) if n in ds.stance_derivations else df
                  for n, df in trials.items()}
    meta = ds.meta.model_copy(update={"channels": keep})
    fmt = format or ("parquet" if any(t.file.endswith(".parquet")
                                      for t in ds.meta.trials.values()) else "csv")
    return write_dataset(out_dir, meta, trials, fmt, overwrite=overwrite)


__all__ = ["drop_channels"]
