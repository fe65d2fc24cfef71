"""Controller section of the config: gait, swing, foothold, MPC, WBC, and the command.

See ``docs/controller.md`` for what each gain does.
"""

from __future__ import annotations

from typing import Literal, Union

from pydantic import Field

from .base import NonNegFloat, PositiveFloat, StrictModel


class GaitConfig(StrictModel):
    """Periodic gait: each leg swings for ``swing_fraction`` of the period."""

    period: float = Field(0.4, gt=0.05, le=5.0, description="Gait cycle period T [s].")
    swing_fraction: float = Field(0.5, gt=0.0, le=0.5,
                                  description="Swing share of the cycle per leg; 0.5 = no double support.")
    weight_shift: NonNegFloat = Field(0.5, le=5.0, description="Initial double support shifting the CoM toward the first stance foot [s].")
    load_transfer: Union[Literal["auto"], NonNegFloat] = Field("auto", description="Double support at each touchdown [s]; 'auto': the time a foot needs to sink to the depth that bears the robot's weight at mpc.max_sink_rate (0 on rigid ground).")

    @property
    def double_support(self) -> bool:
        return self.swing_fraction < 0.5 - 1e-9


class SwingConfig(StrictModel):
    height: PositiveFloat = Field(0.10, description="Cycloid apex above the lift-off/touchdown line [m].")
    touchdown_depth: NonNegFloat = Field(0.0, description="Extra target depth below the surface at touchdown [m] (on top of the expected sinkage).")
    kp: PositiveFloat = Field(400.0, description="Swing-foot task stiffness [1/s²].")
    kd: NonNegFloat = Field(40.0, description="Swing-foot task damping [1/s].")


class FootholdConfig(StrictModel):
    """Capture-point (DCM) foothold with a speed-proportional offset, see control/gait.py."""

    step_width: PositiveFloat = Field(0.12, description="Nominal lateral distance between footholds [m] (hips are 0.19 m apart: a narrower stance shortens the yaw lever of the fore-aft ground force, see docs/controller.md).")
    lateral_margin: float = Field(0.6, gt=0.0, le=1.0, description="Step width is narrowed so the gait's lateral force stays within this share of the ground's lateral capacity [-].")
    k_velocity: float = Field(0.0, ge=-0.9, le=2.0, description="Extra scale of the speed offset [-].")
    k_position: NonNegFloat = Field(0.5, description="Walking-line correction: foothold shift per metre off the line per second of stance [1/s].")
    k_speed_integral: NonNegFloat = Field(0.5, description="Integral gain on the forward speed error (after the speed ramp) added to the speed used for footholds [1/s].")
    max_speed_correction: NonNegFloat = Field(0.3, description="Bound on that integral correction [m/s].")
    max_step: PositiveFloat = Field(0.25, description="Largest foothold offset from the capture point, each axis [m].")


class MPCConfig(StrictModel):
    horizon: int = Field(10, ge=2, le=40, description="Number of MPC steps.")
    dt: float = Field(0.04, gt=0.0, le=0.2, description="MPC step [s]; horizon·dt ≥ one gait cycle.")
    rate_hz: float = Field(40.0, gt=0.0, le=1000.0, description="How often the MPC is solved [Hz].")
    weights_orientation: list[NonNegFloat] = Field([30.0, 30.0, 10.0], min_length=3, max_length=3)
    weights_position: list[NonNegFloat] = Field([2.0, 20.0, 200.0], min_length=3, max_length=3)
    weights_angular_velocity: list[NonNegFloat] = Field([1.0, 1.0, 1.0], min_length=3, max_length=3)
    weights_velocity: list[NonNegFloat] = Field([20.0, 5.0, 10.0], min_length=3, max_length=3)
    weight_force: NonNegFloat = Field(1e-5, description="Force regularisation [1/N²].")
    weight_sinkage: NonNegFloat = Field(0.0, description="Penalty on predicted sinkage [1/m²].")
    max_sinkage: PositiveFloat = Field(0.04, description="Sinkage allowed by the force constraints [m].")
    max_sink_rate: PositiveFloat = Field(0.6, description="Fastest planned sinkage of a loading foot [m/s]: the normal force may only grow as fast as the foot sinks into capacity.")
    friction: PositiveFloat = Field(0.6, description="Friction coefficient of the rigid-ground model [-].")
    max_normal_force: PositiveFloat = Field(300.0, description="Upper bound on the normal force per foot [N].")
    com_height: PositiveFloat = Field(0.41, description="Desired CoM height above the undisturbed surface [m].")
    qp: Literal["newton", "scaled", "daqp", "scaled_rows"] = Field("scaled", description="The QP's numerics (control/mpc.py QP_SETTINGS): 'scaled' (the default since session 20: forces in units of m g, ProxSuite's primal-dual LDLT backend, mu_in restarted each solve, eps_abs 1e-5: the optimum to ≈ 0.001 N, worst ≈ 0.01 N), 'newton' (forces in N, ProxSuite's automatic backend, eps_abs 1e-4: stops up to ≈ 10–25 N from the optimum; the default before session 20, which the figures marked as such in docs/results.md used) or 'daqp' (the scaled QP solved by DAQP's dual active set instead of ProxSuite, exact to round-off, about half the solve time; opt-in) or 'scaled_rows' ('scaled' without the polytope rows the others imply: the same optimum, fewer rows; opt-in). docs/speed.md 'The MPC tick'.")


class WBCConfig(StrictModel):
    """Whole-body QP weights and task gains (see control/wbc.py)."""

    rate_hz: float = Field(500.0, gt=0.0, le=5000.0, description="WBC rate [Hz] (torques held between ticks).")
    w_orientation: list[NonNegFloat] = Field([10.0, 10.0, 5.0], min_length=3, max_length=3,
                                             description="Trunk roll, pitch, yaw task weights. Yaw is weak: without a hip-yaw joint the trunk's yaw is the stance foot's, which only rotational slip can change.")
    w_com: NonNegFloat = 20.0
    w_swing: NonNegFloat = 100.0
    w_contact: NonNegFloat = 1000.0
    w_force: NonNegFloat = Field(10.0, description="Weight on tracking the MPC forces [1/N²].")
    w_regularisation: NonNegFloat = 1e-4
    kp_orientation: NonNegFloat = 300.0
    kd_orientation: NonNegFloat = 30.0
    kp_com: NonNegFloat = 100.0
    kd_com: NonNegFloat = 20.0
    solver: Literal["proxsuite", "daqp"] = Field(
        "daqp",
        description="QP solver of the WBC: 'daqp' (the default since session 20) or 'proxsuite' (the default before; proximal augmented Lagrangian, warm started, tolerance 1e-5; ≈ 0.14 ms per solve in the closed loop) or 'daqp' (dual active-set, exact to round-off, hot started from the previous active set, reading the QP where the assembly writes it; ≈ 0.045 ms per solve, WBC tick 0.23 → 0.13 ms). Same QP; solutions equal within ProxSuite's tolerance (docs/speed.md, 'The WBC's solver').")


class ControllerConfig(StrictModel):
    terrain: str = Field("plant", description="Terrain model inside the controller: 'plant' (same as the plant) or a terrain file name.")
    gait: GaitConfig = Field(default_factory=GaitConfig)
    swing: SwingConfig = Field(default_factory=SwingConfig)
    foothold: FootholdConfig = Field(default_factory=FootholdConfig)
    mpc: MPCConfig = Field(default_factory=MPCConfig)
    wbc: WBCConfig = Field(default_factory=WBCConfig)


class CommandConfig(StrictModel):
    speed: float = Field(0.2, ge=-1.0, le=1.5, description="Commanded forward speed [m/s].")
    lateral_speed: float = Field(0.0, ge=-0.5, le=0.5, description="Commanded lateral speed [m/s].")
    max_acceleration: PositiveFloat = Field(0.5, description="Ramp acceleration limit [m/s²] (Ruckig).")
    max_jerk: PositiveFloat = Field(2.0, description="Ramp jerk limit [m/s³] (Ruckig).")
    start_delay: NonNegFloat = Field(0.8, description="Time before the speed ramp starts (weight shift, then stepping in place) [s].")



__all__ = ["GaitConfig", "SwingConfig", "FootholdConfig", "MPCConfig", "WBCConfig",
           "ControllerConfig", "CommandConfig"]
