"""``import_log``: a lab log (ROS 2 bag, CSV / Parquet files) + a mapping file → a checked
data set (format v1 with declared ``channels``).

Steps: read each stream (:mod:`.sources`: names, units, quaternion order, joint names), put
them on one clock and grid (:mod:`.align`), rotate foot-frame forces to the world
(:mod:`.frames`), turn per-foot forces into the format's stance-foot force, declare the
channel groups that are complete, and write with
:func:`~granular_mpc.validation.dataformat.write_dataset` — whose checks run on the result.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from ..columns import FOOT_SIDES, GRF_COLUMNS, TIME, foot_column
from ..exceptions import ConfigError
from ..robot.model import Biped, load_biped
from ..validation.dataformat import (ChannelGroup, ChannelSet, StanceDerivation, derive_stance,
                                     write_dataset)
from ..validation.dataformat.robot_facts import load_robot_facts
from .align import align
from .frames import foot_force_to_world
from .mapping import ImportMapping, load_mapping
from .sources import Stream, read_bag_streams, read_table_stream

BAG_SUFFIXES = (".mcap", ".db3")


@dataclass(frozen=True)
class ImportResult:
    """What :func:`import_log` wrote.

    Attributes:
        path: the data set folder.
        trial: the trial name.
        channels: the channel groups declared in ``meta.yaml``.
        rows: samples written.
        resampled: False if the streams shared one clock at the output rate (copied as is).
        stance: how stance labels were derived to build the stance-foot force from per-foot
            forces (None if no per-foot force was mapped; the loader derives them again).
        streams: (source, samples) of each stream read.
    """

    path: Path
    trial: str
    channels: ChannelSet
    rows: int
    resampled: bool
    stance: StanceDerivation | None
    streams: tuple[tuple[str, int], ...]


def _is_bag(path: Path) -> bool:
    return (path.is_dir() and (path / "metadata.yaml").is_file()) or \
        path.suffix.lower() in BAG_SUFFIXES


def _read(source: Path, mapping: ImportMapping, joints: tuple[str, ...],
          mapping_file: str) -> list[Stream]:
    if not source.exists():
        raise ConfigError(f"log not found: {source}", key="source", source=mapping_file)
    if _is_bag(source):
        return read_bag_streams(source, mapping, joints, mapping_file)
    folder = source if source.is_dir() else source.parent
    out = []
    for i, stream in enumerate(mapping.streams):
        path = Path(stream.source)
        path = path if path.is_absolute() else folder / path
        if not path.is_file():
            raise ConfigError(f"{stream.source}: file not found in {folder}",
                              key=f"streams[{i}].source", source=mapping_file)
        out.append(read_table_stream(path, stream, f"streams[{i}]", mapping, joints,
                                     mapping_file))
    return out


def _per_foot_to_world(values: dict[str, np.ndarray], frames: dict[str, str], biped: Biped,
                       channels: ChannelSet, mapping_file: str) -> None:
    for side in FOOT_SIDES:
        cols = [foot_column(side, c) for c in GRF_COLUMNS]
        if not any(c in values for c in cols) or frames.get(cols[0]) != "foot":
            continue
        if not channels.has(ChannelGroup.JOINT_ANGLES, ChannelGroup.TRUNK_ORIENTATION):
            raise ConfigError(f"{side}_foot_force in frame: foot needs the joint angles and the "
                              "trunk orientation (map them too, or give the force in frame: "
                              "world)", key="streams.channels", source=mapping_file)
        force = np.column_stack([values[c] for c in cols])
        world = foot_force_to_world(biped, side, values, force)
        for k, c in enumerate(cols):
            values[c] = world[:, k]


def _groups(values: dict[str, np.ndarray], joints: tuple[str, ...],
            mapping_file: str) -> ChannelSet:
    groups = []
    for g in ChannelGroup:
        cols = g.columns(joints)
        have = [c for c in cols if c in values]
        if have and len(have) < len(cols):
            missing = [c for c in cols if c not in values]
            raise ConfigError(f"channel group {g.value} is incomplete: {', '.join(missing)} "
                              "not mapped (map every column of a group, or none)",
                              key="streams", source=mapping_file)
        if have:
            groups.append(g)
    if not groups:
        raise ConfigError("no channel is mapped", key="streams", source=mapping_file)
    return ChannelSet.of(groups)


def import_log(source: str | Path, mapping_file: str | Path | ImportMapping,
               out_dir: str | Path, *, format: Literal["csv", "parquet"] = "csv",
               overwrite: bool = False) -> ImportResult:
    """Import a lab log into a checked data set.

    Args:
        source: a ROS 2 bag (its folder with ``metadata.yaml``), or a folder / file of CSV
            or Parquet streams (stream sources are file names relative to it).
        mapping_file: the mapping file (``docs/import.md``), or a loaded :class:`ImportMapping`.
        out_dir: the data set folder to write.
        format: trial file format.
        overwrite: replace an existing data set there.

    Returns:
        What was written (:class:`ImportResult`).

    Raises:
        ConfigError: a bad mapping, or a topic / column / field that is not in the log
            (the message names the topic or column, ``key`` the mapping key).
        DataFormatError: the imported data fails the data set checks (unit, sign …).
        OutputError: the data set cannot be written.
    """
    if isinstance(mapping_file, ImportMapping):
        mapping, where = mapping_file, "mapping"
    else:
        mapping, where = load_mapping(mapping_file), str(mapping_file)
    biped = load_biped(mapping.robot, with_visuals=False)
    joints = tuple(biped.joint_names)
    streams = _read(Path(source).expanduser(), mapping, joints, where)
    aligned = align(streams, mapping.sample_rate_hz, where)
    values = dict(aligned.values)
    frames = dict(aligned.frames)
    channels = _groups(values, joints, where)
    _per_foot_to_world(values, frames, biped, channels, where)
    stance = None
    per_foot = [foot_column(s, "grf_z") for s in FOOT_SIDES]
    if any(c in values for c in per_foot):
        if not all(c in values for c in per_foot):
            raise ConfigError("a foot force is mapped for one foot only: map left_foot_force "
                              "and right_foot_force", key="streams", source=where)
        if channels.has(ChannelGroup.FOOT_FORCE):
            raise ConfigError("map either foot_force (the stance foot's) or left_foot_force and "
                              "right_foot_force, not both", key="streams", source=where)
        found = derive_stance({TIME: aligned.time, **values},
                              load_robot_facts(mapping.robot, None), channels)
        if isinstance(found, str):
            raise ConfigError(f"cannot derive stance labels: {found}", key="streams",
                              source=where)
        labels, stance = found
        for c in GRF_COLUMNS:
            stance_foot = np.zeros(len(labels))
            for side in FOOT_SIDES:
                on = labels == side
                stance_foot[on] = values[foot_column(side, c)][on]
            values[c] = stance_foot
        channels = ChannelSet.of(list(channels.groups | {ChannelGroup.FOOT_FORCE}))
    columns = channels.columns(joints)
    extras = [foot_column(s, c) for s in FOOT_SIDES for c in GRF_COLUMNS if foot_column(s, c)
              in values]
    df = pd.DataFrame({TIME: aligned.time, **{c: values[c] for c in columns + extras}})
    meta = {"schema_version": 1, "robot": mapping.robot, "terrain": mapping.terrain,
            "sample_rate_hz": mapping.sample_rate_hz, "description": mapping.description,
            "channels": [g.value for g in channels],
            "trials": {mapping.trial: {"commanded_speed_mps": mapping.commanded_speed_mps,
                                       "description": f"imported from {Path(source).name}"}}}
    if mapping.torque_hold_s is not None:
        meta["torque_hold_s"] = mapping.torque_hold_s
    path = write_dataset(out_dir, meta, {mapping.trial: df}, format, overwrite=overwrite)
    return ImportResult(path, mapping.trial, channels, len(df), aligned.resampled, stance,
                        tuple((s.source, len(s.time)) for s in streams))


__all__ = ["BAG_SUFFIXES", "ImportResult", "import_log"]
