"""Animation of a whole log: node transforms per frame, shared by the page and the server.

The log is subsampled to a frame rate (:func:`sample_frames`); each frame records, per
moving node, only transforms (position, quaternion, scale) and visibility in a
:class:`meshcat.animation.Animation` built with ``at_frame`` — never geometry. Footprints
get a visibility track that switches them on at their touchdown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...exceptions import ConfigError, DataFormatError, DataProblem
from ...robot.model import SIDES
from .backend import animation as ma
from .log_rows import FOOT_STRIDE, log_arrays, touchdowns
from .scene import BipedScene, NodeState


@dataclass(frozen=True)
class RecordedAnimation:
    """Everything needed to play a log: the animation and the touchdowns it reveals.

    Attributes:
        animation: the :class:`meshcat.animation.Animation` (transforms per frame).
        n_frames: number of animation frames.
        fps: frame rate [1/s].
        t0: log time of frame 0 [s].
        footprints: ``(frame, side, x [m], y [m])`` per touchdown, in time order; the
            footprint becomes visible at ``frame``.
        extent: ``((x_min, x_max), (y_min, y_max))`` of terrain to draw [m, W].
        first_states: node states of frame 0 (path → :class:`~.scene.NodeState`).
    """

    animation: Any
    n_frames: int
    fps: float
    t0: float
    footprints: list = field(default_factory=list)
    extent: tuple = ((-1.0, 1.0), (-1.0, 1.0))
    first_states: dict[str, NodeState] = field(default_factory=dict)


def sample_frames(times: np.ndarray, fps: float) -> np.ndarray:
    """Row index shown at each animation frame: frame k is the row nearest ``t0 + k/fps``.

    Args:
        times: log times [s], non-decreasing.
        fps: frames per second of the animation [1/s].
    """
    if fps <= 0 or not math.isfinite(fps):
        raise ConfigError("must be a positive number of frames per second", key="fps", value=fps)
    t0, t1 = float(times[0]), float(times[-1])
    n = int(math.floor((t1 - t0) * fps + 1e-9)) + 1
    want = t0 + np.arange(n) / fps
    if len(times) == 1:
        return np.zeros(n, dtype=int)
    j = np.clip(np.searchsorted(times, want), 1, len(times) - 1)
    left_closer = (want - times[j - 1]) <= (times[j] - want)
    return np.where(left_closer, j - 1, j).astype(int)


def record_animation(scene: BipedScene, vis, log_df, fps: float) -> RecordedAnimation:
    """Build the animation of a log: node transforms per frame, no geometry.

    Args:
        scene: what to draw.
        vis: the ``Visualizer`` (rooted at :data:`~.scene.ROOT`) the paths are relative to.
        log_df: the run log (columns: :func:`~.log_rows.log_arrays`).
        fps: animation frame rate [1/s].

    Raises:
        DataFormatError: missing columns, bad time, or no row with a finite pose.
        ConfigError: ``fps`` is not a positive number.
    """
    biped = scene.biped
    arrays = log_arrays(biped, log_df)
    cols, times, values = arrays.columns, arrays.times, arrays.values
    nq = biped.model.nq
    idx = sample_frames(times, fps)
    # Rows with a non-finite pose (e.g. the last rows of a diverged run) show the last
    # finite pose before them.
    finite = np.flatnonzero(np.all(np.isfinite(values[:, :nq]), axis=1))
    if finite.size == 0:
        raise DataFormatError([DataProblem("log", "no row has a finite base pose and joint "
                                           "angles")], root="log")
    idx = finite[np.maximum(np.searchsorted(finite, idx, side="right") - 1, 0)]
    n = len(idx)
    t0 = float(times[0])
    sd = scene.create_data()
    centre = None
    if not scene.style.follow:
        xs, ys = values[:, 0], values[:, 1]
        centre = np.array([0.5 * (xs.min() + xs.max()), 0.5 * (ys.min() + ys.max()),
                           scene.terrain.surface_height + scene.style.look_height])
    anim = ma.Animation(default_framerate=fps)
    first_states: dict = {}
    for k, i in enumerate(idx):
        states = scene.frame_states(sd, values[i], centre)
        if k == 0:
            first_states = states
        with anim.at_frame(vis, k) as frame:
            for path, s in states.items():
                node = frame[path]
                if s.position is not None:
                    node.set_property("position", "vector3", list(s.position))
                if s.quaternion is not None:
                    node.set_property("quaternion", "quaternion", list(s.quaternion))
                if s.scale is not None:
                    node.set_property("scale", "vector3", list(s.scale))
                if s.visible is not None:
                    node.set_property("visible", "boolean", bool(s.visible))
    # Footprints: frame at which each touchdown becomes visible.
    prints = []
    for t, side, x, y in touchdowns(values, times, nq):
        frame_k = min(int(math.ceil((t - t0) * fps - 1e-9)), n - 1)
        prints.append((frame_k, side, x, y))
    for j, (frame_k, _side, _x, _y) in enumerate(prints):
        keys = {0: frame_k == 0, frame_k: True, n - 1: True}
        for k in sorted(keys):
            with anim.at_frame(vis, k) as frame:
                frame[scene.footprint_path(j)].set_property("visible", "boolean", keys[k])
    # Arrow tracks have keys only while the arrow is shown, footprint tracks only at a few
    # frames: pad every track to span frames 0 … n−1, since three.js loops each clip over
    # its own duration and clips of different lengths would drift apart.
    for clip in anim.clips.values():
        for track in clip.tracks.values():
            if track.frames[0] != 0:
                track.frames.insert(0, 0)
                track.values.insert(0, track.values[0])
            if track.frames[-1] != n - 1:
                track.frames.append(n - 1)
                track.values.append(track.values[-1])
            _drop_redundant_keys(track)
    drawn = [nq + FOOT_STRIDE * k for k, side in enumerate(SIDES) if side in cols.sides]
    xs = np.concatenate([values[:, 0]] + [values[:, o + 4] for o in drawn])  # base, C_x
    ys = np.concatenate([values[:, 1]] + [values[:, o + 5] for o in drawn])  # base, C_y
    xs, ys = xs[np.isfinite(xs)], ys[np.isfinite(ys)]
    m = scene.style.terrain_margin
    extent = ((float(xs.min()) - m, float(xs.max()) + m),
              (float(ys.min()) - m, float(ys.max()) + m))
    return RecordedAnimation(anim, n, float(fps), t0, prints, extent, first_states)


def _drop_redundant_keys(track) -> None:
    """Remove keys equal to both neighbours (exact for linear, slerp and step tracks)."""
    fr, va = track.frames, track.values
    if len(fr) <= 2:
        return
    keep_f, keep_v = [fr[0]], [va[0]]
    for i in range(1, len(fr) - 1):
        if va[i] == va[i - 1] and va[i] == va[i + 1]:
            continue
        keep_f.append(fr[i])
        keep_v.append(va[i])
    keep_f.append(fr[-1])
    keep_v.append(va[-1])
    track.frames[:] = keep_f
    track.values[:] = keep_v


__all__ = ["RecordedAnimation", "sample_frames", "record_animation"]
