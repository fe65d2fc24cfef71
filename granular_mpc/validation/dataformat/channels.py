"""Channel groups: which kinds of measurement a data set carries (``meta.yaml`` ``channels``).

A lab measures what its sensors give: joint encoders and motor currents, an IMU, sometimes
foot force or motion capture, rarely intrusion. ``meta.yaml`` may list the groups that
were measured; a group that is not listed must be **absent** from the trial files (never
zero-filled), a listed one must be complete. Without a ``channels`` key every group is
measured (format v1 as it always was).

=========================  ==========================================  ===========
group                      columns                                     unit, frame
=========================  ==========================================  ===========
``joint_angles``           ``q_<joint>``                               rad
``joint_velocities``       ``dq_<joint>``                              rad/s
``joint_torques``          ``tau_<joint>``                             N·m
``trunk_orientation``      ``base_qw, base_qx, base_qy, base_qz``      B in W
``trunk_angular_velocity`` ``base_wx, base_wy, base_wz``               rad/s, B
``trunk_position``         ``base_x, base_y, base_z``                  m, W
``trunk_linear_velocity``  ``base_vx, base_vy, base_vz``               m/s, W
``foot_force``             ``grf_x, grf_y, grf_z``                     N, W
``intrusion``              ``intrusion_x, intrusion_y, intrusion_z``   m, W axes
=========================  ==========================================  ===========

Replay and diagnosis ask ``dataset.has(ChannelGroup.FOOT_FORCE)`` rather than looking
for columns. A copy of a data set without some groups: :func:`.drop.drop_channels`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Iterable, Iterator, Sequence

from ...columns import (BASE_ANGULAR_VELOCITY, BASE_LINEAR_VELOCITY, BASE_POSITION,
                        BASE_QUATERNION, GRF_COLUMNS, INTRUSION_COLUMNS, joint_columns)


class ChannelGroup(str, Enum):
    """One group of measured channels (its value is the name used in ``meta.yaml``)."""

    JOINT_ANGLES = "joint_angles"
    JOINT_VELOCITIES = "joint_velocities"
    JOINT_TORQUES = "joint_torques"
    TRUNK_ORIENTATION = "trunk_orientation"
    TRUNK_ANGULAR_VELOCITY = "trunk_angular_velocity"
    TRUNK_POSITION = "trunk_position"
    TRUNK_LINEAR_VELOCITY = "trunk_linear_velocity"
    FOOT_FORCE = "foot_force"
    INTRUSION = "intrusion"

    def columns(self, joint_names: Sequence[str]) -> tuple[str, ...]:
        """The format-v1 columns of this group for a robot with ``joint_names``."""
        kind = _JOINT_KIND.get(self)
        if kind is not None:
            return tuple(joint_columns(joint_names, kind))
        return _FIXED_COLUMNS[self]


_JOINT_KIND = {ChannelGroup.JOINT_ANGLES: "q", ChannelGroup.JOINT_VELOCITIES: "dq",
               ChannelGroup.JOINT_TORQUES: "tau"}
_FIXED_COLUMNS: dict[ChannelGroup, tuple[str, ...]] = {
    ChannelGroup.TRUNK_ORIENTATION: BASE_QUATERNION,
    ChannelGroup.TRUNK_ANGULAR_VELOCITY: BASE_ANGULAR_VELOCITY,
    ChannelGroup.TRUNK_POSITION: BASE_POSITION,
    ChannelGroup.TRUNK_LINEAR_VELOCITY: BASE_LINEAR_VELOCITY,
    ChannelGroup.FOOT_FORCE: GRF_COLUMNS,
    ChannelGroup.INTRUSION: INTRUSION_COLUMNS,
}
_PREFIX_KIND = {"q_": ChannelGroup.JOINT_ANGLES, "dq_": ChannelGroup.JOINT_VELOCITIES,
                "tau_": ChannelGroup.JOINT_TORQUES}


def group_of_column(column: str) -> ChannelGroup | None:
    """The group a format-v1 column belongs to (``q_knee`` → joint angles), or None."""
    for group, cols in _FIXED_COLUMNS.items():
        if column in cols:
            return group
    for prefix, group in _PREFIX_KIND.items():
        if column.startswith(prefix):
            return group
    return None


@dataclass(frozen=True)
class ChannelSet:
    """The channel groups a data set carries.

    Attributes:
        groups: the measured groups.
        declared: True if ``meta.yaml`` lists them (False: no ``channels`` key, all
            groups measured, format v1 as before).
    """

    groups: frozenset[ChannelGroup]
    declared: bool = True

    @classmethod
    def all(cls) -> "ChannelSet":
        """Every group, undeclared (a data set without a ``channels`` key)."""
        return cls(frozenset(ChannelGroup), declared=False)

    @classmethod
    def of(cls, groups: Iterable[ChannelGroup | str] | None) -> "ChannelSet":
        """From ``meta.channels`` (None: :meth:`all`)."""
        if groups is None:
            return cls.all()
        return cls(frozenset(ChannelGroup(g) for g in groups), declared=True)

    def has(self, *groups: ChannelGroup | str) -> bool:
        """True if every one of ``groups`` was measured."""
        return all(ChannelGroup(g) in self.groups for g in groups)

    @property
    def missing(self) -> tuple[ChannelGroup, ...]:
        """The groups not measured, in :class:`ChannelGroup` order."""
        return tuple(g for g in ChannelGroup if g not in self.groups)

    def columns(self, joint_names: Sequence[str]) -> list[str]:
        """The format-v1 columns of the measured groups, in :class:`ChannelGroup` order."""
        out: list[str] = []
        for g in self:
            out += g.columns(joint_names)
        return out

    def __iter__(self) -> Iterator[ChannelGroup]:
        return (g for g in ChannelGroup if g in self.groups)

    def __len__(self) -> int:
        return len(self.groups)

    def __contains__(self, group: object) -> bool:
        try:
            return ChannelGroup(group) in self.groups       # type: ignore[arg-type]
        except ValueError:
            return False

    def __str__(self) -> str:
        return ", ".join(g.value for g in self) or "(none)"


__all__ = ["ChannelGroup", "ChannelSet", "group_of_column"]
