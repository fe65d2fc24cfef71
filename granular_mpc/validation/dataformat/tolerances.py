"""Thresholds of the data-format checks (:class:`FormatTolerances`)."""

from __future__ import annotations

from pydantic import Field

from ...config import NonNegFloat, PositiveFloat, StrictModel


class FormatTolerances(StrictModel):
    """Thresholds of the loader's checks. The defaults suit a YoboGo-10S-class biped.

    Every threshold is on a physical quantity, so it can be reasoned about: change one
    when your data legitimately exceeds it, never to silence a real unit problem.
    """

    quaternion_norm: PositiveFloat = Field(1e-3, description="Allowed | ‖q‖ − 1 | of the trunk quaternion [-].")
    sample_rate: PositiveFloat = Field(0.01, description="Allowed relative difference between 1/median(Δt) and sample_rate_hz [-].")
    step_jitter: float = Field(0.5, gt=0.0, lt=1.0, description="Each Δt must lie within (1 ± this)/sample_rate_hz [-].")
    joint_limit_margin: NonNegFloat = Field(0.1, description="Allowed excursion beyond the URDF position limits [rad].")
    velocity_limit_factor: PositiveFloat = Field(2.0, description="|dq| may reach this multiple of the URDF velocity limit [-].")
    torque_limit_factor: PositiveFloat = Field(2.0, description="|tau| may reach this multiple of the URDF effort limit [-].")
    max_base_height: PositiveFloat = Field(5.0, description="Largest plausible median |base_z| [m].")
    max_base_speed: PositiveFloat = Field(20.0, description="Largest plausible trunk speed (95th percentile) [m/s].")
    max_base_rate: PositiveFloat = Field(50.0, description="Largest plausible trunk angular rate (95th percentile) [rad/s].")
    max_intrusion: PositiveFloat = Field(0.5, description="Largest plausible |intrusion_*| [m] (longer than the leg).")
    max_commanded_speed: PositiveFloat = Field(3.0, description="Largest plausible |commanded_speed_mps| [m/s].")
    rate_correlation: float = Field(0.8, gt=0.0, lt=1.0, description="A velocity column is compared with the time derivative of its position column only when they correlate at least this well [-].")
    rate_ratio: float = Field(2.0, gt=1.0, description="Allowed ratio velocity / derivative of position, either way [-].")
    weight_ratio: float = Field(3.0, gt=1.0, description="Mean vertical GRF over a trial must lie within [1/this, this] × robot weight [-].")
    intrusion_sign: PositiveFloat = Field(0.005, description="Stance intrusion_z below −this for most samples means a flipped sign [m].")
    min_travel_duration: PositiveFloat = Field(0.4, description="Shortest trial whose direction of travel and GRF balance are checked [s].")


__all__ = ["FormatTolerances"]
