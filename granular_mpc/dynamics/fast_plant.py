"""A drop-in for the reference :class:`~.plant.Plant` that steps with the compiled code.

    plant = FastPlant(Plant(biped, terrain, sim))      # instead of the Plant itself
    d = plant.new_data(q0)
    d.base_wrench = rig                                # None, a 6-vector or a callable
    for _ in range(n):
        plant.step(d, controller(d))                   # same call as Plant.step
    d.foot_force(0), d.foot_diag(0), d.foot_point(0), d.foot_in_contact(0)

:class:`FastPlant` / :class:`FastPlantData` offer what the closed loop, the run log, the
synthesiser and the replay read from ``Plant`` / ``PlantData`` (``new_data``, ``step``,
``simulate``, ``energy``; ``t``, ``steps``, ``q``, ``v``, ``tau``, ``tau_a``,
``set_torque``, ``base_wrench``, ``foot_force``, ``foot_point``, ``foot_in_contact``,
``foot_diag``, ``readout``) with the same physics: one compiled call per step
(:class:`~.compiled.CompiledPlant`). A callable ``base_wrench`` (e.g. a guide rig) is
evaluated in Python where the reference evaluates it — at the drifted configuration and
the half-step velocity of the Verlet step (which needs ``M⁻¹Δτ`` from Pinocchio when the
torque changed), at the start state for semi-implicit Euler — so it matches too.
``d.contact.feet[i]`` offers foot ``i``'s per-patch state (``state``, (n, S), the layout
of :mod:`granular_mpc.terrain.contact`) and terrain parameters (``params``) as writable views
into the compiled state, so a replay sets a foot's initial contact state the same way on
both plants (the two feet share one ``params`` unless the compiled plant was built with
``per_foot_theta``). ``pin`` is a Pinocchio data of the robot for the caller's kinematics
(not updated by :meth:`FastPlant.step`). Not offered: ``fext`` and the actuator-model
read-outs of ``PlantData``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .compiled import CompiledPlant
from .plant import READOUT_FOOT_PARTS, Plant
from .step_sx import AUX_SLICES, aux_foot


class FastPlant:
    """The reference plant's interface on the compiled step.

    Args:
        plant: the reference :class:`~.plant.Plant` (model; not stepped).
        compiled: an already built :class:`CompiledPlant` of ``plant`` (optional).

    Attributes:
        reference: the reference plant; compiled: the compiled plant.
    """

    def __init__(self, plant: Plant, compiled: CompiledPlant | None = None) -> None:
        self.reference = plant
        self.compiled = compiled if compiled is not None else CompiledPlant(plant)

    @property
    def biped(self):
        return self.reference.biped

    @property
    def terrain(self):
        return self.reference.terrain

    @property
    def sim(self):
        return self.reference.sim

    @property
    def joint_effects(self) -> tuple:
        return self.reference.joint_effects

    @property
    def dt(self) -> float:
        return self.reference.dt

    def new_data(self, q0: np.ndarray, v0: np.ndarray | None = None) -> "FastPlantData":
        """Data at configuration ``q0`` and velocity ``v0`` (as :meth:`Plant.new_data`)."""
        return FastPlantData(self, self.compiled.new_data(q0, v0))

    def scratch_data(self, q0: np.ndarray, v0: np.ndarray | None = None) -> "FastPlantData":
        """This plant's one reusable data, reset to what :meth:`new_data` ``(q0, v0)``
        gives (the same state, command, θ and read-outs; its buffers and Pinocchio data
        kept): for callers that finish with a data before asking for the next one (a
        replay per window). Each call resets and returns the same object."""
        d = self.__dict__.get("_scratch")
        if d is None:
            d = self._scratch = self.new_data(q0, v0)
            return d
        self.compiled.reset_data(d.data, q0, v0)
        d.base_wrench = None
        d._point[:] = 0.0
        return d

    def step(self, d: "FastPlantData", tau_a: np.ndarray | None = None) -> None:
        """Advance ``d`` by one step with actuator torques ``tau_a`` [N·m] (held)."""
        if tau_a is not None:
            d.set_torque(tau_a)
        c, data = self.compiled, d.data
        w = d.base_wrench
        if callable(w):
            q, v = data.x[c.layout.q].copy(), data.x[c.layout.v].copy()
            if not c.verlet:
                data.wrench[:] = w(q, v)
            else:
                if not data.started:
                    data.wrench[:] = w(q, v)
                    data.call_start()
                    data.started = True
                a = data.x[c.layout.a].copy()
                dtau = data.tau - data.x[c.layout.tau_prev]
                if dtau.any():
                    model = self.biped.model
                    full = np.zeros(model.nv)
                    full[self.biped.idx_v] = dtau
                    a = a + pin.computeMinverse(model, d.pin_data, q) @ full
                v_half = v + 0.5 * c.dt * a
                q_new = pin.integrate(self.biped.model, q, v_half * c.dt)
                data.wrench[:] = w(q_new, v_half)
        else:
            data.wrench[:] = 0.0 if w is None else w
        c.advance(data, 1)
        d.note_step()

    def step_n(self, d: "FastPlantData", n: int) -> None:
        """Advance ``d`` by ``n`` steps with its held torque: the same as ``n`` calls of
        :meth:`step` (the same compiled step per step, the same time sums and read-outs),
        without their per-step Python. A callable ``base_wrench`` is stepped by
        :meth:`step` (it is evaluated per step)."""
        w = d.base_wrench
        if callable(w) or (self.compiled.verlet and not d.data.started):
            for _ in range(n):
                self.step(d)
            return
        d.data.wrench[:] = 0.0 if w is None else w
        self.compiled.advance_steps(d.data, n, d._point)

    def simulate(self, d: "FastPlantData", duration: float, controller=None) -> None:
        """Step for ``duration`` [s]; ``controller(d) -> tau_a`` is called every step."""
        n = int(round(duration / self.dt))
        for _ in range(n):
            self.step(d, None if controller is None else controller(d))

    def energy(self, d: "FastPlantData") -> tuple[float, float]:
        """(kinetic, potential) energy [J], potential relative to z = 0."""
        model = self.biped.model
        ke = pin.computeKineticEnergy(model, d.pin_data, d.q, d.v)
        pe = pin.computePotentialEnergy(model, d.pin_data, d.q)
        return float(ke), float(pe)


class FootContactView:
    """Foot ``i``'s part of a compiled state, shaped like ``ContactData.feet[i]``.

    Attributes:
        state: per-patch terrain state, (n patches, S), a writable view of the state.
        params: the terrain θ this foot's law reads (``terrain.param_names`` order), a
            writable view of the held parameters.
    """

    def __init__(self, state: np.ndarray, params: np.ndarray) -> None:
        self.state = state
        self.params = params


class ContactView:
    """Both feet's :class:`FootContactView` (``feet[0]`` left, ``feet[1]`` right)."""

    def __init__(self, data) -> None:
        L = data.layout
        states = data.x[L.contact].reshape(2, L.n_patches, L.patch_state)
        self.feet = tuple(FootContactView(states[i], data.theta[L.terrain_theta(i)])
                          for i in (0, 1))

    def in_contact(self, foot: int) -> bool:
        return bool(self.feet[foot].state[:, 6].max() > 0.5)


class FastPlantData:
    """Changing part of a :class:`FastPlant` run, read like ``PlantData``.

    ``q`` and ``v`` are copies (the reference replaces its arrays every step, so a kept
    reference never changes; a copy keeps that behaviour). ``foot_point`` holds the last
    evaluated contact point of a foot that is clear of the surface, as the reference does.
    """

    def __init__(self, plant: FastPlant, data) -> None:
        self.plant = plant
        self.data = data
        #: external trunk wrench: None, (f_W [N], m_W [N·m]) at the trunk origin, or a
        #: callable (q, v) -> that 6-vector
        self.base_wrench = None
        self.pin_data = plant.biped.create_data()
        #: per-foot contact state and terrain θ, writable views (see the module docstring)
        self.contact = ContactView(data)
        self._point = np.zeros((2, 3))
        self._idx_v = plant.biped.idx_v
        L = data.layout
        # views into the compiled state (updated in place by every call)
        self._states = data.x[L.contact].reshape(2, L.n_patches, L.patch_state)
        self._contact_flags = self._states[:, :, 6]     # per foot and patch: in contact
        self._evaluated = (AUX_SLICES[0, "evaluated"].start, AUX_SLICES[1, "evaluated"].start)
        self._point_sl = (AUX_SLICES[0, "point"], AUX_SLICES[1, "point"])
        # readout(): one gather from [q, v (the head of x) | τ_a | aux | kept points |
        # contact flags]: the feet's force and diagnostics from aux, the kept point
        nqv, na, n_aux = L.nq + L.nv, L.na, len(data.aux)
        o_aux = nqv + na
        o_pt = o_aux + n_aux
        take = list(range(o_aux))
        for foot in (0, 1):
            for part, n in READOUT_FOOT_PARTS:
                start = (o_pt + 3 * foot if part == "point"
                         else o_aux + AUX_SLICES[foot, part].start)
                take += range(start, start + n)
        take += [o_pt + 6, o_pt + 7]
        self._qv = slice(0, nqv)
        # q and v: copies of these slices of the state (the compiled data's x, updated in place)
        self._x, self._q_sl, self._v_sl = data.x, L.q, L.v
        self._readout_take = np.array(take, dtype=np.intp)

    @property
    def pin(self):
        """A Pinocchio data of the robot (for the caller's kinematics; not stepped)."""
        return self.pin_data

    @property
    def t(self) -> float:
        return self.data.t

    @property
    def steps(self) -> int:
        return self.data.steps

    @property
    def q(self) -> np.ndarray:
        return self._x[self._q_sl].copy()

    @property
    def v(self) -> np.ndarray:
        return self._x[self._v_sl].copy()

    @property
    def tau(self) -> np.ndarray:
        """Held generalised torque (nv; zero on the base) [N·m]."""
        full = np.zeros(self.data.layout.nv)
        full[self._idx_v] = self.data.tau
        return full

    @property
    def tau_a(self) -> np.ndarray:
        return self.data.tau.copy()

    def set_torque(self, tau_a: np.ndarray) -> None:
        """Hold actuator torques ``tau_a`` [N·m] (actuator order) from now on."""
        self.data.tau[:] = tau_a

    def note_step(self) -> None:
        """Keep each evaluated foot's contact point (called by :meth:`FastPlant.step`)."""
        aux = self.data.aux
        if aux[self._evaluated[0]] > 0.5:
            self._point[0] = aux[self._point_sl[0]]
        if aux[self._evaluated[1]] > 0.5:
            self._point[1] = aux[self._point_sl[1]]

    # ------------------------------------------------------------------ read-outs
    def foot_force(self, foot: int) -> np.ndarray:
        """Total terrain force on foot ``foot`` (0 left, 1 right) in W [N]."""
        return aux_foot(self.data.aux, foot, "force").copy()

    def foot_point(self, foot: int) -> np.ndarray:
        """Mean contact point of foot ``foot``'s patches in W [m]."""
        return self._point[foot].copy()

    def foot_in_contact(self, foot: int) -> bool:
        # ndarray.max's reduction called directly (without its Python wrapper)
        return bool(_max_reduce(self._contact_flags[foot], None) > 0.5)

    def foot_diag(self, foot: int) -> np.ndarray:
        """Mean over the foot's patches of (depth, f_cap_z, x_s, y_s, z_s, ψ_c)."""
        return aux_foot(self.data.aux, foot, "diag").copy()

    def readout(self) -> np.ndarray:
        """The state and the contact read-outs as one flat vector, the layout of
        :meth:`~.plant.PlantData.readout` (:func:`~.plant.readout_offsets`): the values of
        :attr:`q`, :attr:`v`, :attr:`tau_a`, per foot :meth:`foot_force`,
        :meth:`foot_point`, :meth:`foot_diag`, then :meth:`foot_in_contact` (1.0 / 0.0)."""
        data = self.data
        contact = _max_reduce(self._contact_flags, 1) > 0.5
        return np.concatenate((data.x[self._qv], data.tau, data.aux, self._point.ravel(),
                               contact))[self._readout_take]


#: the reduction :meth:`FastPlantData.foot_in_contact` calls directly
_max_reduce = np.maximum.reduce


__all__ = ["FastPlant", "FastPlantData", "ContactView", "FootContactView"]
