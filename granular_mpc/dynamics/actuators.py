"""Joint losses and a simple motor model for the plant's actuators (``sim.actuators``).

Everything here is off by default: the plant's actuators are then ideal torque sources
(the commanded joint torque reaches the joint, the energy spent is the mechanical work).
Switched on, per actuated joint (joint side, actuator order, SI units):

* **friction** (``sim.actuators.friction``): τ_f = −τ_c tanh(q̇ / ω_s) − b q̇, added to
  the joint torque. ``sign(q̇)`` is regularised by ``tanh`` with the velocity scale ω_s
  (not a stick–slip switch): the force is a smooth function of the state, so the
  integrator's one-evaluation-per-step Verlet scheme and its exact ``M⁻¹Δτ`` torque
  correction stay valid. Near q̇ = 0 it acts as a viscous damper of slope τ_c/ω_s; an
  explicit step is monotone for dt · λ_max(M⁻¹_aa C) ≤ 1 (C = diag(τ_c/ω_s + b)), which
  :meth:`ActuatorModel.check_step` checks over the joint range when the plant is built.
  The price: no true sticking — a joint loaded by |τ| < τ_c creeps at q̇ = ω_s atanh(τ/τ_c).
* **motor** (``sim.actuators.motor``): gear ratio N, rotor inertia J_r about its spin axis;
  the reflected inertia N² J_r is added to the joint's diagonal of the mass matrix
  (Pinocchio's ``model.armature``, honoured by ABA, CRBA, ``computeMinverse``, RNEA and the
  kinetic energy — on a copy of the robot model that only the plant uses; the rotor's
  gyroscopic coupling to the link is neglected); the torque–speed envelope clips the
  command: in the motoring quadrant (τ q̇ > 0) |τ| ≤ min(τ_peak, τ_stall (1 − |q̇|/q̇_0))
  (≥ 0), otherwise |τ| ≤ τ_peak;
* **electrical power** (always available as a read-out, whether or not the motor model is
  on): P_elec = τ_m q̇ + R_w (τ_m / (k_t N))², τ_m the motor torque at the joint, i.e.
  mechanical output plus copper loss. Negative when the joint is back-driven
  (regeneration); whether that energy is recovered is the analysis's choice.

Parameter defaults and their sources: docs/model.md §3.1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..config.scenario import ActuatorsConfig
from ..exceptions import ConfigError


def _per_joint(values, n: int, key: str) -> np.ndarray:
    """Expand a config list (three: abd, hip, knee of every leg; or ``n``) to ``n`` joints."""
    arr = np.asarray(values, dtype=float)
    if arr.size == n:
        return arr.copy()
    if arr.size == 3 and n % 3 == 0:
        return np.tile(arr, n // 3)
    raise ConfigError(f"has {arr.size} values for {n} actuated joints", key=key,
                      value=list(values), allowed=f"one, three or {n} values")


@dataclass(frozen=True)
class ActuatorModel:
    """Joint friction and motor parameters per actuated joint (arrays in actuator order).

    Build with :meth:`from_config`. The plant uses it only where a switch is on
    (:attr:`active`, :attr:`armature`); :meth:`electrical_power` works in any case.

    Attributes:
        friction: joint friction on.
        coulomb: τ_c [N·m]; viscous: b [N·m·s/rad]; velocity_scale: ω_s [rad/s].
        motor: motor model on; reflected_inertia, torque_speed_limit: its two parts.
        gear_ratio: N [-]; rotor_inertia: J_r [kg·m²].
        peak_torque: τ_peak [N·m]; stall_torque: τ_stall [N·m]; no_load_speed: q̇_0 [rad/s]
            (all at the joint).
        torque_constant: k_t [N·m/A] (at the motor); winding_resistance: R_w [Ω].
    """

    friction: bool
    coulomb: np.ndarray
    viscous: np.ndarray
    velocity_scale: float
    motor: bool
    reflected_inertia: bool
    torque_speed_limit: bool
    gear_ratio: np.ndarray
    rotor_inertia: np.ndarray
    peak_torque: np.ndarray
    stall_torque: np.ndarray
    no_load_speed: np.ndarray
    torque_constant: np.ndarray
    winding_resistance: np.ndarray

    @classmethod
    def from_config(cls, config: ActuatorsConfig, urdf_torque_limits: np.ndarray) -> "ActuatorModel":
        """The model of ``config`` (``sim.actuators``) for a robot whose URDF effort limits
        are ``urdf_torque_limits`` [N·m] (actuator order; the default peak torque)."""
        n = len(urdf_torque_limits)
        f, m = config.friction, config.motor
        pre = "sim.actuators."

        def per(values, key):
            return _per_joint(values, n, pre + key)

        peak = (np.asarray(urdf_torque_limits, dtype=float).copy() if m.peak_torque is None
                else per(m.peak_torque, "motor.peak_torque"))
        return cls(friction=f.enabled, coulomb=per(f.coulomb, "friction.coulomb"),
                   viscous=per(f.viscous, "friction.viscous"),
                   velocity_scale=float(f.velocity_scale),
                   motor=m.enabled, reflected_inertia=m.reflected_inertia,
                   torque_speed_limit=m.torque_speed_limit,
                   gear_ratio=per(m.gear_ratio, "motor.gear_ratio"),
                   rotor_inertia=per(m.rotor_inertia, "motor.rotor_inertia"),
                   peak_torque=peak, stall_torque=per(m.stall_torque, "motor.stall_torque"),
                   no_load_speed=per(m.no_load_speed, "motor.no_load_speed"),
                   torque_constant=per(m.torque_constant, "motor.torque_constant"),
                   winding_resistance=per(m.winding_resistance, "motor.winding_resistance"))

    # ------------------------------------------------------------------ switches
    @property
    def limits_torque(self) -> bool:
        """Whether the command is clipped to the torque–speed envelope."""
        return self.motor and self.torque_speed_limit

    @property
    def active(self) -> bool:
        """Whether the joint torques differ from the command (friction or clipping)."""
        return self.friction or self.limits_torque

    @property
    def armature(self) -> np.ndarray:
        """Reflected rotor inertia N² J_r on each joint's diagonal [kg·m²] (zeros when off)."""
        if self.motor and self.reflected_inertia:
            return self.gear_ratio ** 2 * self.rotor_inertia
        return np.zeros_like(self.gear_ratio)

    # ------------------------------------------------------------------ torques
    def friction_torque(self, dq: np.ndarray) -> np.ndarray:
        """τ_f = −τ_c tanh(q̇/ω_s) − b q̇ [N·m] at joint rates ``dq`` [rad/s] (zeros when off)."""
        dq = np.asarray(dq, dtype=float)
        if not self.friction:
            return np.zeros_like(dq)
        return -self.coulomb * np.tanh(dq / self.velocity_scale) - self.viscous * dq

    def torque_bound(self, tau: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Largest |τ| [N·m] the motor delivers in the direction of ``tau`` at ``dq`` [rad/s].

        Motoring (τ q̇ > 0): min(τ_peak, max(0, τ_stall (1 − |q̇|/q̇_0))); braking or at
        rest: τ_peak.
        """
        tau, dq = np.asarray(tau, dtype=float), np.asarray(dq, dtype=float)
        line = np.maximum(self.stall_torque * (1.0 - np.abs(dq) / self.no_load_speed), 0.0)
        return np.where(tau * dq > 0.0, np.minimum(self.peak_torque, line), self.peak_torque)

    def motor_torque(self, tau_cmd: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Joint torque τ_m [N·m] the motor delivers for the command ``tau_cmd`` at ``dq``:
        the command clipped to :meth:`torque_bound` (the command itself when the limit is off)."""
        tau_cmd = np.asarray(tau_cmd, dtype=float)
        if not self.limits_torque:
            return tau_cmd.copy()
        bound = self.torque_bound(tau_cmd, dq)
        return np.clip(tau_cmd, -bound, bound)

    def electrical_power(self, tau_motor: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """P_elec = τ_m q̇ + R_w (τ_m / (k_t N))² per joint [W] (negative: regenerating).

        Args:
            tau_motor: motor torque at the joint τ_m [N·m] (the delivered torque, before
                joint friction), actuator order.
            dq: joint rates [rad/s].
        """
        tau_motor, dq = np.asarray(tau_motor, dtype=float), np.asarray(dq, dtype=float)
        current = tau_motor / (self.torque_constant * self.gear_ratio)
        return tau_motor * dq + self.winding_resistance * current ** 2

    # ------------------------------------------------------------------ model
    def dynamics_model(self, model: pin.Model, idx_v: np.ndarray) -> pin.Model:
        """``model`` itself when no reflected inertia is applied, else a copy whose
        ``armature`` holds N² J_r at the actuated joints ``idx_v`` (the original, which the
        controller uses, is not changed)."""
        arm = self.armature
        if not arm.any():
            return model
        out = pin.Model(model)
        armature = np.array(out.armature)
        armature[np.asarray(idx_v)] += arm
        out.armature = armature
        return out

    def check_step(self, model: pin.Model, configurations, idx_v: np.ndarray,
                   dt: float) -> float:
        """Check that the actuators' velocity slopes are integrable at step ``dt`` [s].

        Linearised, the friction is −C q̇ with C = diag(τ_c/ω_s + b), plus τ_stall/q̇_0 when
        the torque–speed envelope is on (the slope of its voltage line); an explicit step
        (both integrators of the plant) multiplies the joint velocities by
        (1 − dt M⁻¹_aa C), which is monotone (no sign-flipping chatter) when
        ρ = dt · λ_max(M⁻¹_aa C) ≤ 1. M⁻¹_aa (the actuated block of M⁻¹: free-floating, no
        contact — the smallest effective inertias) depends on the joint angles only; ρ is
        the largest over ``configurations``.

        Returns:
            ρ [-] (0 when neither friction nor the envelope is on).

        Raises:
            ConfigError: ρ > 1, naming ``sim.actuators.friction.velocity_scale`` (or
                ``sim.actuators.motor.no_load_speed`` when friction is off).
        """
        if not self.active:
            return 0.0
        data = model.createData()
        idx = np.asarray(idx_v)
        c = np.zeros_like(self.gear_ratio)
        if self.friction:
            c = c + self.coulomb / self.velocity_scale + self.viscous
        if self.limits_torque:
            c = c + self.stall_torque / self.no_load_speed
        sqrt_c = np.sqrt(c)
        rho = 0.0
        for q in configurations:
            minv = pin.computeMinverse(model, data, q)
            minv = np.triu(minv) + np.triu(minv, 1).T
            # λ(M⁻¹_aa C) = λ(C^½ M⁻¹_aa C^½), a symmetric matrix
            sym = sqrt_c[:, None] * minv[np.ix_(idx, idx)] * sqrt_c[None, :]
            rho = max(rho, dt * float(np.linalg.eigvalsh(sym).max()))
        if rho > 1.0:
            what = ("raise the friction's velocity scale" if self.friction
                    else "raise the no-load speed or lower the stall torque")
            key = ("sim.actuators.friction.velocity_scale" if self.friction
                   else "sim.actuators.motor.no_load_speed")
            raise ConfigError(
                f"joint velocity slope too stiff for sim.dt = {dt:g} s: dt·λ_max(M⁻¹ C) = "
                f"{rho:.2f} > 1 (C = τ_c/ω_s + b + τ_stall/q̇_0); {what}, or lower sim.dt",
                key=key, value=self.velocity_scale if self.friction else list(self.no_load_speed),
                allowed="dt·λ_max(M⁻¹ C) ≤ 1")
        return rho


def joint_range_samples(q_ref: np.ndarray, idx_q: np.ndarray, lower: np.ndarray,
                        upper: np.ndarray, n: int = 64, seed: int = 0) -> list[np.ndarray]:
    """``q_ref`` and ``n`` configurations with joint angles drawn uniformly in
    [``lower``, ``upper``] [rad] (fixed ``seed``: the same set every time) — what
    :meth:`ActuatorModel.check_step` scans."""
    rng = np.random.default_rng(seed)
    out = [np.asarray(q_ref, dtype=float)]
    for _ in range(n):
        q = out[0].copy()
        q[np.asarray(idx_q)] = rng.uniform(lower, upper)
        out.append(q)
    return out


__all__ = ["ActuatorModel", "joint_range_samples"]
