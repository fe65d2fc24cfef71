"""The ``meta.yaml`` schema of a data set (format v1): data set, trials, generator.

Unknown keys are errors; :mod:`.checks_meta` turns pydantic's errors into
:class:`~granular_mpc.exceptions.DataProblem` s, :func:`granular_mpc.config.validate` into
one :class:`~granular_mpc.exceptions.ConfigError` (in-memory meta).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Iterable, Literal

from pydantic import Field, StringConstraints, field_validator, model_validator

from ...config import EffectSpec, FiniteFloat, NonNegFloat, PositiveFloat, StrictModel
from .channels import ChannelGroup

SCHEMA_VERSION = 1
"""The format version this package reads and writes."""
SUFFIXES = {"csv": ".csv", "parquet": ".parquet"}
"""Trial file format → file name suffix."""

#: How long a logged torque command is held after its stamp [s] (a zero-order hold; at
#: most 0.1 s — a 10 Hz controller)
TorqueHold = Annotated[float, Field(ge=0.0, le=0.1)]
TrialName = Annotated[str, StringConstraints(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$",
                                             max_length=200)]


def file_name_error(name: str) -> str:
    """Why ``name`` is not a valid trial file name, or ``""``."""
    if not name or name in (".", "..") or "/" in name or "\\" in name:
        return (f"{name!r} must be a file name inside the data set folder, "
                "without a directory part")
    if Path(name).suffix.lower() not in SUFFIXES.values():
        return f"{name!r} must end in .csv or .parquet"
    return ""


def shared_files(pairs: Iterable[tuple[str, str]]) -> list[str]:
    """Messages for trials that name the same file (compared case-insensitively).

    Args:
        pairs: (trial name, file name) per trial, in ``meta.yaml`` order.
    """
    seen: dict[str, str] = {}
    out = []
    for name, file in pairs:
        key = file.lower()                    # case-insensitive file systems
        if key in seen:
            out.append(f"trials {seen[key]!r} and {name!r} use the same file {file!r}")
        else:
            seen[key] = name
    return out


class TrialMeta(StrictModel):
    """One trial: its file and what the robot was asked to do."""

    file: str = Field(description="Trial file name in the data set folder, *.csv or *.parquet.")
    commanded_speed_mps: FiniteFloat = Field(
        description="Commanded forward walking speed along world x [m/s].")
    description: str = Field("", description="Free-form notes on this trial.")

    @field_validator("file")
    @classmethod
    def _plain_file_name(cls, value: str) -> str:
        problem = file_name_error(value)
        if problem:
            raise ValueError(problem)
        return value


class GeneratorMeta(StrictModel):
    """Provenance of a synthetic data set (written by ``granular-mpc synth``)."""

    scenario: str = Field("", description="Scenario file the plant was configured from.")
    seed: int | None = Field(None, description="Random seed of the noise and of the plant.")
    effects: list[EffectSpec] = Field(default_factory=list,
                                      description="Extra physical effects injected in the plant.")
    noise: dict[str, NonNegFloat] = Field(
        default_factory=dict,
        description="Standard deviation of the additive Gaussian noise per column or column "
                    "prefix (e.g. 'grf_', 'q_'), in that column's unit.")
    settings: dict[str, Any] = Field(default_factory=dict,
                                     description="Any further generator settings (free-form).")


class DatasetMeta(StrictModel):
    """Contents of ``meta.yaml`` (format v1). Unknown keys are errors.

    Example::

        schema_version: 1
        robot: yobogo10s
        terrain: dry play sand, 12 cm layer, loosened between trials
        sample_rate_hz: 500
        trials:
          trial_001: {file: trial_001.csv, commanded_speed_mps: 0.2}
          trial_002: {file: trial_002.csv, commanded_speed_mps: 0.3}
    """

    schema_version: Literal[1] = Field(description="Format version; this loader reads 1.")
    robot: str = Field(min_length=1, description="Robot model name in models/ (or a path).")
    terrain: str = Field(description="Free-form description of the ground.")
    sample_rate_hz: PositiveFloat = Field(description="Nominal sample rate of every trial [Hz].")
    trials: dict[TrialName, TrialMeta] = Field(min_length=1,
                                               description="Trial name → trial entry.")
    description: str = Field("", description="Free-form notes on the data set.")
    torque_hold_s: TorqueHold | None = Field(
        None,
        description="The tau_* columns are commands held for this long after their time stamp "
                    "(a zero-order hold: 0.002 for a 500 Hz controller that logs its command "
                    "at the tick) [s]. A held torque acts, on average, half the hold after its "
                    "stamp; the diagnosis' joint torque equation error pairs the kinematics at "
                    "t with τ(t − hold/2). Absent: the torque acts at its stamp.")
    generator: GeneratorMeta | None = Field(None, description="Set for synthetic data.")
    channels: list[ChannelGroup] | None = Field(
        None, description="Channel groups measured (joint_angles, joint_velocities, "
        "joint_torques, trunk_orientation, trunk_angular_velocity, trunk_position, "
        "trunk_linear_velocity, foot_force, intrusion); absent: all of them. The columns of "
        "a group not listed must be absent from the trial files.")

    @field_validator("channels")
    @classmethod
    def _channels_listed_once(cls, value: list[ChannelGroup] | None) -> list[ChannelGroup] | None:
        if value is None:
            return value
        if not value:
            raise ValueError("channels: list at least one channel group (or leave the key out: "
                             "all groups measured)")
        twice = sorted({g.value for g in value if value.count(g) > 1})
        if twice:
            raise ValueError(f"channels: {', '.join(twice)} listed more than once")
        return value

    @model_validator(mode="after")
    def _files_unique(self) -> "DatasetMeta":
        shared = shared_files([(n, t.file) for n, t in self.trials.items()])
        if shared:
            raise ValueError("; ".join(shared))
        return self


__all__ = ["SCHEMA_VERSION", "SUFFIXES", "TorqueHold", "TrialName", "file_name_error",
           "shared_files", "TrialMeta", "GeneratorMeta", "DatasetMeta"]
