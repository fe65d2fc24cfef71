"""The plant step as one compiled C function: :class:`CompiledPlant`.

    plant = Plant(biped, terrain, sim)             # the reference (Pinocchio + Python)
    fast = CompiledPlant(plant)                    # same model, compiled once (cached .so)
    s = fast.initial_state(q0)
    s = fast.step(s, tau_a, n_steps=20)            # 20 steps of dt with τ_a held
    s = fast.step(s, n_steps=20, q_ref=q_hold, kp=150.0, kd=3.0)   # joint PD in the loop
    replay = CompiledPlant(plant, per_foot_theta=True,           # each foot its own θ,
                           joint_params=(effect_info("joint_friction"),))  # effect params in θ

One step is the reference :meth:`Plant.step` — Verlet (or semi-implicit Euler) on the
configuration manifold, the articulated-body algorithm, both feet's terrain law with the
terrain's effects, joint end stops, joint damping and traceable joint effects — written
as a single CasADi SX expression (:mod:`.step_sx`), generated to C, compiled once per
model with the system compiler (:mod:`.codegen`, cached by source hash) and called once
per ``chunk`` steps (``mapaccum``); the state lives in flat NumPy vectors between calls.
:meth:`CompiledPlant.advance_steps` (the closed loop's path) calls ``plant_steps<k>``
(:func:`steps_function`): ``k`` steps returning every step's state and aux, so the
per-step read-outs and checks of single steps are kept without a Python call per step.
``tests/test_compiled.py`` checks it against :class:`Plant` to ~1e-9 over random states
on sand and rigid ground.

Route (measured, issue 12): Pinocchio 4.1 from PyPI has no ``pinocchio.casadi``, so the
rigid-body part is written directly over the Pinocchio model's tree in CasADi SX
(:mod:`.rigid_body_sx`: ABA, O(n), ≈ 2,450 operations with external forces, 2.2 µs
compiled; no new dependency, and the very model the reference uses, so the comparison
test holds to ~1e-12). Measured alternatives on the same URDF (operation counts of the
SX functions, without external forces): our ABA 2,411; adam-robotics 0.5's CasADi ABA
3,409 (plus the conversions from its 4×4 base transform and mixed-velocity convention,
and a second parse of the URDF); its M(q) 2,155 + h(q, v) 1,429 before the symbolic 12×12
solve the plant would need. Numba would leave the terrain law (already CasADi) in a
separate call and re-implement what CasADi generates.

Profile of the compiled sand step (each piece compiled alone and timed through the buffer
interface, shared 2-core machine under load ≈ 8): step 16.6 µs ≈ 8,900 operations after
common-subexpression elimination — both feet's terrain law 10.1 µs (61 %: per foot the
closed form's 80 sin, 74 cos, 166 divisions, 6 atan2, 4 acos), ABA 2.2 µs, the Verlet
``M⁻¹Δτ`` correction 1.5 µs, foot kinematics 0.5 µs, integrate 0.4 µs; a Python call
adds ≈ 1–2 µs, hence ``chunk`` steps per call. ``bench/plant.py`` measures it beside the
reference (11–13× faster there under load; the reference's own profile is in that file).

Without a C compiler the same functions run in CasADi's virtual machine (same results,
several times slower). Not supported (:class:`ConfigError`, never silently ignored): the
actuator model ``sim.actuators`` (joint friction, motor envelope, rotor inertia), joint
effects that cannot be traced with CasADi, and a callable trunk wrench (a constant wrench
per call is; :class:`~.fast_plant.FastPlant` evaluates a callable one in Python).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..exceptions import ConfigError, PlantDivergedError
from ..codegen import compile_functions
from .multi_step import chunk_function, steps_function
from .plant import Plant, PlantData, start_state
from .step_sx import AUX_NAMES, AUX_SLICES, StepBuilder, StepLayout, aux_foot

#: step counts with a compiled "every step's result" function (``plant_steps<k>``), the
#: calls :meth:`CompiledPlant.advance_steps` makes (largest first)
STEP_COUNTS = (8, 4, 2)
#: steps per compiled call in :meth:`CompiledPlant.step` (``mapaccum``)
DEFAULT_CHUNK = 10


@dataclass(frozen=True)
class CompiledState:
    """State of one robot between compiled steps (arrays are read-only copies).

    Attributes:
        t: simulated time [s]; steps: steps taken.
        x: the flat state (layout :class:`~.step_sx.StepLayout`).
        started: whether a step has been taken (with Verlet: ``a`` has been evaluated).
        aux: after a step, per foot the terrain force, mean contact point, contact flag,
            mean diagnostics and evaluated flag (:data:`~.step_sx.AUX_FOOT`), then the
            largest |v| of the last call (:data:`~.step_sx.AUX_NAMES`).
        layout: the layout of ``x``.
    """

    t: float
    steps: int
    x: np.ndarray
    started: bool
    layout: StepLayout = field(repr=False)
    aux: np.ndarray = field(default_factory=lambda: np.zeros(len(AUX_NAMES)), repr=False)

    def __post_init__(self) -> None:
        for name in ("x", "aux"):
            arr = np.array(getattr(self, name), dtype=float)
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)

    @property
    def q(self) -> np.ndarray:
        """Configuration [m, quaternion (x, y, z, w), rad] (nq)."""
        return self.x[self.layout.q]

    @property
    def v(self) -> np.ndarray:
        """Generalised velocity [m/s, rad/s], base twist in the trunk frame (nv)."""
        return self.x[self.layout.v]

    @property
    def a(self) -> np.ndarray:
        """Last generalised acceleration (nv); meaningful once ``started``."""
        return self.x[self.layout.a]

    @property
    def tau_prev(self) -> np.ndarray:
        """Actuator torques held during the last step [N·m] (actuator order)."""
        return self.x[self.layout.tau_prev]

    @property
    def contact(self) -> np.ndarray:
        """Per-patch terrain states, shape (2 feet, n patches, S)."""
        L = self.layout
        return self.x[L.contact].reshape(2, L.n_patches, L.patch_state)

    def foot_force(self, foot: int) -> np.ndarray:
        """Total terrain force on foot ``foot`` (0 left, 1 right) in W [N], last step."""
        return aux_foot(self.aux, foot, "force")

    def foot_point(self, foot: int) -> np.ndarray:
        """Mean contact point of foot ``foot``'s patches in W [m], last step."""
        return aux_foot(self.aux, foot, "point")

    def foot_diag(self, foot: int) -> np.ndarray:
        """Mean over foot ``foot``'s patches of (depth, f_cap_z, x_s, y_s, z_s, ψ_c), last step."""
        return aux_foot(self.aux, foot, "diag")

    def foot_in_contact(self, foot: int) -> bool:
        """Whether a patch of foot ``foot`` is in contact (committed state)."""
        return bool(self.contact[foot, :, 6].max() > 0.5)


class CompiledPlant:
    """The reference :class:`Plant` stepped by compiled code (same model, same results).

    Args:
        plant: the reference plant (robot, terrain, sim settings, joint effects).
        chunk: steps per compiled call (``mapaccum``) for multi-step calls.
        per_foot_theta: each foot reads its own terrain θ (``θ`` is then the terrain's
            values twice, left foot first; :class:`~.step_sx.StepLayout`).
        joint_params: registered joint effects (``EffectInfo``, kind ``joint``) compiled
            with their parameters in ``θ`` (after the terrain's), at their neutral values
            (off) by default — one compiled model serves every parameter setting.

    Attributes:
        plant, layout, dt, theta (default parameter vector: terrain values in
        ``terrain.param_names`` order, then the joint-effect parameters), theta_names,
        functions: name → compiled CasADi function (``plant_step``, ``plant_start``,
        ``plant_chunk``).
    """

    def __init__(self, plant: Plant, *, chunk: int = DEFAULT_CHUNK, per_foot_theta: bool = False,
                 joint_params: tuple = ()) -> None:
        if chunk < 1:
            raise ConfigError("chunk must be ≥ 1", key="chunk", value=chunk)
        builder = StepBuilder(plant, per_foot_theta=per_foot_theta, joint_params=joint_params)
        self.plant = plant
        self.layout = builder.layout
        #: registered joint effects compiled with their parameters in θ
        self.joint_params = builder.joint_params
        self.dt = float(plant.sim.dt)
        self.chunk = int(chunk)
        self.verlet = plant.sim.integrator == "verlet"
        terrain_names = tuple(plant.terrain.param_names)
        terrain_values = list(np.asarray(plant.terrain.param_values, dtype=float))
        names = ([f"{side}:{n}" for side in ("left", "right") for n in terrain_names]
                 if per_foot_theta else list(terrain_names))
        values = terrain_values * (2 if per_foot_theta else 1)
        for info in builder.joint_params:
            neutral = info.neutral_params()
            names += [f"{info.name}.{k}" for k in info.params]
            values += [float(neutral[k]) for k in info.params]
        self.theta_names = tuple(names)
        self.theta = np.array(values, dtype=float)
        step, start = builder.step_function(), builder.start_function()
        #: the symbolic (uncompiled) functions, for other wrappers
        self.symbolic = {"plant_step": step, "plant_start": start,
                         "plant_chunk": chunk_function(step, chunk),
                         **{f"plant_steps{k}": steps_function(step, k, plant.sim.max_speed)
                            for k in STEP_COUNTS}}
        # without a C compiler the same functions run in CasADi's virtual machine (slower)
        self.functions = compile_functions("plant", list(self.symbolic.values()), fallback=True)
        self._step1 = _Caller(self.functions["plant_step"])
        self._stepk = _Caller(self.functions["plant_chunk"])
        self._start = _Caller(self.functions["plant_start"])

    @classmethod
    def from_parts(cls, biped, terrain, sim=None, joint_effects: tuple = (), **kw) -> "CompiledPlant":
        """Build from the parts of a :class:`Plant` (biped, terrain, sim settings)."""
        plant = Plant(biped, terrain, joint_effects=tuple(joint_effects)) if sim is None \
            else Plant(biped, terrain, sim, tuple(joint_effects))
        return cls(plant, **kw)

    # ------------------------------------------------------------------ states
    def initial_state(self, q0: np.ndarray, v0: np.ndarray | None = None) -> CompiledState:
        """State at configuration ``q0`` and velocity ``v0`` (like :meth:`Plant.new_data`)."""
        d = self.plant.new_data(q0, v0)
        return self.state_from_data(d)

    def initial_x(self, q0: np.ndarray, v0: np.ndarray | None = None) -> np.ndarray:
        """``initial_state(q0, v0).x`` without building a reference plant data: the same
        checks and quaternion normalisation as :meth:`Plant.new_data`, the contact part
        from the fresh contact state (which does not depend on ``q0``), cached."""
        template = self.__dict__.get("_x_template")
        if template is None:
            model = self.plant.biped.model
            q_ref = np.zeros(model.nq)
            q_ref[6] = 1.0
            template = np.array(self.initial_state(q_ref).x)
            template[self.layout.q] = 0.0
            self._x_template = template
        x = template.copy()
        x[self.layout.q], x[self.layout.v] = start_state(self.plant.biped.model, q0, v0)
        return x

    def state_from_data(self, d: PlantData) -> CompiledState:
        """The compiled state equal to the reference plant data ``d`` (for comparisons)."""
        L = self.layout
        x = np.zeros(L.nx)
        x[L.q], x[L.v] = d.q, d.v
        if d.a is not None:
            x[L.a] = d.a
        x[L.tau_prev] = d.tau_prev[self.plant.biped.idx_v]
        x[L.contact] = np.concatenate([f.state.ravel() for f in d.contact.feet])
        return CompiledState(d.t, d.steps, x, d.a is not None, L)

    def control(self, tau=None, *, q_ref=None, kp=None, kd=None) -> np.ndarray:
        """The control vector ``u = [τ_ff, q_ref, k_p, k_d]`` (see :mod:`.step_sx`)."""
        na = self.layout.na
        u = np.zeros(4 * na)
        if tau is not None:
            u[0:na] = tau
        if q_ref is not None:
            u[na:2 * na] = q_ref
        if kp is not None:
            u[2 * na:3 * na] = kp
        if kd is not None:
            u[3 * na:4 * na] = kd
        return u

    # ------------------------------------------------------------------ stepping
    def step(self, state: CompiledState, tau=None, n_steps: int = 1, *, q_ref=None, kp=None,
             kd=None, wrench=None, theta=None) -> CompiledState:
        """Advance ``state`` by ``n_steps`` steps of ``dt`` with the command held.

        Args:
            state: the current state (not modified).
            tau: feed-forward actuator torques [N·m] (actuator order), default zero.
            n_steps: number of steps.
            q_ref, kp, kd: optional joint PD law evaluated at every step's start state,
                ``τ = τ_ff + k_p (q_ref − q_a) − k_d q̇_a`` [rad, N·m/rad, N·m·s/rad].
            wrench: constant external wrench on the trunk (f_W [N], m_W [N·m]) at the trunk
                origin, in W, or None.
            theta: terrain parameter values (``terrain.param_names`` order), default the
                terrain's own.

        Returns:
            The new :class:`CompiledState`.

        Raises:
            PlantDivergedError: the velocity bound ``sim.max_speed`` was exceeded or the
                state became non-finite (time and state at the end of the compiled call
                where it was detected).
        """
        u = self.control(tau, q_ref=q_ref, kp=kp, kd=kd)
        th = self.theta if theta is None else np.asarray(theta, dtype=float)
        if callable(wrench):
            raise ConfigError("the compiled plant takes a constant trunk wrench per call, "
                              "not a callable", key="wrench")
        w = np.zeros(6) if wrench is None else np.asarray(wrench, dtype=float)
        x = np.array(state.x)
        t, steps, aux = state.t, state.steps, state.aux
        started = state.started
        if self.verlet and not started and n_steps > 0:
            x = self._start(x, u, th, w)[0]
        started = started or n_steps > 0
        left = int(n_steps)
        while left > 0:
            caller, k = (self._stepk, self.chunk) if left >= self.chunk else (self._step1, 1)
            x, aux = caller(x, u, th, w)
            left -= k
            t += k * self.dt
            steps += k
            self._check(t, x, aux)
        return CompiledState(t, steps, x, started, self.layout, aux)

    # ------------------------------------------------------------------ in-place path
    def new_data(self, q0: np.ndarray, v0: np.ndarray | None = None) -> "CompiledData":
        """Mutable data at ``q0``, ``v0`` for :meth:`advance` (the lean per-step path)."""
        return CompiledData(self, self.initial_state(q0, v0))

    def reset_data(self, d: "CompiledData", q0: np.ndarray, v0: np.ndarray | None = None) -> None:
        """Put ``d`` back where :meth:`new_data` ``(q0, v0)`` starts (time, state, aux,
        held command, θ, wrench), keeping its buffers (a replay's per-window set-up)."""
        d.reset(self.initial_x(q0, v0), self.theta)

    def data_from_state(self, state: CompiledState) -> "CompiledData":
        """Mutable data holding ``state`` (a copy)."""
        return CompiledData(self, state)

    def advance(self, d: "CompiledData", n_steps: int = 1) -> None:
        """Advance ``d`` in place by ``n_steps`` with its held command (``d.tau``, ``d.q_ref``,
        ``d.kp``, ``d.kd``, ``d.wrench``, ``d.theta``); same physics as :meth:`step`,
        without allocating (a Python controller's per-step path).

        Raises:
            PlantDivergedError: as :meth:`step`.
        """
        if self.verlet and not d.started and n_steps > 0:
            d.call_start()
        if n_steps > 0:
            d.started = True
        left = int(n_steps)
        while left > 0:
            k = self.chunk if left >= self.chunk else 1
            d.call(k > 1)
            left -= k
            d.t += k * self.dt
            d.steps += k
            if not (d.aux[-1] < self.plant.sim.max_speed) or not math.isfinite(d.x.sum()):
                self._check(d.t, d.x, d.aux)

    def advance_samples(self, d: "CompiledData", tau: np.ndarray, n_steps: int
                        ) -> tuple[np.ndarray, np.ndarray, int]:
        """Per row ``k`` of ``tau`` ((n, na) [N·m]): hold it, :meth:`advance` ``d`` by
        ``n_steps``, keep the state and aux — the same calls and numbers, one Python loop.

        Returns:
            ``(X, A, done)``: states (n, nx) and aux (n, n_aux) after each row, NaN from
            row ``done`` on; ``done`` < n when the plant diverged after row ``done`` (the
            :class:`PlantDivergedError` :meth:`advance` raises there; ``d`` then holds
            that row's state).
        """
        n = len(tau)
        X = np.full((n, self.layout.nx), np.nan)
        A = np.full((n, d.aux.size), np.nan)
        if n_steps != self.chunk:            # the general path: advance per row
            for k in range(n):
                d.tau[:] = tau[k]
                try:
                    self.advance(d, n_steps)
                except PlantDivergedError:
                    return X, A, k
                X[k], A[k] = d.x, d.aux
            return X, A, n
        call, x, x_out, aux, d_tau = d._calls[True][1], d.x, d._x_out, d.aux, d.tau
        if self.verlet and not d.started and n > 0:
            d_tau[:] = tau[0]                # the start sees the first row's torque
            d.call_start()
        d.started = d.started or n > 0
        vmax, dt_call = self.plant.sim.max_speed, n_steps * self.dt
        for k in range(n):                   # advance(d, chunk) per row, without its checks
            d_tau[:] = tau[k]
            call()
            x[:] = x_out
            d.t += dt_call
            X[k], A[k] = x_out, aux
            if not aux[-1] < vmax:
                break
        d.steps += n_steps * (k + 1) if n else 0
        # the divergence test of advance, per row: its first failing row
        bad = ~((A[:, -1] < vmax) & np.isfinite(X).all(axis=1))
        if not bad.any():
            return X, A, n
        done = int(np.argmax(bad))
        X[done:], A[done:] = np.nan, np.nan
        return X, A, done

    def advance_steps(self, d: "CompiledData", n_steps: int,
                      points: np.ndarray | None = None) -> None:
        """Advance ``d`` in place by ``n_steps`` single steps: the same as ``n_steps`` calls
        of ``advance(d, 1)`` (the same compiled step per step, the time summed step by
        step), in one Python call: the steps run in compiled calls that return every step's
        state and aux (``plant_steps<k>``, ``k`` from :data:`STEP_COUNTS`, largest first;
        a remainder of one step as ``plant_step``), the per-step check and contact-point
        read-out done on those results.

        Args:
            d: the data (its held command is used).
            n_steps: steps.
            points: optional (2, 3) array; after every step, each foot whose contact was
                evaluated writes its contact point [m, W] into its row (the read-out
                :class:`~.fast_plant.FastPlantData` keeps).

        Raises:
            PlantDivergedError: as :meth:`step`, at the step where it happened.
        """
        if n_steps <= 0:
            return
        if self.verlet and not d.started:
            d.call_start()
        d.started = True
        left = int(n_steps)
        while left > 0:
            for k in STEP_COUNTS:
                if k <= left:
                    self._steps(d, k, points)
                    break
            else:
                k = 1
                self._one_step(d, points)
            left -= k

    def _one_step(self, d: "CompiledData", points: np.ndarray | None) -> None:
        """One step of :meth:`advance_steps`: the compiled step, the time, the check, the
        contact points."""
        d._calls[False][1]()
        d.x[:] = d._x_out
        self._stepped(d, points)

    def _stepped(self, d: "CompiledData", points: np.ndarray | None) -> None:
        """The bookkeeping after one step whose state and aux are in ``d``: the time, the
        step count, the divergence check, the contact points."""
        x, aux = d.x, d.aux
        d.t += self.dt
        d.steps += 1
        # ndarray.sum's reduction called directly (the same sum, without its wrapper)
        if not (aux[-1] < self.plant.sim.max_speed) or not math.isfinite(_add_reduce(x, None)):
            self._check(d.t, x, aux)
        if points is not None:
            for foot in (0, 1):
                if aux[_EVALUATED[foot]] > 0.5:
                    points[foot] = aux[_POINT[foot]]

    def _steps(self, d: "CompiledData", k: int, points: np.ndarray | None) -> None:
        """``k`` steps of :meth:`advance_steps` in one compiled call that returns every
        step's state and aux: the same numbers as ``k`` single steps (the same compiled
        step), the time summed step by step. The per-step check cannot fire when every
        speed is below the bound and every state entry below ``BOUND`` (:mod:`.multi_step`) in magnitude (NaN
        fails both tests); otherwise the steps are replayed one by one with the per-step check, so
        the error is raised at the step (time, state, aux, contact points) where it
        happened (the tests and the contact points' last steps come with the call,
        :func:`steps_function`)."""
        d._calls["steps", k][1]()
        xs, auxs, info = d._steps_out[k]     # (k, nx), (k, n_aux): row j = step j; (3,)
        failed, last0, last1 = info.tolist()
        if failed:
            self._replay(d, xs, auxs, points)
            return
        d.x[:] = xs[k - 1]
        d.aux[:] = auxs[k - 1]
        t, dt = d.t, self.dt
        for _ in range(k):
            t += dt
        d.t = t
        d.steps += k
        if points is not None:
            # each foot's point from the last step that evaluated its contact
            if last0:
                points[0] = auxs[int(last0) - 1, _POINT[0]]
            if last1:
                points[1] = auxs[int(last1) - 1, _POINT[1]]

    def _replay(self, d: "CompiledData", xs: np.ndarray, auxs: np.ndarray,
                points: np.ndarray | None) -> None:
        """The steps of one multi-step call taken one by one (state, time, check, points)."""
        for j in range(len(xs)):
            d.x[:] = xs[j]
            d.aux[:] = auxs[j]
            self._stepped(d, points)

    def _check(self, t: float, x: np.ndarray, aux: np.ndarray) -> None:
        L, sim = self.layout, self.plant.sim
        if not (aux[-1] < sim.max_speed) or not np.isfinite(x).all():
            q, v = x[L.q], x[L.v]
            reason = "non-finite" if not np.isfinite(x).all() else "velocity-bound"
            raise PlantDivergedError(t, q, v, reason, q_names=self.plant.biped.q_names,
                                     v_names=self.plant.biped.v_names)


#: the reductions :meth:`CompiledPlant.advance_steps` calls directly
_add_reduce = np.add.reduce
#: per foot: where its "evaluated" flag and its contact point are in an aux vector
_EVALUATED = [AUX_SLICES[0, "evaluated"].start, AUX_SLICES[1, "evaluated"].start]
_POINT = (AUX_SLICES[0, "point"], AUX_SLICES[1, "point"])


class CompiledData:
    """Changing part of one robot for :meth:`CompiledPlant.advance` (like ``PlantData``).

    Attributes:
        t [s], steps, started: as :class:`CompiledState`.
        x: the flat state (views ``q``, ``v``); aux: last call's auxiliary output.
        u: the held control, with views ``tau`` (feed-forward [N·m]), ``q_ref`` [rad],
            ``kp`` [N·m/rad], ``kd`` [N·m·s/rad] — write into them (``d.tau[:] = …``).
        theta: terrain parameters; wrench: trunk wrench in W (f [N], m [N·m]).
    """

    def __init__(self, fast: CompiledPlant, state: CompiledState) -> None:
        L = fast.layout
        self.layout = L
        self.t, self.steps, self.started = state.t, state.steps, state.started
        self.x = np.array(state.x)
        self.aux = np.array(state.aux)
        self.u = np.zeros(L.nu)
        self.theta = fast.theta.copy()
        self.wrench = np.zeros(6)
        self.q, self.v = self.x[L.q], self.x[L.v]
        na = L.na
        self.tau, self.q_ref, self.kp, self.kd = (self.u[k * na:(k + 1) * na] for k in range(4))
        self._x_out = np.zeros(L.nx)
        #: per step count k of STEP_COUNTS: every step's state and aux, (k, nx), (k, n_aux)
        #: (row j: after step j; the column-major outputs of ``plant_steps<k>``)
        self._steps_out = {k: (np.zeros((k, L.nx)), np.zeros((k, len(self.aux))), np.zeros(3))
                           for k in STEP_COUNTS}
        self._calls = {}
        for key, name in ((False, "plant_step"), (True, "plant_chunk"), ("start", "plant_start"),
                          *((("steps", k), f"plant_steps{k}") for k in STEP_COUNTS)):
            buf, call = fast.functions[name].buffer()
            for i, a in enumerate((self.x, self.u, self.theta, self.wrench)):
                buf.set_arg(i, memoryview(a))
            if name.startswith("plant_steps"):
                for i, a in enumerate(self._steps_out[key[1]]):
                    buf.set_res(i, memoryview(a.reshape(-1)))
            else:
                buf.set_res(0, memoryview(self._x_out))
                if name != "plant_start":
                    buf.set_res(1, memoryview(self.aux))
            self._calls[key] = (buf, call)

    def reset(self, x: np.ndarray, theta: np.ndarray) -> None:
        """Back to a fresh data at state ``x`` with parameters ``theta`` (unstarted, time
        0, zero aux, command and wrench; the buffers are kept)."""
        self.t, self.steps, self.started = 0.0, 0, False
        self.x[:] = x
        self.aux[:] = 0.0
        self.u[:] = 0.0
        self.theta[:] = theta
        self.wrench[:] = 0.0

    def call(self, chunk: bool) -> None:
        """One compiled call (``chunk`` steps or one), result copied into ``x``."""
        self._calls[chunk][1]()
        self.x[:] = self._x_out

    def call_start(self) -> None:
        self._calls["start"][1]()
        self.x[:] = self._x_out

    def state(self) -> CompiledState:
        """An immutable snapshot."""
        return CompiledState(self.t, self.steps, self.x, self.started, self.layout, self.aux)


class _Caller:
    """Calls a compiled function through its buffer interface on pre-allocated arrays."""

    def __init__(self, fn: ca.Function) -> None:
        self.ins = [np.zeros(fn.size1_in(i) * fn.size2_in(i)) for i in range(fn.n_in())]
        self.outs = [np.zeros(fn.size1_out(i) * fn.size2_out(i)) for i in range(fn.n_out())]
        self._buf, self._call = fn.buffer()
        for i, a in enumerate(self.ins):
            self._buf.set_arg(i, memoryview(a))
        for i, a in enumerate(self.outs):
            self._buf.set_res(i, memoryview(a))

    def __call__(self, *args) -> list[np.ndarray]:
        for dst, src in zip(self.ins, args):
            dst[:] = src
        self._call()
        return [o.copy() for o in self.outs]


__all__ = ["CompiledPlant", "CompiledState", "CompiledData", "DEFAULT_CHUNK", "STEP_COUNTS",
           "chunk_function", "steps_function"]
