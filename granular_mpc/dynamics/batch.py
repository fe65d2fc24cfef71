"""Many robots stepped in one call: :class:`BatchPlant` on the compiled plant step.

    fast = CompiledPlant(Plant(biped, terrain, sim))
    batch = BatchPlant(fast, n_robots=64)                 # threads over the cores
    s = batch.initial_state(q0)                           # (nq,) or (64, nq)
    s = batch.step(s, tau, n_steps=10)                    # tau (64, na) or (na,)
    s = batch.step(s, n_steps=10, q_ref=q_ref, kp=150.0, kd=3.0, theta=thetas)

Every robot has its own state, command (feed-forward torque, PD target and gains), trunk
wrench and terrain parameters ``θ`` (``terrain.param_names`` order: e.g. ζ, φ_s, the
bulldozing length, the surface plane, and the parameters of the terrain's effects). The
*set* of effects and the robot model are those the :class:`CompiledPlant` was built with
(another set is another compiled model).

One call runs ``CompiledPlant.functions["plant_chunk"]`` (``chunk`` steps) for all robots
through CasADi's ``map`` of the compiled function: ``"thread"`` splits the robots over
``threads`` OS threads (the compiled code runs without the Python lock), ``"serial"`` runs
them in turn. (CasADi's ``"openmp"`` map is not offered: the PyPI CasADi wheels are built
without OpenMP and fall back to serial evaluation.) Robots whose state
diverges are flagged in :attr:`BatchState.diverged` (no exception: the others go on);
reset them with :meth:`BatchPlant.reset`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..exceptions import ConfigError
from .compiled import CompiledPlant
from .step_sx import AUX_NAMES, StepLayout, aux_foot

PARALLELIZATIONS = ("thread", "serial")


@dataclass(frozen=True)
class BatchState:
    """States of N robots (read-only arrays, one row per robot).

    Attributes:
        t: simulated time per robot [s] (N,); steps: steps taken per robot (N,).
        x: flat states (N, nx), layout :class:`~.step_sx.StepLayout`.
        started: whether each robot has stepped (Verlet: ``a`` evaluated) (N,).
        aux: last call's auxiliary output per robot (N, len(AUX_NAMES)), layout
            :data:`~.step_sx.AUX_FOOT` per foot, then the largest |v| of the call.
        diverged: robots whose state exceeded ``sim.max_speed`` or became non-finite (N,).
    """

    t: np.ndarray
    steps: np.ndarray
    x: np.ndarray
    started: np.ndarray
    aux: np.ndarray
    diverged: np.ndarray
    layout: StepLayout = field(repr=False)

    def __post_init__(self) -> None:
        for name, dtype in (("t", float), ("steps", np.int64), ("x", float),
                            ("started", bool), ("aux", float), ("diverged", bool)):
            arr = np.array(getattr(self, name), dtype=dtype)
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)

    @property
    def n_robots(self) -> int:
        return self.x.shape[0]

    @property
    def q(self) -> np.ndarray:
        """Configurations (N, nq) [m, quaternion x y z w, rad]."""
        return self.x[:, self.layout.q]

    @property
    def v(self) -> np.ndarray:
        """Generalised velocities (N, nv), base twist in the trunk frame."""
        return self.x[:, self.layout.v]

    def foot_force(self, foot: int) -> np.ndarray:
        """Terrain force on foot ``foot`` (0 left, 1 right) in W [N], (N, 3)."""
        return aux_foot(self.aux, foot, "force")

    def foot_in_contact(self, foot: int) -> np.ndarray:
        """Whether a patch of foot ``foot`` is in contact, (N,) bool."""
        L = self.layout
        c = self.x[:, L.contact].reshape(-1, 2, L.n_patches, L.patch_state)
        return c[:, foot, :, 6].max(axis=1) > 0.5


class BatchPlant:
    """N independent robots on one compiled plant model, stepped together.

    Args:
        compiled: the :class:`CompiledPlant` (model, terrain law, step settings).
        n_robots: N.
        parallelization: ``"thread"`` (default) or ``"serial"``.
        threads: worker threads (default: the number of CPUs).
    """

    def __init__(self, compiled: CompiledPlant, n_robots: int, *,
                 parallelization: str = "thread", threads: int | None = None) -> None:
        if n_robots < 1:
            raise ConfigError("n_robots must be ≥ 1", key="n_robots", value=n_robots)
        if parallelization not in PARALLELIZATIONS:
            raise ConfigError(f"unknown parallelization {parallelization!r}",
                              key="parallelization", allowed=", ".join(PARALLELIZATIONS))
        self.compiled = compiled
        self.layout = compiled.layout
        self.n_robots = int(n_robots)
        self.threads = int(threads or os.cpu_count() or 1)
        self.parallelization = parallelization
        names = ("plant_chunk", "plant_step", "plant_start")
        fns = [compiled.functions[n].map(n_robots, "thread", self.threads)
               if parallelization == "thread" else compiled.functions[n].map(n_robots)
               for n in names]
        self._chunk, self._step1, self._start = (_BatchCaller(f, n_robots) for f in fns)

    # ------------------------------------------------------------------ states
    def initial_state(self, q0: np.ndarray, v0: np.ndarray | None = None) -> BatchState:
        """States at configurations ``q0`` ((nq,) for all, or (N, nq)) and velocities ``v0``."""
        N, L = self.n_robots, self.layout
        try:
            q0 = np.broadcast_to(np.asarray(q0, dtype=float), (N, L.nq))
            v0 = np.zeros((N, L.nv)) if v0 is None else np.broadcast_to(
                np.asarray(v0, dtype=float), (N, L.nv))
        except ValueError as exc:
            raise ConfigError(f"q0/v0 must be ({L.nq},)/({L.nv},) or one row per robot: {exc}",
                              key="q0") from exc
        x = np.zeros((N, L.nx))
        x[:, L.q], x[:, L.v] = q0, v0
        quat = x[:, 3:7]                      # free-flyer quaternion, normalised as Plant does
        quat /= np.linalg.norm(quat, axis=1, keepdims=True)
        return BatchState(np.zeros(N), np.zeros(N, int), x, np.zeros(N, bool),
                          np.zeros((N, len(AUX_NAMES))), np.zeros(N, bool), L)

    def reset(self, state: BatchState, mask: np.ndarray, q0: np.ndarray,
              v0: np.ndarray | None = None) -> BatchState:
        """``state`` with the robots selected by ``mask`` (N,) restarted at ``q0``, ``v0``."""
        fresh = self.initial_state(q0, v0)
        m = np.asarray(mask, dtype=bool)

        def pick(a, b):
            return np.where(m.reshape((-1,) + (1,) * (a.ndim - 1)), b, a)

        return BatchState(pick(state.t, fresh.t), pick(state.steps, fresh.steps),
                          pick(state.x, fresh.x), pick(state.started, fresh.started),
                          pick(state.aux, fresh.aux), pick(state.diverged, fresh.diverged),
                          self.layout)

    def controls(self, tau=None, *, q_ref=None, kp=None, kd=None) -> np.ndarray:
        """Control rows ``u = [τ_ff, q_ref, k_p, k_d]`` (N, 4·na), each part broadcast."""
        N, na = self.n_robots, self.layout.na
        u = np.zeros((N, 4 * na))
        for k, part in enumerate((tau, q_ref, kp, kd)):
            if part is not None:
                u[:, k * na:(k + 1) * na] = np.broadcast_to(np.asarray(part, float), (N, na))
        return u

    # ------------------------------------------------------------------ stepping
    def step(self, state: BatchState, tau=None, n_steps: int = 1, *, q_ref=None, kp=None,
             kd=None, wrench=None, theta=None) -> BatchState:
        """Advance every robot by ``n_steps`` steps with its command held.

        Args:
            state: current states (not modified).
            tau, q_ref, kp, kd: as :meth:`CompiledPlant.step`, each (na,) or (N, na).
            n_steps: steps for every robot.
            wrench: trunk wrench in W at the trunk origin, (6,) or (N, 6) [N, N·m].
            theta: terrain parameters, (nθ,) or (N, nθ); default the terrain's own.

        Returns:
            The new :class:`BatchState` (diverged robots flagged, not raised).
        """
        N, L = self.n_robots, self.layout
        u = self.controls(tau, q_ref=q_ref, kp=kp, kd=kd)
        th = np.broadcast_to(self.compiled.theta if theta is None else
                             np.asarray(theta, float), (N, L.n_theta))
        w = np.broadcast_to(np.zeros(6) if wrench is None else np.asarray(wrench, float), (N, 6))
        x = np.array(state.x)
        aux = np.array(state.aux)
        started = np.array(state.started)
        if n_steps > 0 and self.compiled.verlet and not started.all():
            x0 = self._start(x, u, th, w)[0]
            x = np.where(started[:, None], x, x0)
        started[:] = started | (n_steps > 0)
        left = int(n_steps)
        speed = np.zeros(N)
        while left > 0:
            caller, k = (self._chunk, self.compiled.chunk) if left >= self.compiled.chunk \
                else (self._step1, 1)
            x, aux = caller(x, u, th, w)
            speed = np.maximum(speed, aux[:, -1])
            left -= k
        aux[:, -1] = speed
        diverged = np.array(state.diverged) | ~(speed < self.compiled.plant.sim.max_speed) \
            | ~np.isfinite(x).all(axis=1)
        dt = self.compiled.dt
        return BatchState(state.t + n_steps * dt, state.steps + n_steps, x, started, aux,
                          diverged, L)


class _BatchCaller:
    """Calls a mapped function on (N, n) row arrays (= column-major n × N) via buffers."""

    def __init__(self, fn: ca.Function, n: int) -> None:
        self.ins = [np.zeros((n, fn.size1_in(i))) for i in range(fn.n_in())]
        self.outs = [np.zeros((n, fn.size1_out(i))) for i in range(fn.n_out())]
        self._buf, self._call = fn.buffer()
        for i, a in enumerate(self.ins):
            self._buf.set_arg(i, memoryview(a.reshape(-1)))
        for i, a in enumerate(self.outs):
            self._buf.set_res(i, memoryview(a.reshape(-1)))

    def __call__(self, *args) -> list[np.ndarray]:
        for dst, src in zip(self.ins, args):
            dst[:] = src
        self._call()
        return [o.copy() for o in self.outs]


__all__ = ["BatchPlant", "BatchState", "PARALLELIZATIONS"]
