"""Time alignment: the streams' common time span, one grid at the output rate, and
interpolation of every stream onto it.

The common span is from the latest first sample to the earliest last sample over all
streams (after each stream's ``time_offset_s``). The grid is t_k = t_start + k / f_s.
Values are interpolated linearly; a quaternion is interpolated component-wise after
making consecutive samples lie in one hemisphere, then renormalised (at ≥ 100 Hz this
equals slerp to far below sensor noise). When every stream already has the same sample
times and they are evenly spaced at the output rate (within 1 µs), nothing is
interpolated: the values are copied bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..columns import BASE_QUATERNION
from ..exceptions import ConfigError
from .sources import Stream

SAME_GRID_TOLERANCE_S = 1e-6
"""Sample times that differ by less than this are the same sample [s]."""


@dataclass(frozen=True)
class Aligned:
    """Every stream on one grid.

    Attributes:
        time: grid times [s] from 0 (the start of the common span).
        values: data set column → values on the grid.
        frames: column → frame of its vector.
        resampled: False if the streams shared their sample times (values copied as is).
        start_s: the common span's start on the streams' clock [s].
    """

    time: np.ndarray
    values: Mapping[str, np.ndarray]
    frames: Mapping[str, str]
    resampled: bool
    start_s: float


def _same_grid(streams: Sequence[Stream], rate_hz: float) -> bool:
    t0 = streams[0].time
    if any(s.time.shape != t0.shape or np.max(np.abs(s.time - t0)) > SAME_GRID_TOLERANCE_S
           for s in streams[1:]):
        return False
    return bool(np.max(np.abs(np.diff(t0) - 1.0 / rate_hz)) < SAME_GRID_TOLERANCE_S)


def _continuous_quaternion(q: np.ndarray) -> np.ndarray:
    """Flip samples so that consecutive quaternions have a positive dot product."""
    q = q.copy()
    for k in range(1, len(q)):
        if float(q[k] @ q[k - 1]) < 0.0:
            q[k] = -q[k]
    return q


def align(streams: Sequence[Stream], rate_hz: float, mapping_file: str = "") -> Aligned:
    """Put every stream on one grid at ``rate_hz`` (module docstring).

    Raises:
        ConfigError: the streams do not overlap in time, or two streams fill one column.
    """
    owner: dict[str, str] = {}
    for s in streams:
        for col in s.values:
            if col in owner:
                raise ConfigError(f"column {col} is filled by two streams: {owner[col]} and "
                                  f"{s.source}", key=f"{s.key}.channels", source=mapping_file)
            owner[col] = s.source
    frames = {c: f for s in streams for c, f in s.frames.items()}
    if _same_grid(streams, rate_hz):
        t = streams[0].time
        values = {c: v for s in streams for c, v in s.values.items()}
        return Aligned(t - t[0], values, frames, False, float(t[0]))
    start = max(float(s.time[0]) for s in streams)
    stop = min(float(s.time[-1]) for s in streams)
    if stop <= start:
        spans = ", ".join(f"{s.source} [{s.time[0]:.3f}, {s.time[-1]:.3f}] s" for s in streams)
        raise ConfigError(f"the streams do not overlap in time ({spans}): check time_offset_s",
                          key="streams", source=mapping_file)
    n = int(np.floor((stop - start) * rate_hz + 1e-9)) + 1
    grid = start + np.arange(n) / rate_hz
    values: dict[str, np.ndarray] = {}
    for s in streams:
        quat = [c for c in BASE_QUATERNION if c in s.values]
        if len(quat) == 4:
            q = _continuous_quaternion(np.column_stack([s.values[c] for c in BASE_QUATERNION]))
            qi = np.column_stack([np.interp(grid, s.time, q[:, k]) for k in range(4)])
            qi /= np.linalg.norm(qi, axis=1, keepdims=True)
            values.update({c: qi[:, k] for k, c in enumerate(BASE_QUATERNION)})
        for col, v in s.values.items():
            if col not in values:
                values[col] = np.interp(grid, s.time, v)
    return Aligned(grid - start, values, frames, True, start)


__all__ = ["SAME_GRID_TOLERANCE_S", "Aligned", "align"]
