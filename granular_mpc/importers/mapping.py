"""The mapping file of an import: which topic / column is which channel, in which unit,
order and frame, and how the streams' clocks line up (``docs/import.md``).

Unknown keys are errors (with their dotted path and a did-you-mean hint), like every
configuration file of the package.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from ..columns import (BASE_ANGULAR_VELOCITY, BASE_LINEAR_VELOCITY, BASE_POSITION,
                       BASE_QUATERNION, GRF_COLUMNS, INTRUSION_COLUMNS, JointKind, foot_column)
from ..config import FiniteFloat, PositiveFloat, StrictModel, load_yaml, validate
from ..validation.dataformat.meta import TorqueHold

#: vector targets of a channel entry → the data set columns they fill (in field order)
VECTOR_TARGETS: dict[str, tuple[str, ...]] = {
    "trunk_orientation": BASE_QUATERNION,
    "trunk_angular_velocity": BASE_ANGULAR_VELOCITY,
    "trunk_position": BASE_POSITION,
    "trunk_linear_velocity": BASE_LINEAR_VELOCITY,
    "foot_force": GRF_COLUMNS,
    "intrusion": INTRUSION_COLUMNS,
    "left_foot_force": tuple(foot_column("left", c) for c in GRF_COLUMNS),
    "right_foot_force": tuple(foot_column("right", c) for c in GRF_COLUMNS),
}
FOOT_FORCE_TARGETS = ("left_foot_force", "right_foot_force")
#: single data set columns a channel entry may fill (the components of the vector targets)
COLUMN_TARGETS: tuple[str, ...] = tuple(dict.fromkeys(
    c for cols in VECTOR_TARGETS.values() for c in cols))


class ChannelMap(StrictModel):
    """One channel of a stream: where it is in the message / file and what it becomes.

    ``field`` names a message attribute by dotted path (``wrench.force``: a vector message
    whose x, y, z [, w] are read; ``pose.position.z``: one number) or, in a CSV/Parquet
    file, one column. ``fields`` lists one path / column per component instead (x, y, z;
    for a quaternion in the order given by ``order``).
    """

    to: str = Field(description="A vector target (trunk_orientation, trunk_angular_velocity, "
                    "trunk_position, trunk_linear_velocity, foot_force, intrusion, "
                    "left_foot_force, right_foot_force) or one data set column (base_z, "
                    "grf_z, …).")
    field: str | None = Field(None, description="Dotted message path or column name.")
    fields: list[str] | None = Field(None, description="One path / column per component.")
    scale: FiniteFloat = Field(1.0, description="Multiply by this to get SI units (deg→rad "
                               "0.0174533, mN→N 0.001, mm→m 0.001; −1 flips a sign).")
    order: Literal["wxyz", "xyzw"] = Field("xyzw", description="Quaternion component order "
                                           "(ROS messages: xyzw). trunk_orientation only.")
    frame: Literal["world", "foot"] = Field("world", description="Frame of a foot force: "
                                            "'foot' = the robot's foot frame F, rotated to W "
                                            "with the leg kinematics and the trunk orientation.")

    @model_validator(mode="after")
    def _one_source(self) -> "ChannelMap":
        if self.to not in VECTOR_TARGETS and self.to not in COLUMN_TARGETS:
            raise ValueError(f"unknown target to: {self.to!r}; allowed: "
                             f"{', '.join(VECTOR_TARGETS)}, or one data set column: "
                             f"{', '.join(COLUMN_TARGETS)}")
        if (self.field is None) == (self.fields is None):
            raise ValueError("give either field or fields")
        if self.fields is not None and self.to in VECTOR_TARGETS \
                and len(self.fields) != len(VECTOR_TARGETS[self.to]):
            raise ValueError(f"{self.to} needs {len(VECTOR_TARGETS[self.to])} fields, "
                             f"got {len(self.fields)}")
        if self.frame == "foot" and self.to not in FOOT_FORCE_TARGETS:
            raise ValueError("frame: foot is for left_foot_force / right_foot_force only")
        return self


class StreamMap(StrictModel):
    """One stream: a bag topic or a CSV / Parquet file, with its own clock."""

    source: str = Field(description="Bag topic (/joint_states) or file name (relative to the "
                        "log folder, or absolute).")
    time: str = Field("header", description="Bag: 'header' (header.stamp) or 'receive' (the "
                      "bag's log time). File: the time column.")
    time_scale: PositiveFloat = Field(1.0, description="File time × this = seconds (ms: 0.001).")
    time_offset_s: FiniteFloat = Field(0.0, description="Added to this stream's time [s] to "
                                       "bring it onto the common clock.")
    joint_state: dict[JointKind, str] = Field(
        default_factory=dict, description="sensor_msgs/JointState: kind (q, dq, tau) → array "
        "field (position, velocity, effort); joints named by the message's name field.")
    joint_columns: dict[JointKind, str] = Field(
        default_factory=dict, description="Files: kind → column pattern with {joint} (the "
        "log's joint name), e.g. q: '{joint}_pos_deg'.")
    joint_scale: dict[JointKind, FiniteFloat] = Field(
        default_factory=dict, description="Unit scale per joint kind (deg→rad 0.0174533).")
    channels: list[ChannelMap] = Field(default_factory=list)


class ImportMapping(StrictModel):
    """The mapping file: robot, trial, output rate, joint names and the streams."""

    robot: str = Field(min_length=1, description="Robot model name in models/ (or a path).")
    terrain: str = Field(description="Free-form description of the ground.")
    sample_rate_hz: PositiveFloat = Field(description="Rate of the written data set [Hz]; "
                                          "every stream is interpolated onto one grid.")
    trial: str = Field("trial_001", pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$",
                       description="Trial name in the data set.")
    commanded_speed_mps: FiniteFloat = Field(description="Commanded walking speed along +x [m/s].")
    description: str = Field("", description="Free-form notes, copied to meta.yaml.")
    torque_hold_s: TorqueHold | None = Field(
        None,
        description="How long the controller holds each logged torque command [s] (its "
                    "period when it logs the command at the tick: 0.002 at 500 Hz); copied "
                    "to meta.yaml (docs/data-format.md). Omit when the torques are measured.")
    joint_names: dict[str, str] = Field(default_factory=dict, description="Log joint name → "
                                        "robot joint name (unlisted names are used as they are).")
    streams: list[StreamMap] = Field(min_length=1)


def load_mapping(path: str | Path) -> ImportMapping:
    """Read and validate a mapping file.

    Raises:
        ConfigError: unreadable file, unknown key, wrong type (with the dotted key path).
    """
    return validate(ImportMapping, load_yaml(path), source=str(path))


__all__ = ["VECTOR_TARGETS", "FOOT_FORCE_TARGETS", "ChannelMap", "StreamMap", "ImportMapping",
           "load_mapping"]
