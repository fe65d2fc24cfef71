"""Robot section of the config (``models/<robot>.yaml``): URDF plus what the URDF cannot say."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from .base import FiniteFloat, NonNegFloat, PositiveFloat, StrictModel


class FootGeometry(StrictModel):
    """Semi-cylindrical rigid sole: a circular arc in the foot's x–z plane, extruded along y."""

    chord: PositiveFloat = Field(0.075, description="Chord of the sole arc along x [m].")
    height: PositiveFloat = Field(0.024, description="Arc height (sagitta) [m].")
    width: PositiveFloat = Field(0.063, description="Width W along y [m].")
    slices: int = Field(2, ge=1, le=8, description="Contact patches across the width (roll/yaw moments).")

    @model_validator(mode="after")
    def _check(self) -> "FootGeometry":
        if self.height > self.chord / 2:
            raise ValueError("foot.height must not exceed chord/2 (arc at most a half circle)")
        return self

    @property
    def radius(self) -> float:
        """Arc radius R = (c²/4 + h²) / (2h) [m]."""
        return (self.chord ** 2 / 4.0 + self.height ** 2) / (2.0 * self.height)

    @property
    def half_angle(self) -> float:
        """Half-angle ψ_max of the arc about the foot's −z axis [rad]."""
        return math.asin(self.chord / (2.0 * self.radius))


class FootConfig(StrictModel):
    frame: str = Field(description="URDF frame at the centre of the sole arc; x forward, z up.")


class RobotConfig(StrictModel):
    """A biped description: URDF plus what the URDF cannot say."""

    name: str
    urdf: str = Field(description="URDF path, relative to the robot YAML file.")
    joints: list[str] = Field(min_length=6, max_length=6,
                              description="Actuated joints: left hip abd., hip pitch, knee, then right.")
    feet: dict[Literal["left", "right"], FootConfig]
    foot: FootGeometry = Field(default_factory=FootGeometry)
    standing_joints: list[FiniteFloat] = Field(min_length=6, max_length=6,
                                                description="Nominal standing joint angles [rad].")
    joint_damping: NonNegFloat = Field(0.0, description="Viscous joint damping [N·m·s/rad].")
    source_dir: str = Field("", description="Folder of the robot file (filled in by the loader).")

    @property
    def urdf_path(self) -> Path:
        p = Path(self.urdf)
        return p if p.is_absolute() else Path(self.source_dir) / p


__all__ = ["FootGeometry", "FootConfig", "RobotConfig"]
