"""Scenario files (``sim/*.yaml``): what ``granular-mpc run`` and ``granular-mpc sweep`` read.

The simulation, drop-test, fall, push, metrics, output and sweep sections, and the
:class:`ScenarioConfig` that holds them with the robot, terrain and controller sections.
Loading (names → inlined files, ``--set`` overrides): :mod:`granular_mpc.scenario`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Mapping, Optional, Union

from pydantic import AfterValidator, BeforeValidator, Field, field_validator, model_validator

from .base import FiniteFloat, NonNegFloat, PositiveFloat, StrictModel
from .controller import CommandConfig, ControllerConfig
from .robot import RobotConfig
from .terrain import GranularTerrainConfig, RigidTerrainConfig, TerrainConfig


def _per_joint_list(value: Any) -> Any:
    """One number → the same number for the three joints of a leg (abd, hip, knee)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [value] * 3
    return value


def _per_joint_check(positive: bool):
    def check(values: list[float]) -> list[float]:
        if len(values) not in (3, 6):
            raise ValueError(f"give one number, three (abd, hip, knee: both legs) or six "
                             f"(actuator order), not {len(values)} numbers")
        if any((x <= 0.0 if positive else x < 0.0) for x in values):
            raise ValueError(f"every value must be {'> 0' if positive else '≥ 0'}")
        return values
    return check


PerJointNonNeg = Annotated[list[FiniteFloat], BeforeValidator(_per_joint_list),
                           AfterValidator(_per_joint_check(False))]
"""Per actuated joint, each ≥ 0: one number (every joint), three (abd, hip, knee; both legs)
or six (actuator order)."""
PerJointPositive = Annotated[list[FiniteFloat], BeforeValidator(_per_joint_list),
                             AfterValidator(_per_joint_check(True))]
"""As :data:`PerJointNonNeg`, each > 0."""


class JointFrictionConfig(StrictModel):
    """Coulomb + viscous friction in every actuated joint (plant only), joint side:
    τ_f = −τ_c tanh(q̇ / ω_s) − b q̇. Defaults: Mini-Cheetah-class actuators
    (docs/model.md §3.1); off unless ``enabled``."""

    enabled: bool = Field(False, description="Apply joint friction in the plant.")
    coulomb: PerJointNonNeg = Field(0.2, description="Coulomb friction torque τ_c [N·m].")
    viscous: PerJointNonNeg = Field(0.01, description="Viscous friction coefficient b [N·m·s/rad].")
    velocity_scale: PositiveFloat = Field(0.1, description="ω_s of the tanh that smooths sign(q̇) [rad/s].")


class MotorConfig(StrictModel):
    """A geared electric motor per actuated joint (plant only): reflected rotor inertia,
    torque–speed envelope, copper loss. Defaults: Mini-Cheetah-class actuators
    (docs/model.md §3.1); off unless ``enabled`` (ideal torque sources)."""

    enabled: bool = Field(False, description="Apply the motor model in the plant.")
    gear_ratio: PerJointPositive = Field(default_factory=lambda: [6.0, 6.0, 9.33], description="Gear ratio N [-].")
    rotor_inertia: PerJointNonNeg = Field(63.0e-6, description="Rotor inertia J_r about its spin axis [kg·m²].")
    reflected_inertia: bool = Field(True, description="Add N² J_r to the joint's diagonal of the mass matrix.")
    torque_speed_limit: bool = Field(True, description="Clip the torque to the motor's torque–speed envelope.")
    peak_torque: Optional[PerJointPositive] = Field(None, description="Peak joint torque [N·m]; null: the URDF's effort limits.")
    stall_torque: PerJointPositive = Field(default_factory=lambda: [62.4, 62.4, 97.1], description="Joint torque of the voltage line at q̇ = 0 [N·m].")
    no_load_speed: PerJointPositive = Field(default_factory=lambda: [40.0, 40.0, 25.7], description="Joint speed where the voltage line reaches zero torque [rad/s].")
    torque_constant: PerJointPositive = Field(0.075, description="Motor torque per ampere k_t [N·m/A].")
    winding_resistance: PerJointNonNeg = Field(0.2595, description="Copper-loss resistance R_w in P = R_w i² [Ω].")


class ActuatorsConfig(StrictModel):
    """Joint losses and motor model of the plant (all off by default: ideal actuators).
    The controller does not see them (docs/model.md §3.1)."""

    friction: JointFrictionConfig = Field(default_factory=JointFrictionConfig)
    motor: MotorConfig = Field(default_factory=MotorConfig)


class SimConfig(StrictModel):
    """Plant integration: step, integrator, duration, seed, divergence bound, actuators."""

    dt: float = Field(5.0e-4, gt=0.0, le=0.01, description="Plant integration step [s].")
    integrator: Literal["verlet", "semi_implicit_euler"] = "verlet"
    duration: PositiveFloat = Field(2.0, description="Simulated time [s].")
    seed: int = 0
    max_speed: PositiveFloat = Field(200.0, description="Divergence bound on |v| [m/s, rad/s].")
    actuators: ActuatorsConfig = Field(default_factory=ActuatorsConfig, description="Joint losses and motor model of the plant (off: ideal actuators).")
    plant: Optional[Literal["compiled", "reference"]] = Field(None, description="Plant that steps the run: compiled (the plant step as one compiled C function, same physics, ≈ 18× faster) or reference (Pinocchio + Python). Unset: compiled, unless $GRANULAR_MPC_PLANT says otherwise; features the compiled plant does not model (a track terrain, sim.actuators, joint effects CasADi cannot trace) fall back to the reference plant with a one-line note.")


class DropConfig(StrictModel):
    """Drop test: joints held at the standing pose by stiff PD, released above the surface."""

    height: NonNegFloat = Field(0.02, description="Clearance of the lowest sole point above the surface [m].")
    kp: PositiveFloat = Field(150.0, description="Joint PD stiffness [N·m/rad].")
    kd: NonNegFloat = Field(3.0, description="Joint PD damping [N·m·s/rad].")


class PlaybackConfig(StrictModel):
    """Joint playback (``mode: playback``, the paper protocol's fallback): the joint
    references of a recorded run tracked by joint PD, without any balance feedback, as a
    position-controlled servo would (docs/paper.md, "The fallback protocol")."""

    reference: Optional[str] = Field(None, description="Run folder whose log's joint angles, velocities and torques are played back (required in mode 'playback').")
    kp: NonNegFloat = Field(150.0, description="Joint PD stiffness [N·m/rad] (the drop test's servo gains; 0 with feedforward: the recorded torques alone).")
    kd: NonNegFloat = Field(3.0, description="Joint PD damping [N·m·s/rad].")
    feedforward: bool = Field(False, description="Add the recorded joint torques to the PD torques (off: pure PD, as a position servo).")


Vector3 = Annotated[list[FiniteFloat], Field(min_length=3, max_length=3)]
"""Three finite numbers (a vector [x, y, z])."""


class FallConfig(StrictModel):
    """When the closed loop counts as fallen (checked at every controller tick)."""

    enabled: bool = Field(True, description="Detect falls at all.")
    min_trunk_height: PositiveFloat = Field(0.25, description="Fallen when the trunk origin is less than this above the free surface [m] (standing: ≈ 0.47 m).")
    max_roll_deg: float = Field(15.0, gt=0.0, le=180.0, description="Fallen when |trunk roll| exceeds this [deg] (Z-Y-X Euler angles).")
    max_pitch_deg: float = Field(15.0, gt=0.0, le=90.0, description="Fallen when |trunk pitch| exceeds this [deg].")
    stop: bool = Field(True, description="End the run at the fall (else record it and go on).")


class PushConfig(StrictModel):
    """A push on the trunk: a constant world-frame force (and torque) held for ``duration``.

    Give ``force`` [N] or ``impulse`` [N·s] (then force = impulse / duration). ``at: time``
    starts the push at ``time``; ``at: mid_stance`` at the first planned mid-stance (of
    ``side``, or of either foot) at or after ``time``.
    """

    at: Literal["time", "mid_stance"] = "time"
    time: NonNegFloat = Field(description="Start [s] ('time'), or earliest start ('mid_stance').")
    side: Literal["left", "right", "any"] = Field("any", description="Stance foot whose mid-stance starts the push ('mid_stance' only).")
    force: Optional[Vector3] = Field(None, description="Force on the trunk [N], world frame.")
    impulse: Optional[Vector3] = Field(None, description="Impulse on the trunk [N·s], world frame.")
    torque: Vector3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="Torque on the trunk [N·m], world frame.")
    duration: PositiveFloat = Field(0.1, description="How long the push lasts [s].")

    @model_validator(mode="after")
    def _one_of(self) -> "PushConfig":
        if (self.force is None) == (self.impulse is None):
            raise ValueError("give exactly one of 'force' [N] and 'impulse' [N·s]")
        return self

    @property
    def force_W(self) -> list[float]:
        """The force held during the push [N], world frame."""
        if self.force is not None:
            return list(self.force)
        return [i / self.duration for i in self.impulse]


class GuideRigConfig(StrictModel):
    """Drop tests: a vertical guide rail on the trunk (springs and dampers on trunk x, y
    and orientation; vertical motion free), as in a drop-tower experiment."""

    stiffness: PositiveFloat = Field(1.0e5, description="Horizontal spring [N/m].")
    damping: NonNegFloat = Field(1500.0, description="Horizontal damper [N·s/m].")
    rot_stiffness: PositiveFloat = Field(800.0, description="Orientation spring [N·m/rad].")
    rot_damping: NonNegFloat = Field(30.0, description="Orientation damper [N·m·s/rad].")


class MetricsConfig(StrictModel):
    """The window over which summary averages are taken (docs/user-guide.md, summary.json)."""

    settle: NonNegFloat = Field(1.0, description="Time after the end of the speed ramp before averaging starts [s].")


class OutputConfig(StrictModel):
    log_rate_hz: Optional[PositiveFloat] = Field(None, description="Log rows per simulated second [Hz]; default: the WBC rate.")
    flush_every: int = Field(500, ge=1, description="Rows per log part written to disk.")
    plots: bool = Field(True, description="Write DIR/plots/*.png after the run.")
    html_fps: PositiveFloat = Field(30.0, description="Frame rate of DIR/animation.html [1/s].")


class SweepConfig(StrictModel):
    """Runs of one scenario over speeds × terrains (× controller terrains × grid × seeds)."""

    speeds: list[FiniteFloat] = Field(min_length=1, description="Commanded speeds [m/s].")
    terrains: list[str] = Field(min_length=1, description="Plant terrain names (models/terrain/).")
    controller_terrains: list[str] = Field(default_factory=lambda: ["plant"], min_length=1,
                                           description="Controller terrain models ('plant' or terrain names).")
    grid: dict[str, list[Any]] = Field(default_factory=dict, description="Dotted scenario key → values; every combination is run.")
    duration: Optional[PositiveFloat] = Field(None, description="sim.duration of every run [s] (default: the scenario's).")
    seeds: list[int] = Field(default_factory=list, description="sim.seed values (default: the scenario's).")
    plots: bool = Field(False, description="Write each run's plots (slower).")

    @field_validator("grid", mode="before")
    @classmethod
    def _flatten(cls, value: Any) -> Any:
        """``{controller: {mpc: {horizon: [8, 10]}}}`` → ``{"controller.mpc.horizon": [8, 10]}``."""
        if not isinstance(value, Mapping):
            return value
        out: dict[str, Any] = {}

        def walk(prefix: str, node: Any) -> None:
            if isinstance(node, Mapping) and (node or not prefix):
                for k, v in node.items():
                    walk(f"{prefix}.{k}" if prefix else str(k), v)
            else:
                out[prefix] = node
        walk("", value)
        return out


class ScenarioConfig(StrictModel):
    """One closed-loop scenario: robot, plant terrain, controller, command and run options.

    ``robot`` and ``terrain`` are the loaded robot and terrain files (scenario YAML names
    them; :func:`granular_mpc.scenario.load_scenario` inlines them). ``controller_terrain``
    is the loaded file named by ``controller.terrain`` (``None`` when that is ``plant``).
    """

    name: str = Field("scenario", description="Scenario name (default output folder runs/<name>-<time>).")
    description: str = ""
    mode: Literal["walk", "drop", "playback"] = Field("walk", description="'walk': closed-loop walking; 'drop': drop test on a guide rig; 'playback': a recorded run's joint references tracked by joint PD (playback:).")
    robot: RobotConfig
    terrain: TerrainConfig
    controller_terrain: Optional[Annotated[Union[GranularTerrainConfig, RigidTerrainConfig],
                                           Field(discriminator="kind")]] = None
    sim: SimConfig = Field(default_factory=SimConfig)
    controller: ControllerConfig = Field(default_factory=ControllerConfig)
    command: CommandConfig = Field(default_factory=CommandConfig)
    initial_clearance: Optional[float] = Field(None, ge=-0.05, le=0.5, description="Lowest sole point above the free surface at t = 0 [m] (walk); default 0 on rigid ground, −0.005 on sand.")
    drop: DropConfig = Field(default_factory=DropConfig)
    playback: PlaybackConfig = Field(default_factory=PlaybackConfig)
    rig: GuideRigConfig = Field(default_factory=GuideRigConfig)
    fall: FallConfig = Field(default_factory=FallConfig)
    pushes: list[PushConfig] = Field(default_factory=list)
    metrics: MetricsConfig = Field(default_factory=MetricsConfig)
    output: OutputConfig = Field(default_factory=OutputConfig)
    sweep: Optional[SweepConfig] = None

    @model_validator(mode="after")
    def _consistent(self) -> "ScenarioConfig":
        if self.controller.terrain == "plant" and self.controller_terrain is not None:
            raise ValueError("controller_terrain is given but controller.terrain is 'plant'; "
                             "set controller.terrain to a terrain name, or drop controller_terrain")
        if self.mode == "playback" and not self.playback.reference:
            raise ValueError("mode 'playback' needs playback.reference: the run folder whose "
                             "joint references are played back")
        if self.mode == "drop" and self.pushes:
            raise ValueError("pushes are not supported in mode 'drop' (the guide rig holds the trunk)")
        if self.output.log_rate_hz is not None and self.output.log_rate_hz * self.sim.dt > 1.0 + 1e-9:
            raise ValueError(f"output.log_rate_hz = {self.output.log_rate_hz:g} exceeds the plant "
                             f"rate 1/sim.dt = {1.0 / self.sim.dt:g} Hz")
        return self

    @property
    def log_rate_hz(self) -> float:
        """Log rows per simulated second [Hz]."""
        return self.output.log_rate_hz or self.controller.wbc.rate_hz

    @property
    def start_clearance(self) -> float:
        """Clearance of the lowest sole point above the surface at t = 0 [m]."""
        if self.mode == "drop":
            return self.drop.height
        if self.initial_clearance is not None:
            return self.initial_clearance
        return 0.0 if self.terrain.kind == "rigid" else -0.005


__all__ = ["PerJointNonNeg", "PerJointPositive", "JointFrictionConfig", "MotorConfig",
           "ActuatorsConfig", "SimConfig", "DropConfig", "PlaybackConfig", "Vector3", "FallConfig", "PushConfig", "GuideRigConfig",
           "MetricsConfig", "OutputConfig", "SweepConfig", "ScenarioConfig"]
