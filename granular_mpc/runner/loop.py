"""The closed loop: step plant and controller, check falls, switch pushes, yield log rows.

:func:`closed_loop` is a generator that steps one :class:`~granular_mpc.runner.state.LoopState`
and yields one log row (a dict with the run-log columns of :mod:`granular_mpc.runlog`) every
``1 / output.log_rate_hz`` simulated seconds, until the duration or a fall. Nothing is
written: ``run``, ``synth`` and user scripts consume the rows as they like.

A log row at time t holds the state at t and the torque commanded at t (held until the
next controller tick).

The plant steps between two events (a controller tick, a log row, a push edge, the end)
are taken in one call where the plant offers ``step_n`` (the compiled plant,
:meth:`~granular_mpc.dynamics.fast_plant.FastPlant.step_n`: the same single steps, so the
rows are bit for bit those of one call per step, ``tests/test_loop.py``); a
``state.stop_reason`` set by a signal handler during such a call ends the loop after it
(at most one controller period later).

Falls are checked at every controller tick: trunk origin less than
``fall.min_trunk_height`` above the free surface, or |roll| > ``fall.max_roll_deg``, or
|pitch| > ``fall.max_pitch_deg`` (Z-Y-X Euler angles of the trunk).
"""

from __future__ import annotations

import math
from typing import Any, Iterator

import numpy as np
from threadpoolctl import threadpool_limits

from ..rotations import roll_pitch_from_quat_xyzw
from ..runlog import PlantRecorder
from .build import PushWindow, Simulation
from .state import FallEvent, LoopState


def trunk_roll_pitch(q: np.ndarray) -> tuple[float, float]:
    """Trunk roll and pitch [rad] (Z-Y-X Euler angles, R = Rz Ry Rx) from q's quaternion.

    Args:
        q: configuration in Pinocchio order (trunk quaternion ``(x, y, z, w)`` in ``q[3:7]``).
    """
    return roll_pitch_from_quat_xyzw(q[3:7])


def check_fall(sim: Simulation, q: np.ndarray) -> str | None:
    """Why the trunk state ``q`` counts as fallen, or ``None`` (thresholds: ``fall:``)."""
    f = sim.scenario.fall
    h = q[2] - sim.surface_height
    if h < f.min_trunk_height:
        return f"trunk height {h:.3f} m < {f.min_trunk_height:g} m"
    roll, pitch = trunk_roll_pitch(q)
    if abs(math.degrees(roll)) > f.max_roll_deg:
        return f"|roll| {abs(math.degrees(roll)):.1f} deg > {f.max_roll_deg:g} deg"
    if abs(math.degrees(pitch)) > f.max_pitch_deg:
        return f"|pitch| {abs(math.degrees(pitch)):.1f} deg > {f.max_pitch_deg:g} deg"
    return None


def planned_stance(schedule, t: float) -> str:
    """Stance label of the gait plan at ``t`` [s]: the single planned stance foot, else ``none``."""
    left, right = schedule.contacts(t)
    if schedule.standing(t) or left == right:
        return "none"
    return "left" if left else "right"


def solver_columns(cd) -> dict:
    """The controller's latest solver outcome as log columns: status as data, per row.

    Args:
        cd: the walking controller's data.

    Returns:
        ``mpc_status``, ``mpc_fallback``, ``mpc_solve_ms`` [ms], ``wbc_status``,
        ``wbc_solve_ms`` [ms] and the cumulative ``qp_failures``.
    """
    plan = cd.plan
    return {
        "mpc_status": plan.status.value if plan is not None else "none",
        "mpc_fallback": plan.fallback if plan is not None else "",
        "mpc_solve_ms": float(plan.solve_ms) if plan is not None else float("nan"),
        "wbc_status": cd.wbc.last_status.value,
        "wbc_solve_ms": float(cd.wbc.last_ms),
        "qp_failures": int(cd.qp_failures),
    }


def closed_loop(sim: Simulation, state: LoopState | None = None) -> Iterator[dict]:
    """Step the closed loop; yield one log row every ``sim.log_every`` plant steps.

    Rows are dicts with the run-log columns (:class:`granular_mpc.runlog.PlantRecorder`)
    plus ``cmd_vx, cmd_vy`` [m/s] (speed reference, walk mode), the controller's latest
    solver outcome (``mpc_status``, ``mpc_fallback``, ``mpc_solve_ms``, ``wbc_status``,
    ``wbc_solve_ms``, cumulative ``qp_failures``) and ``push_fx, push_fy,
    push_fz`` [N] (force on the trunk, world frame). The row at a fall is always yielded.
    The loop ends at ``sim.duration`` (a last row at t = duration), at a fall when
    ``fall.stop``, or when ``state.stop_reason`` is set; ``state.end_reason`` says which.

    Args:
        sim: the simulation (:func:`~granular_mpc.runner.build.build_simulation`).
        state: the state to step (``sim.new_state()`` if ``None``); stepped in place.

    Raises:
        PlantDivergedError: the plant state became non-finite or exploded.
        GranularMpcError: from the controller (e.g. a QP that cannot be set up).
    """
    # the controller's matrices are tiny: multithreaded BLAS costs far more than it saves
    # (measured: MPC tick 16 ms → 2.4 ms, WBC 0.8 → 0.7 ms with one thread)
    with threadpool_limits(limits=1, user_api="blas"):
        yield from _step_rows(sim, state)


def _step_rows(sim: Simulation, state: LoopState | None) -> Iterator[dict]:
    """The loop of :func:`closed_loop` (without the BLAS thread limit)."""
    st = state if state is not None else sim.new_state()
    plant, pd, cd = sim.plant, st.plant, st.controller
    ctrl = sim.controller
    sc = sim.scenario
    recorder = PlantRecorder(sim.biped)
    walk = ctrl is not None
    if not walk:
        q_hold = sim.biped.actuated(sim.q0)
        kp, kd = sc.drop.kp, sc.drop.kd
        tau_max = sim.biped.torque_limits
    pushes = list(sim.pushes)
    active: PushWindow | None = None
    zero_push = {"push_fx": 0.0, "push_fy": 0.0, "push_fz": 0.0}
    fall_cfg = sc.fall
    n_steps = sim.n_steps
    half_dt = 0.5 * sim.dt        # window edges fall on the nearest plant step
    step_n = getattr(plant, "step_n", None)
    chunked = step_n is not None
    while True:
        k = st.step
        t = pd.t
        last = k >= n_steps
        fall_row = False
        if k % sim.control_every == 0 and not last:
            q = pd.q        # a copy (read once: the plant does not step until after the row)
            if walk:
                tau = ctrl.compute(cd, t, q, pd.v)
            elif sim.playback is not None:
                tau = sim.playback.torque(t, pd.q[sim.biped.idx_q], pd.v[sim.biped.idx_v])
            else:
                qa = pd.q[sim.biped.idx_q]
                dqa = pd.v[sim.biped.idx_v]
                tau = np.clip(kp * (q_hold - qa) - kd * dqa, -tau_max, tau_max)
            pd.set_torque(tau)
            if fall_cfg.enabled and (walk or sim.playback is not None) and st.fall is None:
                why = check_fall(sim, q)
                if why is not None:
                    st.fall = FallEvent(t, why)
                    fall_row = True
        if walk:
            # pushes: switch the trunk wrench on/off at window edges
            if active is not None and t >= active.end - half_dt:
                active = None
                pd.base_wrench = None
            if active is None and pushes and t >= pushes[0].start - half_dt:
                active = pushes.pop(0)
                st.pushes_applied.append(active)
                pd.base_wrench = active.wrench
        if k % sim.log_every == 0 or fall_row or last:
            extra: dict[str, Any]
            if walk:
                # one dict display: the same keys, order and values as the former
                # dict + update(solver_columns) + update(push) calls
                v_ref = cd.command_velocity(t)      # the tick's, when it ran at t
                fx, fy, fz = ((float(active.wrench[0]), float(active.wrench[1]),
                               float(active.wrench[2])) if active is not None
                              else (0.0, 0.0, 0.0))
                extra = {"cmd_vx": float(v_ref[0]), "cmd_vy": float(v_ref[1]),
                         **solver_columns(cd), "push_fx": fx, "push_fy": fy, "push_fz": fz}
                stance = planned_stance(ctrl.schedule, t)
            else:
                extra = zero_push
                stance = None
            yield recorder.row(pd, stance=stance, extra=extra)
        if last:
            st.end_reason = "duration reached"
            return
        if fall_row and fall_cfg.stop:
            st.end_reason = f"fell: {st.fall.reason} at t = {st.fall.time:.3f} s"
            return
        if st.stop_reason is not None:
            st.end_reason = st.stop_reason
            return
        # the steps up to the next event (controller tick, log row, end, push edge) have
        # nothing to do between them: stepped in one call (the same single steps)
        n = _quiet_steps(k, sim, active, pushes, pd.t, half_dt) if chunked else 1
        if n > 1:
            step_n(pd, n)
        else:
            plant.step(pd)
        st.step += n


def _quiet_steps(k: int, sim: Simulation, active: PushWindow | None, pushes: list,
                 t: float, half_dt: float) -> int:
    """How many plant steps from step ``k`` (time ``t`` [s]) the loop can take in one call:
    up to the next controller tick, log row or the end, and stopping at the step where
    the next push edge is reached (the loop's own test, on the time summed step by step)."""
    n = min(sim.control_every - k % sim.control_every, sim.log_every - k % sim.log_every,
            max(sim.n_steps - k, 1))
    edge = (active.end - half_dt if active is not None
            else pushes[0].start - half_dt if pushes else None)
    if edge is not None and n > 1:
        dt = sim.dt
        for j in range(1, n):
            t += dt
            if t >= edge:
                return j
    return n


__all__ = ["closed_loop", "check_fall", "trunk_roll_pitch", "planned_stance", "solver_columns"]
