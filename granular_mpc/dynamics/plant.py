"""The augmented plant: 3-D floating-base biped (Pinocchio) + per-foot terrain contact.

State: ``q`` (13: base position, base quaternion x y z w, 6 joints) and ``v`` (12: base
twist in the trunk frame, joint rates) plus, per contact patch, the terrain's intrusion
state (anchor, touchdown point C0, contact flag …, see :mod:`granular_mpc.terrain.contact`).
Touchdown and lift-off follow from geometry: a patch is in contact while its lowest sole
point is below the free surface — there is no scripted contact schedule.

Integrators (``sim.integrator``):

* ``verlet`` (default): velocity Verlet, kick–drift–kick, one dynamics evaluation per step
  (the acceleration at the end of a step is reused at the start of the next one and
  corrected exactly, ``Δa = M⁻¹ Δτ``, when the torque command changes). The
  velocity-dependent rigid-body terms are evaluated at a predicted end-of-step velocity,
  which keeps the scheme second order for the floating base: energy error O(dt²).
* ``semi_implicit_euler``: v ← v + dt·a(q, v); q ← q ⊕ dt·v. First order, symplectic.

Both integrate the configuration on its manifold (``pinocchio.integrate``). Joints have
end stops: beyond the URDF position limits a stiff spring–damper pushes back.

Actuators (``sim.actuators``, :mod:`.actuators`): ideal by default. Optional joint friction
and motor model (reflected rotor inertia, torque–speed envelope), unknown to the controller.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..config import SimConfig
from ..exceptions import ConfigError, PlantDivergedError
from ..robot.model import SIDES, Biped
from ..rotations import matrix_from_quat_xyzw
from ..terrain.base import TerrainModel
from ..terrain.contact import ContactData
from .actuators import ActuatorModel, joint_range_samples

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_ZERO_FORCE = pin.Force.Zero()


@dataclass(frozen=True)
class Plant:
    """Immutable plant model: robot, terrain, step. State lives in :class:`PlantData`.

    Attributes:
        biped, terrain, sim: robot, plant terrain, step settings.
        joint_effects: joint-effect hook, empty (off) by default: callables
            ``(q_a [rad], dq_a [rad/s]) -> tau_a [N·m]`` (actuator order) whose sum is added
            to the actuator torques in :meth:`forward`, at the state being evaluated (e.g.
            ``granular_mpc.effects.joint_friction``). The held command
            ``d.tau`` (what a motor-current torque sensor reports) is not changed.
        actuators: the joint-loss and motor model of ``sim.actuators`` (derived).
        model: the Pinocchio model the plant integrates (derived): the robot's, or a copy
            with the reflected rotor inertia as ``armature`` when the motor model adds it.
    """

    biped: Biped
    terrain: TerrainModel
    sim: SimConfig = field(default_factory=SimConfig)
    joint_effects: tuple = ()

    def __post_init__(self) -> None:
        if self.terrain.foot != self.biped.config.foot:
            raise ConfigError("the terrain model was built for another foot geometry",
                              key="terrain", allowed="build_terrain(config, biped.config)")
        if self.actuators.active:              # sim.actuators: integrable at this dt?
            samples = joint_range_samples(self.biped.standing_configuration(), self._iq,
                                          self._q_lo, self._q_hi)
            self.actuators.check_step(self.model, samples, self._iv, self.sim.dt)

    @property
    def actuators(self) -> ActuatorModel:
        """Joint losses and motor model (``sim.actuators``), cached."""
        cache = self.__dict__.get("_actuators_cache")
        if cache is None:
            cache = ActuatorModel.from_config(self.sim.actuators, self.biped.torque_limits)
            object.__setattr__(self, "_actuators_cache", cache)
        return cache

    @property
    def model(self) -> pin.Model:
        """The Pinocchio model integrated: ``biped.model``, plus armature N² J_r if on."""
        cache = self.__dict__.get("_model_cache")
        if cache is None:
            cache = self.actuators.dynamics_model(self.biped.model, self._iv)
            object.__setattr__(self, "_model_cache", cache)
        return cache

    @property
    def dt(self) -> float:
        return self.sim.dt

    def new_data(self, q0: np.ndarray, v0: np.ndarray | None = None) -> "PlantData":
        """Plant data starting at configuration ``q0`` [m, quaternion, rad] and ``v0``."""
        return PlantData(self, *start_state(self.biped.model, q0, v0))

    # ------------------------------------------------------------------ dynamics
    def forward(self, d: "PlantData", q: np.ndarray, v: np.ndarray,
                v_dyn: np.ndarray | None = None) -> np.ndarray:
        """Generalised acceleration at (q, v) with the current torque and terrain forces.

        Evaluates (but does not commit) the terrain contact; results land in ``d``.
        ``v_dyn`` (default ``v``) is the velocity used for the rigid-body velocity terms
        (Coriolis, gyroscopic, the free-flyer's ω × v); the contact, the end stops and
        ``base_wrench`` always see ``v``. The Verlet step passes its predicted end-of-step
        velocity there (see :meth:`step`).
        """
        model, pdata, contact = self.model, d.pin, d.contact
        pin.forwardKinematics(model, pdata, q, v)
        for i, (fid, jid, to_joint) in enumerate(self._feet):
            oMf = pin.updateFramePlacement(model, pdata, fid)
            p = oMf.translation
            # a swing foot whose sole cannot reach the surface costs nothing
            if p[2] > self._clear_height and not contact.in_contact(i):
                contact.skip(i)
                d.fext[jid] = _ZERO_FORCE
                continue
            # foot i's buffers: its law's input also holds i (0 left, 1 right), which
            # per-foot terrain effects read as PatchState.foot
            kin = contact.feet[i].kin
            kin[0:3] = p
            kin[3:12] = oMf.rotation.ravel("F")
            kin[12:18] = pin.getFrameVelocity(model, pdata, fid, _LWA).vector
            contact.evaluate(i)
            d.fext[jid] = pin.Force(to_joint @ contact.feet[i].wrench_local)
        # joint end stops: stiff spring-damper beyond the URDF position limits
        qa = q[self._iq]
        over = np.maximum(qa - self._q_hi, 0.0) + np.minimum(qa - self._q_lo, 0.0)
        if over.any():
            va = v[self._iv]
            tau = d.tau.copy()
            tau[self._iv] += np.where(over != 0.0, -self.STOP_K * over - self.STOP_D * va, 0.0)
        else:
            tau = d.tau
        if self._joint_damping > 0.0:          # viscous joint damping (robot.joint_damping)
            tau = tau.copy()
            tau[self._iv] -= self._joint_damping * v[self._iv]
        if self.joint_effects:                 # joint-effect hook (e.g. joint friction)
            qa, va = q[self._iq], v[self._iv]
            tau = tau.copy()
            for fn in self.joint_effects:
                tau[self._iv] += fn(qa, va)
        if self.actuators.active:              # joint losses, motor model (sim.actuators)
            tau = tau.copy()
            tau[self._iv] += self._actuator_torque(d, v[self._iv])
        w = d.base_wrench
        if w is None:
            d.fext[1] = _ZERO_FORCE
        else:
            # external wrench on the trunk, given in W at the trunk origin → trunk frame
            if callable(w):
                w = w(q, v)
            R = matrix_from_quat_xyzw(q[3:7])
            d.fext[1] = pin.Force(R.T @ w[0:3], R.T @ w[3:6])
        return pin.aba(model, pdata, q, v if v_dyn is None else v_dyn, tau, d.fext)

    #: joint end-stop stiffness [N·m/rad] and damping [N·m·s/rad]
    STOP_K = 500.0
    STOP_D = 5.0

    def _actuator_torque(self, d: "PlantData", dq_a: np.ndarray) -> np.ndarray:
        """(τ_m − τ_cmd) + τ_f [N·m] at joint rates ``dq_a``: what the actuator model adds to
        the held command; records τ_m, τ_f and ``dq_a`` in ``d``."""
        act = self.actuators
        tau_cmd = d.tau[self._iv]
        d._tau_motor = act.motor_torque(tau_cmd, dq_a)
        d._tau_friction = act.friction_torque(dq_a)
        d._dq_eval = dq_a.copy()
        return (d._tau_motor - tau_cmd) + d._tau_friction

    def _torque_change(self, d: "PlantData") -> np.ndarray:
        """Δτ since ``d.a`` was evaluated [N·m] (full size), for Verlet's ``M⁻¹Δτ``: the
        command's change, or — when the torque–speed envelope clips — the delivered
        torque's change at the joint rates ``d.a`` was evaluated at (then recorded)."""
        dtau = d.tau - d.tau_prev
        if self.actuators.limits_torque and d._dq_eval is not None:
            tau_m = self.actuators.motor_torque(d.tau[self._iv], d._dq_eval)
            dtau[self._iv] = tau_m - d._tau_motor
            d._tau_motor = tau_m
        return dtau

    @property
    def _joint_damping(self) -> float:
        return self.biped.config.joint_damping

    @property
    def _iq(self) -> np.ndarray:
        return self.biped.idx_q

    @property
    def _iv(self) -> np.ndarray:
        return self.biped.idx_v

    @property
    def _q_lo(self) -> np.ndarray:
        return self.biped.position_limits[0]

    @property
    def _q_hi(self) -> np.ndarray:
        return self.biped.position_limits[1]

    @property
    def _feet(self) -> tuple:
        """(frame id, joint id, foot→joint force action matrix) per foot, cached."""
        cache = self.__dict__.get("_feet_cache")
        if cache is None:
            model = self.biped.model
            cache = tuple((self.biped.foot_frame[s], self.biped.foot_joint[s],
                           model.frames[self.biped.foot_frame[s]].placement.toDualActionMatrix())
                          for s in SIDES)
            object.__setattr__(self, "_feet_cache", cache)
        return cache

    @property
    def _clear_height(self) -> float:
        """Foot-frame height above which no sole point can touch the surface [m]."""
        return self.terrain.surface_height + self.biped.config.foot.radius + 0.005

    def step(self, d: "PlantData", tau_a: np.ndarray | None = None) -> None:
        """Advance ``d`` by one step ``dt`` with actuator torques ``tau_a`` [N·m] (held)."""
        if tau_a is not None:
            d.set_torque(tau_a)
        dt = self.sim.dt
        if self.sim.integrator == "verlet":
            if d.a is None:
                d.a = self.forward(d, d.q, d.v).copy()
                d.contact.commit()
            elif d.tau_changed:
                # acceleration is affine in τ: correct the reused one exactly
                minv = pin.computeMinverse(self.model, d.pin, d.q)
                d.a = d.a + minv @ self._torque_change(d)
            d.tau_changed = False
            v_half = d.v + 0.5 * dt * d.a
            q_new = pin.integrate(self.biped.model, d.q, v_half * dt)
            # The contact sees v_half (its elastic displacement then integrates exactly the
            # position update). The rigid-body velocity terms are evaluated at the predicted
            # end-of-step velocity v_half + dt/2·a_n: evaluating them at v_half (as the
            # kick–drift–kick form with velocity-independent forces would) lags them by
            # dt/2 and makes the scheme first order (measured: free-fall energy drift
            # halving with dt; tests/test_plant.py::test_verlet_is_second_order).
            a_new = self.forward(d, q_new, v_half, v_half + 0.5 * dt * d.a)
            d.v = v_half + 0.5 * dt * a_new
            d.q = q_new
            d.a = a_new.copy()
        else:
            a = self.forward(d, d.q, d.v)
            d.v = d.v + dt * a
            d.q = pin.integrate(self.biped.model, d.q, d.v * dt)
            d.a = a.copy()
        d.contact.commit()
        d.tau_prev[:] = d.tau
        d.t += dt
        d.steps += 1
        if not (np.abs(d.v).max() < self.sim.max_speed) or not np.isfinite(d.q).all():
            reason = "non-finite" if not (np.isfinite(d.v).all() and np.isfinite(d.q).all()) \
                else "velocity-bound"
            raise PlantDivergedError(d.t, d.q, d.v, reason, q_names=self.biped.q_names,
                                     v_names=self.biped.v_names)

    def simulate(self, d: "PlantData", duration: float, controller=None) -> None:
        """Step for ``duration`` [s]; ``controller(d) -> tau_a`` is called every step."""
        n = int(round(duration / self.sim.dt))
        for _ in range(n):
            self.step(d, None if controller is None else controller(d))

    # ------------------------------------------------------------------ energy
    def energy(self, d: "PlantData") -> tuple[float, float]:
        """(kinetic, potential) energy [J], potential relative to z = 0 (kinetic includes
        the rotors' N² J_r q̇² / 2 when the motor model adds reflected inertia)."""
        model = self.model
        ke = pin.computeKineticEnergy(model, d.pin, d.q, d.v)
        pe = pin.computePotentialEnergy(model, d.pin, d.q)
        return float(ke), float(pe)


def start_state(model: pin.Model, q0: np.ndarray, v0: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """The start configuration and velocity of a plant run (new arrays): ``q0`` with its
    base quaternion normalised, ``v0`` (default zero).

    Raises:
        ConfigError: ``q0`` or ``v0`` has the wrong size (nq, nv).
    """
    q0 = np.asarray(q0, dtype=float)
    if q0.shape != (model.nq,):
        raise ConfigError(f"q0 must have {model.nq} entries, got {q0.shape}", key="q0")
    v0 = np.zeros(model.nv) if v0 is None else np.asarray(v0, dtype=float)
    if v0.shape != (model.nv,):
        raise ConfigError(f"v0 must have {model.nv} entries, got {v0.shape}", key="v0")
    q0 = q0.copy()
    q0[3:7] /= np.linalg.norm(q0[3:7])
    return q0, v0.copy()


class PlantData:
    """Changing part of the plant: time, state, torque, terrain contact state, buffers."""

    def __init__(self, plant: Plant, q: np.ndarray, v: np.ndarray) -> None:
        model = plant.biped.model
        self.plant = plant
        self.t = 0.0
        self.steps = 0
        self.q = q
        self.v = v
        self.a: np.ndarray | None = None
        self.tau = np.zeros(model.nv)
        self.tau_prev = np.zeros(model.nv)
        self.tau_changed = False
        self.pin = model.createData()
        self.fext = pin.StdVec_Force()
        for _ in range(model.njoints):
            self.fext.append(pin.Force.Zero())
        self.contact: ContactData = plant.terrain.new_data(plant.sim.dt)
        #: optional external wrench on the trunk: (f_W [N], m_W [N·m]) at the trunk origin,
        #: or a callable (q, v) -> that 6-vector (e.g. a test rig), evaluated every step
        self.base_wrench = None
        self._idx_v = plant.biped.idx_v
        # actuator model (sim.actuators), at the last dynamics evaluation: motor torque,
        # friction torque [N·m] and the joint rates they were evaluated at [rad/s]
        self._tau_motor: np.ndarray | None = None
        self._tau_friction: np.ndarray | None = None
        self._dq_eval: np.ndarray | None = None

    def set_torque(self, tau_a: np.ndarray) -> None:
        """Hold actuator torques ``tau_a`` [N·m] (actuator order) from now on."""
        tau_a = np.asarray(tau_a, dtype=float)
        if not np.array_equal(self.tau[self._idx_v], tau_a):
            self.tau[self._idx_v] = tau_a
            self.tau_changed = True

    @property
    def tau_a(self) -> np.ndarray:
        return self.tau[self._idx_v].copy()

    # ------------------------------------------------------------------ read-outs
    @property
    def tau_motor(self) -> np.ndarray:
        """Joint torque the motors deliver [N·m], actuator order: the command clipped to the
        torque–speed envelope at the last dynamics evaluation (the command if ideal)."""
        if self._tau_motor is None or not self.plant.actuators.limits_torque:
            return self.tau_a
        return self._tau_motor.copy()

    @property
    def tau_friction(self) -> np.ndarray:
        """Joint friction torque at the last dynamics evaluation [N·m] (zeros if off)."""
        if self._tau_friction is None or not self.plant.actuators.friction:
            return np.zeros(len(self._idx_v))
        return self._tau_friction.copy()

    @property
    def electrical_power(self) -> np.ndarray:
        """Electrical power per motor now [W], P = τ_m q̇ + R_w (τ_m/(k_t N))² with
        :attr:`tau_motor` and the current joint rates (``sim.actuators.motor`` constants,
        used even when the motor model is off). Negative: regenerating."""
        return self.plant.actuators.electrical_power(self.tau_motor, self.v[self._idx_v])

    def foot_force(self, foot: int) -> np.ndarray:
        """Total terrain force on foot ``foot`` (0 left, 1 right) in W [N]."""
        return self.contact.feet[foot].force.sum(axis=0)

    def foot_point(self, foot: int) -> np.ndarray:
        """Mean contact point of foot ``foot``'s patches in W [m]."""
        return self.contact.feet[foot].point.mean(axis=0)

    def foot_in_contact(self, foot: int) -> bool:
        return self.contact.in_contact(foot)

    def foot_diag(self, foot: int) -> np.ndarray:
        """Mean over the foot's patches of (depth, f_cap_z, x_s, y_s, z_s, ψ_c)."""
        return self.contact.feet[foot].diag.mean(axis=0)

    def readout(self) -> np.ndarray:
        """The state and the contact read-outs as one flat vector (layout
        :func:`readout_offsets`): the values of ``q``, ``v``, :attr:`tau_a` and, per foot,
        :meth:`foot_force`, :meth:`foot_point`, :meth:`foot_diag`, then both feet's
        :meth:`foot_in_contact` as 1.0 / 0.0 — what a log row reads, in one array."""
        parts = [self.q, self.v, self.tau[self._idx_v]]
        for foot in (0, 1):
            parts += (self.foot_force(foot), self.foot_point(foot), self.foot_diag(foot))
        parts.append([float(self.foot_in_contact(0)), float(self.foot_in_contact(1))])
        return np.concatenate(parts)


#: layout of :meth:`PlantData.readout` (and ``FastPlantData.readout``, offsets
#: :func:`readout_offsets`):
#: ``[q (nq) | v (nv) | τ_a (na) | per foot, left first: force in W [N] (3), contact point
#: in W [m] (3), diagnostics (depth, f_cap_z, x_s, y_s, z_s, ψ_c) (6) | in contact (2)]``;
#: the per-foot parts in order, with their sizes
READOUT_FOOT_PARTS = (("force", 3), ("point", 3), ("diag", 6))
#: size of one foot's block in a read-out
READOUT_PER_FOOT = sum(n for _, n in READOUT_FOOT_PARTS)


def readout_offsets(nq: int, nv: int, na: int) -> dict:
    """Offsets in a read-out vector (:meth:`PlantData.readout`): ``"q"``, ``"v"``,
    ``"tau_a"``, ``(foot, part)`` for each of :data:`READOUT_FOOT_PARTS`, ``"contact"``
    (two entries, left first), ``"size"``."""
    off = {"q": 0, "v": nq, "tau_a": nq + nv}
    k = nq + nv + na
    for foot in (0, 1):
        for part, n in READOUT_FOOT_PARTS:
            off[foot, part] = k
            k += n
    off["contact"] = k
    off["size"] = k + 2
    return off


__all__ = ["Plant", "PlantData", "READOUT_FOOT_PARTS", "READOUT_PER_FOOT", "readout_offsets",
           "start_state"]
