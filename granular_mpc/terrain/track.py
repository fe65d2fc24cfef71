"""A track: a terrain whose ground law changes along world x (the paper's walking track).

The paper's robot walked in place on a rigid platform, then stepped forward across the
rigid segment onto a 12 cm sand layer level with it (Chen et al., Sec. III-B). Here that is
a :class:`TrackTerrain`: one :class:`~granular_mpc.terrain.base.TerrainModel` per segment
(built for the same foot), and per foot the law of the segment under it.

Rule (the simplest faithful one):

* **At touchdown** a foot takes the segment under the lowest point of its sole's mid-line
  (world x; the edge itself belongs to the next segment). Its intrusion state in that
  segment starts fresh (C₀ = the touchdown point, no elastic displacement): landing on the
  other material resets it.
* **While in contact** the foot keeps that segment's law until it lifts off, even if its
  contact point rolls or slides across an edge during the stance (a few cm at most).
* A foot clear of the ground is re-assigned at its next evaluation.

**Continuity at the edge.** The law is discontinuous across an edge: a foot landing 1 mm
before the edge meets rigid ground, 1 mm after it the sand's zero surface capacity. A
real foot straddling the edge would be partly held by the rigid lip; here a straddling
foot is wholly on the medium it landed on. Both segments share the free surface (the
config rejects a step), so the geometry is continuous; only the law jumps. The controller's
ground model is not a track: it is whatever ``controller.terrain`` names.

Only the per-step Python plant (:class:`~granular_mpc.dynamics.Plant`) takes a track; the
compiled/batched plant takes one law (:attr:`TrackTerrain.contact` says so).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..config import FootGeometry
from ..exceptions import ConfigError
from .contact import N_KIN, ContactData


@dataclass(frozen=True)
class TrackTerrain:
    """Immutable track model: one terrain model per segment, switched along world x.

    Attributes:
        config: the validated :class:`~granular_mpc.config.terrain.TrackTerrainConfig`.
        segments: the segments' terrain models, in x order (same foot geometry).
        kind: ``"track"``.
    """

    config: Any
    segments: tuple
    kind: str = "track"

    def __post_init__(self) -> None:
        if len(self.segments) != len(self.config.segments):
            raise ConfigError("one terrain model per track segment is needed",
                              key="terrain.segments")
        feet = {m.foot for m in self.segments}
        if len(feet) != 1:
            raise ConfigError("the track's segments were built for different feet",
                              key="terrain.segments")

    # ------------------------------------------------------------------ what the plant reads
    @property
    def foot(self) -> FootGeometry:
        return self.segments[0].foot

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def surface_height(self) -> float:
        """The common free surface [m] (world z)."""
        return float(self.config.surface_height)

    @property
    def edges(self) -> tuple[float, ...]:
        """x of the edges between segments [m]."""
        return self.config.edges

    def segment_index(self, x: float) -> int:
        """Index of the segment at world x [m]."""
        return self.config.segment_index(x)

    def at(self, x: float):
        """The terrain model at world x [m] (for closed-form questions: capacity, depth …)."""
        return self.segments[self.segment_index(x)]

    def new_data(self, dt: float | None = None) -> "TrackContactData":
        return TrackContactData(self, dt)

    @property
    def contact(self):
        raise ConfigError("a track has one contact law per segment; the compiled and batched "
                          "plants take one law (use the Python plant, or one segment's "
                          "terrain: track.segments[k])", key="terrain.kind", value="track")

    @property
    def param_names(self) -> tuple[str, ...]:
        """Parameter names of every segment, ``<k>.<name>`` (segment index k)."""
        return tuple(f"{k}.{n}" for k, m in enumerate(self.segments) for n in m.param_names)

    @property
    def param_values(self) -> np.ndarray:
        return np.concatenate([m.param_values for m in self.segments])


def sole_point_x(kin: np.ndarray, radius: float, half_angle: float) -> float:
    """World x of the lowest point of the sole's mid-line [m].

    The float twin of :func:`granular_mpc.terrain.contact.slice_geometry` for the slice at
    lateral offset 0: ``kin`` is a foot's kinematic input (position, rotation column-major).
    """
    e_x = kin[3:6]
    e_z = kin[9:12]
    psi = math.atan2(-e_x[2], e_z[2])
    psi = min(max(psi, -half_angle), half_angle)
    return float(kin[0] + radius * (math.sin(psi) * e_x[0] - math.cos(psi) * e_z[0]))


class TrackFoot:
    """One foot's view of a track's contact: the buffers of the segment it is on.

    ``kin`` is the foot's own input array (the plant writes it); the outputs (``force``,
    ``point``, ``diag``, ``wrench_local``) and states are those of the current segment.
    """

    def __init__(self, data: "TrackContactData", index: int) -> None:
        self._data = data
        self._index = index
        self.kin = np.zeros(N_KIN)

    @property
    def buffers(self):
        """The current segment's buffers of this foot."""
        d = self._data
        return d.datas[d.segment[self._index]].feet[self._index]

    @property
    def force(self) -> np.ndarray:
        return self.buffers.force

    @property
    def point(self) -> np.ndarray:
        return self.buffers.point

    @property
    def diag(self) -> np.ndarray:
        return self.buffers.diag

    @property
    def wrench_local(self) -> np.ndarray:
        return self.buffers.wrench_local

    @property
    def state(self) -> np.ndarray:
        return self.buffers.state

    @property
    def new_state(self) -> np.ndarray:
        return self.buffers.new_state


class TrackContactData:
    """Changing part of a track's contact: one :class:`ContactData` per segment and, per
    foot, the segment it is on (the same interface as :class:`ContactData`)."""

    def __init__(self, track: TrackTerrain, dt: float | None = None) -> None:
        self.track = track
        self.datas: tuple[ContactData, ...] = tuple(m.new_data(dt) for m in track.segments)
        foot = track.foot
        self._radius, self._half = foot.radius, foot.half_angle
        self.segment = [0, 0]
        self.feet = (TrackFoot(self, 0), TrackFoot(self, 1))

    @property
    def active(self) -> list[bool]:
        return [self.datas[self.segment[i]].active[i] for i in range(2)]

    def set_dt(self, dt: float) -> None:
        for d in self.datas:
            d.set_dt(dt)

    def _place(self, foot: int) -> None:
        """Re-assign a foot that is not in contact to the segment under its sole."""
        cur = self.segment[foot]
        if self.datas[cur].in_contact(foot):
            return
        new = self.track.segment_index(sole_point_x(self.feet[foot].kin, self._radius, self._half))
        if new != cur:
            buf = self.datas[new].feet[foot]
            buf.state[:] = 0.0          # landing on another material: fresh intrusion state
            buf.new_state[:] = 0.0
            self.segment[foot] = new

    def evaluate(self, foot: int) -> None:
        """Compute foot ``foot``'s patch forces with the law of its segment (not committed)."""
        self._place(foot)
        d = self.datas[self.segment[foot]]
        d.feet[foot].kin[:] = self.feet[foot].kin
        d.evaluate(foot)

    def skip(self, foot: int) -> None:
        """Foot ``foot`` is clear of the terrain: zero force, contact state reset."""
        self.datas[self.segment[foot]].skip(foot)

    def commit(self) -> None:
        """Accept the evaluated step for each foot in its segment."""
        for i in range(2):
            buf = self.datas[self.segment[i]].feet[i]
            buf.state[:] = buf.new_state

    def reset(self) -> None:
        for d in self.datas:
            d.reset()
        self.segment = [0, 0]

    def in_contact(self, foot: int) -> bool:
        return self.datas[self.segment[foot]].in_contact(foot)

    def segment_of(self, foot: int) -> int:
        """Index of the segment foot ``foot`` is on (0 = left, 1 = right)."""
        return self.segment[foot]

    def set_param(self, name: str, value: float) -> None:
        """Set a parameter: ``"<k>.<name>"`` in segment k, or ``name`` in every segment
        that has it."""
        for d, local in self._targets(name):
            d.set_param(local, value)

    def param(self, name: str) -> float:
        """A parameter's value (``"<k>.<name>"``, or ``name`` of the first segment with it)."""
        d, local = self._targets(name)[0]
        return d.param(local)

    def _targets(self, name: str) -> list[tuple[ContactData, str]]:
        head, _, rest = name.partition(".")
        if head.isdigit() and rest:
            k = int(head)
            if k >= len(self.datas) or rest not in self.datas[k].model.param_names:
                raise ConfigError(f"no parameter {rest!r} in track segment {k}", key="terrain",
                                  value=name)
            return [(self.datas[k], rest)]
        out = [(d, name) for d in self.datas if name in d.model.param_names]
        if not out:
            raise ConfigError(f"no track segment has a parameter {name!r}", key="terrain",
                              value=name)
        return out


def build_track(config, segment_models: Sequence) -> TrackTerrain:
    """The track model of ``config`` from its segments' built terrain models (x order)."""
    return TrackTerrain(config=config, segments=tuple(segment_models))


__all__ = ["TrackTerrain", "TrackContactData", "TrackFoot", "build_track", "sole_point_x"]
