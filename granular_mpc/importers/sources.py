"""Reading the streams of a lab log: ROS 2 bags (rosbag2 sqlite3 or MCAP, through the
pure-Python ``rosbags`` library, no ROS needed) and CSV / Parquet files.

Each stream becomes a :class:`Stream`: its time [s] on the common clock and its values
already in data set columns (``q_<joint>``, ``base_qw`` …) and SI units, in the order the
stream gives them (quaternions reordered to w, x, y, z; foot forces still in their
sensor frame, see :mod:`.frames`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pandas as pd

from ..columns import BASE_QUATERNION, joint_columns
from ..exceptions import ConfigError
from .mapping import VECTOR_TARGETS, ChannelMap, ImportMapping, StreamMap


@dataclass(frozen=True)
class Stream:
    """One stream on the common clock.

    Attributes:
        source: the topic or file name (named by errors).
        key: the mapping key of the stream (``streams[2]``).
        time: sample times [s], strictly increasing.
        values: data set column → values (SI), one per sample.
        frames: column → frame of its vector (``"foot"`` for foot-frame forces).
    """

    source: str
    key: str
    time: np.ndarray
    values: Mapping[str, np.ndarray]
    frames: Mapping[str, str]


def _error(message: str, key: str, source: str, mapping_file: str) -> ConfigError:
    return ConfigError(f"{source}: {message}", key=key, source=mapping_file)


def target_columns(ch: ChannelMap) -> tuple[str, ...]:
    """The data set columns a channel entry fills, in the order of its components."""
    if ch.to == "trunk_orientation":
        return tuple(BASE_QUATERNION) if ch.order == "wxyz" else \
            (BASE_QUATERNION[1], BASE_QUATERNION[2], BASE_QUATERNION[3], BASE_QUATERNION[0])
    return VECTOR_TARGETS.get(ch.to, (ch.to,))


def _components(ch: ChannelMap) -> list[str]:
    """Dotted paths / column names of each component of a channel entry."""
    if ch.fields is not None:
        return list(ch.fields)
    cols = target_columns(ch)
    if len(cols) == 1:
        return [ch.field or ""]
    axes = ("x", "y", "z", "w") if ch.to == "trunk_orientation" and ch.order == "xyzw" else \
        ("w", "x", "y", "z") if ch.to == "trunk_orientation" else ("x", "y", "z")
    return [f"{ch.field}.{a}" for a in axes]


def _check_time(time: np.ndarray, source: str, key: str, mapping_file: str) -> None:
    if time.size < 2:
        raise _error(f"has {time.size} sample(s); a stream needs at least 2", key, source,
                     mapping_file)
    finite = np.isfinite(time)
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        raise _error(f"time is not finite at sample {bad + 1} ({float(time[bad]):g})",
                     f"{key}.time", source, mapping_file)
    if not np.all(np.diff(time) > 0):
        bad = int(np.flatnonzero(~(np.diff(time) > 0))[0]) + 1
        raise _error(f"time is not strictly increasing at sample {bad + 1} "
                     f"({float(time[bad]):.9g} s after {float(time[bad - 1]):.9g} s)",
                     f"{key}.time", source, mapping_file)


def log_joint_name(mapping: ImportMapping, joint: str) -> str:
    """The log's name of robot joint ``joint`` (``joint_names`` inverted; else itself)."""
    return next((k for k, v in mapping.joint_names.items() if v == joint), joint)


# ------------------------------------------------------------------------------ files
def read_table_stream(path: Path, stream: StreamMap, key: str, mapping: ImportMapping,
                      robot_joints: tuple[str, ...], mapping_file: str) -> Stream:
    """One CSV / Parquet stream (columns named by the mapping)."""
    try:
        df = pd.read_parquet(path) if path.suffix.lower() == ".parquet" else pd.read_csv(path)
    except (OSError, ValueError) as exc:
        raise _error(f"cannot read: {exc}", f"{key}.source", stream.source, mapping_file) from None

    def column(name: str, what: str) -> np.ndarray:
        if name not in df.columns:
            raise _error(f"has no column {name!r} (columns: {', '.join(map(str, df.columns))})",
                         what, stream.source, mapping_file)
        try:
            return df[name].to_numpy(dtype=float)
        except (TypeError, ValueError):
            bad = pd.to_numeric(df[name], errors="coerce").isna() & df[name].notna()
            rows = np.flatnonzero(bad.to_numpy())
            where = (f": {len(rows)} cell(s), the first in data row {rows[0] + 1} "
                     f"({df[name].iloc[rows[0]]!r})" if rows.size else "")
            raise _error(f"column {name!r} is not numeric{where}", what, stream.source,
                         mapping_file) from None

    time = column(stream.time, f"{key}.time") * stream.time_scale + stream.time_offset_s
    _check_time(time, stream.source, key, mapping_file)
    values: dict[str, np.ndarray] = {}
    frames: dict[str, str] = {}
    for kind, pattern in stream.joint_columns.items():
        scale = stream.joint_scale.get(kind, 1.0)
        for joint in robot_joints:
            col = pattern.format(joint=log_joint_name(mapping, joint))
            values[joint_columns([joint], kind)[0]] = \
                column(col, f"{key}.joint_columns.{kind}") * scale
    for i, ch in enumerate(stream.channels):
        where = f"{key}.channels[{i}]"
        for name, target in zip(_components(ch), target_columns(ch)):
            values[target] = column(name, f"{where}.field") * ch.scale
            frames[target] = ch.frame
    return Stream(stream.source, key, time, values, frames)


# ------------------------------------------------------------------------------ bags
def _attr(msg: Any, path: str) -> Any:
    for part in path.split("."):
        msg = getattr(msg, part)
    return msg


def read_bag_streams(path: Path, mapping: ImportMapping, robot_joints: tuple[str, ...],
                     mapping_file: str) -> list[Stream]:
    """Every stream of the mapping from one ROS 2 bag (sqlite3 or MCAP)."""
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:  # pragma: no cover - the optional dependency
        raise ConfigError("reading ROS 2 bags needs the rosbags package: pip install "
                          "'granular_mpc[import]'", key="streams", source=mapping_file) from None
    streams = []
    with AnyReader([path]) as reader:
        topics = {c.topic for c in reader.connections}
        raw: list[tuple[StreamMap, str, list[tuple[int, Any]]]] = []
        for i, stream in enumerate(mapping.streams):
            key = f"streams[{i}]"
            if stream.source not in topics:
                raise _error(f"topic not in the bag (topics: {', '.join(sorted(topics))})",
                             f"{key}.source", stream.source, mapping_file)
            conns = [c for c in reader.connections if c.topic == stream.source]
            msgs = [(t, reader.deserialize(data, c.msgtype))
                    for c, t, data in reader.messages(connections=conns)]
            raw.append((stream, key, msgs))
    stamps = []
    for stream, key, msgs in raw:
        try:
            ns = np.array([_attr(m, "header.stamp.sec") * 10**9 + _attr(m, "header.stamp.nanosec")
                           if stream.time == "header" else t for t, m in msgs], dtype=np.int64)
        except AttributeError:
            raise _error("messages have no header.stamp: use time: receive", f"{key}.time",
                         stream.source, mapping_file) from None
        stamps.append(ns)
    origin = min(int(ns[0]) for ns in stamps if ns.size)
    for (stream, key, msgs), ns in zip(raw, stamps):
        time = (ns - origin).astype(np.float64) * 1e-9 + stream.time_offset_s
        _check_time(time, stream.source, key, mapping_file)
        streams.append(_bag_values(stream, key, msgs, time, mapping, robot_joints, mapping_file))
    return streams


def _bag_values(stream: StreamMap, key: str, msgs: list[tuple[int, Any]], time: np.ndarray,
                mapping: ImportMapping, robot_joints: tuple[str, ...],
                mapping_file: str) -> Stream:
    values: dict[str, np.ndarray] = {}
    frames: dict[str, str] = {}
    if stream.joint_state:
        names = [mapping.joint_names.get(str(n), str(n)) for n in _attr(msgs[0][1], "name")]
        unknown = [n for n in names if n not in robot_joints]
        missing = [j for j in robot_joints if j not in names]
        if missing:
            raise _error(f"joint(s) {', '.join(missing)} of the robot are not in the message "
                         f"names ({', '.join(names)}; unknown: {', '.join(unknown) or 'none'}): "
                         "map them under joint_names", "joint_names", stream.source, mapping_file)
        for kind, field in stream.joint_state.items():
            scale = stream.joint_scale.get(kind, 1.0)
            try:
                rows = np.array([np.asarray(_attr(m, field), dtype=float) for _, m in msgs])
            except (AttributeError, ValueError):
                raise _error(f"no array field {field!r} of one length in every message",
                             f"{key}.joint_state.{kind}", stream.source, mapping_file) from None
            for joint in robot_joints:
                values[joint_columns([joint], kind)[0]] = rows[:, names.index(joint)] * scale
    for i, ch in enumerate(stream.channels):
        where = f"{key}.channels[{i}].{'field' if ch.field is not None else 'fields'}"
        for path, target in zip(_components(ch), target_columns(ch)):
            try:
                values[target] = np.array([float(_attr(m, path)) for _, m in msgs]) * ch.scale
            except (AttributeError, TypeError, ValueError):
                raise _error(f"messages have no number at {path!r}", where, stream.source,
                             mapping_file) from None
            frames[target] = ch.frame
    return Stream(stream.source, key, time, values, frames)


__all__ = ["Stream", "target_columns", "log_joint_name", "read_table_stream", "read_bag_streams"]
