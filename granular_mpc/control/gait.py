"""Gait schedule, speed command ramps (Ruckig) and foothold selection.

Schedule: after an initial weight shift (both feet down, ``weight_shift`` seconds) each leg
is in stance for ``(1 − swing_fraction)·T`` then swings for ``swing_fraction·T``; the right
leg lags the left by T/2, so stepping starts with the left leg in stance and the right leg
in its first swing. With ``swing_fraction = 0.5``
(the paper's gait: period 0.4 s, 50 % swing) there is no double support. The schedule is
the controller's plan only: the plant decides contact from geometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..config import CommandConfig, FootholdConfig, GaitConfig

LEFT, RIGHT = 0, 1


@dataclass(frozen=True)
class GaitSchedule:
    """Time-based contact plan (model; immutable)."""

    config: GaitConfig

    @property
    def period(self) -> float:
        return self.config.period

    @property
    def swing_duration(self) -> float:
        return self.config.period * self.config.swing_fraction

    @property
    def stance_duration(self) -> float:
        return self.config.period - self.swing_duration

    @property
    def start(self) -> float:
        """End of the initial weight shift: stepping starts here [s]."""
        return self.config.weight_shift

    @cached_property
    def _k(self) -> tuple:
        """The schedule's per-call constants, computed once with the arithmetic of the
        properties above (the same bits): period, start, stance and swing durations [s],
        ``start − 1e-12`` and ``stance_duration − 1e-12`` (the two thresholds) [s], and
        each leg's lag ``foot · 0.5 · period`` [s] (left, right)."""
        period, start, stance, swing = (self.period, self.start, self.stance_duration,
                                        self.swing_duration)
        return (period, start, stance, swing, start - 1e-12, stance - 1e-12,
                (0 * 0.5 * period, 1 * 0.5 * period))

    def standing(self, t: float) -> bool:
        """True during the initial weight shift (both feet down, no stepping yet)."""
        return t < self._k[4]

    def _local(self, t: float, foot: int) -> float:
        """Time since the start of this leg's current cycle (stance first) [s]."""
        period, start, *_, lag = self._k
        return (t - start - lag[foot] + 1e-9) % period - 1e-9

    def in_stance(self, t: float, foot: int) -> bool:
        period, start, _, _, standing_end, stance_end, lag = self._k
        if t < standing_end:
            return True
        return (t - start - lag[foot] + 1e-9) % period - 1e-9 < stance_end

    def contacts(self, t: float) -> tuple[bool, bool]:
        """Planned contact of (left, right) at ``t`` [s]: ``in_stance`` of both legs."""
        period, start, _, _, standing_end, stance_end, lag = self._k
        if t < standing_end:
            return True, True
        return ((t - start - lag[0] + 1e-9) % period - 1e-9 < stance_end,
                (t - start - lag[1] + 1e-9) % period - 1e-9 < stance_end)

    def stance_phase(self, t: float, foot: int) -> float:
        """Progress through the current stance, 0 → 1 (meaningful while in stance)."""
        if self.standing(t):
            return 0.0
        return min(self._local(t, foot) / self._k[2], 1.0)

    def swing_phase(self, t: float, foot: int) -> float:
        """Progress through the current swing, 0 → 1 (meaningful while swinging)."""
        _, _, stance, swing, *_ = self._k
        return min(max((self._local(t, foot) - stance) / swing, 0.0), 1.0)

    def time_to_touchdown(self, t: float, foot: int) -> float:
        """Time until this leg's next scheduled touchdown [s] (0 if in stance)."""
        if self.in_stance(t, foot):
            return 0.0
        return self._k[0] - self._local(t, foot)

    def swing_timing(self, t: float, foot: int) -> tuple[float, float]:
        """``(time_to_touchdown(t, foot), swing_phase(t, foot))`` with the leg's cycle time
        evaluated once (the same numbers) [s, –]."""
        if self.in_stance(t, foot):
            return 0.0, self.swing_phase(t, foot)
        period, _, stance, swing, *_ = self._k
        local = self._local(t, foot)
        return period - local, min(max((local - stance) / swing, 0.0), 1.0)

    def time_to_liftoff(self, t: float, foot: int) -> float:
        """Time until this leg's next scheduled lift-off [s] (0 while swinging)."""
        _, start, stance, *_ = self._k
        if self.standing(t):
            first = start + (stance if foot == LEFT else 0.0)
            return first - t
        return max(stance - self._local(t, foot), 0.0)


class CommandRamp:
    """Jerk-limited velocity command (Ruckig, velocity interface), per axis x and y.

    Before ``start_delay`` the command is zero (stepping in place); then the reference
    velocity ramps to the target with bounded acceleration and jerk. ``reference(t)``
    returns the reference displacement, velocity and acceleration [m, m/s, m/s²] in W.
    """

    def __init__(self, config: CommandConfig, dt: float) -> None:
        from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory

        self.config = config
        inp = InputParameter(2)
        inp.control_interface = ControlInterface.Velocity
        inp.current_position = [0.0, 0.0]
        inp.current_velocity = [0.0, 0.0]
        inp.current_acceleration = [0.0, 0.0]
        inp.target_velocity = [config.speed, config.lateral_speed]
        inp.target_acceleration = [0.0, 0.0]
        inp.max_velocity = [2.0, 2.0]
        inp.max_acceleration = [config.max_acceleration] * 2
        inp.max_jerk = [config.max_jerk] * 2
        self._traj = Trajectory(2)
        result = Ruckig(2).calculate(inp, self._traj)
        if result not in (Result.Working, Result.Finished):
            raise ValueError(f"Ruckig could not plan the speed ramp: {result}")
        self._T = self._traj.duration
        end_p, end_v, end_a = self._traj.at_time(self._T)
        self._end = (np.array(end_p), np.array(end_v))

    @property
    def ramp_duration(self) -> float:
        return self._T

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tau = t - self.config.start_delay
        if tau <= 0.0:
            z = np.zeros(2)
            return z, z.copy(), z.copy()
        if tau >= self._T:
            p, v = self._end
            return p + v * (tau - self._T), v.copy(), np.zeros(2)
        p, v, a = self._traj.at_time(tau)
        return np.array(p), np.array(v), np.array(a)


def foothold(config: FootholdConfig, *, dcm: np.ndarray, v_cmd: np.ndarray,
             stance_duration: float, omega: float, lateral_sign: float,
             y_error: float = 0.0, com_y: float | None = None,
             max_lateral: float | None = None) -> np.ndarray:
    """Horizontal foothold (x, y) in W from the divergent component of motion at touchdown.

    Linear inverted pendulum, ω = √(g/h): the DCM ``ξ = p_com + v_com/ω`` (the capture
    point) obeys ``ξ̇ = ω(ξ − p_foot)``. For a periodic walk at speed v with T between
    successive touchdowns (``stance_duration`` argument; half the gait period) and step
    width w, stepping at

        x_foot = ξ_x − v T/(e^{ωT} − 1)            (speed-proportional, Raibert-type offset)
        y_foot = ξ_y + s·w/(1 + e^{ωT}) + k_p·y_error·T    (s = +1 for the left leg)

    reproduces the same DCM offset every step, so deviations of the DCM (pushes, slip,
    sinkage) are corrected by where the foot lands. The last term walks back to the line:
    stepping further out on the side the CoM drifted to pushes it back. ``dcm`` is the DCM
    predicted for the touchdown instant. The offset from the DCM is clipped to ``max_step``
    (plus w/2 laterally). With ``com_y`` (CoM at touchdown) and ``max_lateral``, the foot
    also stays within ``max_lateral`` of the CoM laterally: the ground can only push the CoM
    back with ``F_y ≈ m ω² (y_com − y_foot)`` up to its lateral capacity
    (``max_lateral = (F_y/F_z)_max · h``).
    """
    e = math.exp(omega * stance_duration)
    dx = -v_cmd[0] * stance_duration / (e - 1.0) * (1.0 + config.k_velocity)
    c = config.step_width / (1.0 + e)
    dy = lateral_sign * c - v_cmd[1] * stance_duration / (e - 1.0) \
        + config.k_position * y_error * stance_duration
    # clips on scalars as min(max(·)) (np.clip's numbers for lo ≤ hi, NaN kept, without its
    # per-call array machinery)
    dx = float(min(max(dx, -config.max_step), config.max_step))
    dy = float(min(max(dy, -config.max_step - 0.5 * config.step_width),
                   config.max_step + 0.5 * config.step_width))
    y = dcm[1] + dy
    if com_y is not None and max_lateral is not None:
        y = float(min(max(y, com_y - max_lateral), com_y + max_lateral))
    return np.array([dcm[0] + dx, y])


def predict_com(com: np.ndarray, vcom: np.ndarray, p_stance: np.ndarray, omega: float,
                dt: float) -> np.ndarray:
    """Horizontal CoM after ``dt`` [s] of stance on ``p_stance`` (linear inverted pendulum)."""
    ch, sh = math.cosh(omega * dt), math.sinh(omega * dt)
    # per component on Python floats: the IEEE operations of the array form
    # p + (c − p)·ch + (v/ω)·sh without NumPy's per-call cost
    px, py = p_stance[0], p_stance[1]
    cx, cy = com[0], com[1]
    vx, vy = vcom[0], vcom[1]
    return np.array((float(px + (cx - px) * ch + vx / omega * sh),
                     float(py + (cy - py) * ch + vy / omega * sh)))


def predict_dcm(dcm: np.ndarray, p_stance: np.ndarray, omega: float, dt: float) -> np.ndarray:
    """DCM after ``dt`` [s] of stance on ``p_stance`` (LIP): ``p + (ξ − p) e^{ω dt}``."""
    e = math.exp(omega * dt)
    # per component on Python floats (the array form's IEEE operations)
    px, py = p_stance[0], p_stance[1]
    return np.array((float(px + (dcm[0] - px) * e), float(py + (dcm[1] - py) * e)))


__all__ = ["GaitSchedule", "CommandRamp", "foothold", "predict_dcm", "predict_com", "LEFT", "RIGHT"]
