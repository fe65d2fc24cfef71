"""Closed-loop runs: build the plant and the controller, step, log, summarise, plot.

Three layers, each usable on its own:

* :func:`build_simulation` — the immutable :class:`Simulation` (robot, plant terrain,
  controller terrain, plant, controller, push windows) of a
  :class:`~granular_mpc.config.ScenarioConfig`;
* :func:`closed_loop` — a generator that steps one :class:`LoopState` and yields one log
  row (a dict with the run-log columns of :mod:`granular_mpc.runlog`) every
  ``1 / output.log_rate_hz`` simulated seconds, until the duration or a fall. Nothing is
  written: ``synth`` and user scripts consume the rows as they like;
* :func:`run_scenario` — the ``granular-mpc run`` command: output folder,
  ``config.resolved.yaml`` (before the run starts), the chunked Parquet log written as the
  run goes, progress bar, Ctrl-C / divergence / error handling, ``summary.json``, plots
  and the standalone HTML page.

Timing. The plant steps at ``sim.dt``; the controller (``mode: walk``: the walking
controller; ``mode: drop``: joint PD) is evaluated every ``1 / controller.wbc.rate_hz``
and its torques are held in between. A log row at time t holds the state at t and the
torque commanded at t (held until the next tick).

Falls are checked at every controller tick: trunk origin less than
``fall.min_trunk_height`` above the free surface, or |roll| > ``fall.max_roll_deg``, or
|pitch| > ``fall.max_pitch_deg`` (Z-Y-X Euler angles of the trunk).

Pushes (``pushes:``) put a constant world-frame force/torque on the trunk
(``PlantData.base_wrench``) during ``[start, start + duration)``; a ``mid_stance`` push
starts at the first planned mid-stance at or after ``time``. In ``mode: drop`` the trunk
hangs on a vertical guide rig instead (``rig:``): springs and dampers on trunk x, y and
orientation, vertical motion free; joints are held at the standing pose by PD
(``drop.kp``, ``drop.kd``).

The summary (``summary.json``) is defined in :func:`summarize` and in
``docs/user-guide.md``.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import signal
import sys
import threading
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

import numpy as np
import pinocchio as pin

from . import __version__
from .config import ScenarioConfig, load_terrain
from .exceptions import GranularMpcError, OutputError, PlantDivergedError
from .output import json_safe, make_output_folder
from .robot.model import SIDES, Biped
from .scenario import resolved_dict

#: Keys every summary.json holds (the user-facing contract, DESIGN.md).
SUMMARY_KEYS = (
    "terrain", "controller_terrain_model", "commanded_speed_mps", "mean_speed_mps",
    "sim_time_s", "wall_time_s", "realtime_factor", "fell", "cot", "cot_decoupled",
    "sinkage_peak_mm_mean", "slip_mm_mean", "mpc_solve_ms", "wbc_solve_ms", "qp_failures",
    "lateral_drift_m", "max_roll_deg", "max_pitch_deg", "complete", "reason",
)

#: Files a run writes into its folder (replaced when a run reuses the folder).
LOG_DIR = "log"
PLOTS_DIR = "plots"
SUMMARY_FILE = "summary.json"
RESOLVED_FILE = "config.resolved.yaml"
HTML_FILE = "animation.html"


# ======================================================================================
# Model: everything built from the scenario (immutable)
# ======================================================================================


@dataclass(frozen=True)
class PushWindow:
    """A push resolved to times: wrench (f_W [N], m_W [N·m]) on the trunk in [start, end)."""

    start: float
    end: float
    wrench: np.ndarray
    index: int

    @property
    def impulse(self) -> np.ndarray:
        """Linear impulse [N·s], world frame."""
        return self.wrench[:3] * (self.end - self.start)


@dataclass(frozen=True)
class Simulation:
    """Immutable closed-loop model of one scenario (state lives in :class:`LoopState`).

    Attributes:
        scenario: the validated scenario.
        biped: the robot.
        plant: the plant (its ``terrain`` is the plant's terrain model).
        controller_terrain: the ground model the controller believes in (the plant's own
            object when ``controller.terrain`` is ``plant``).
        controller: the walking controller (``None`` in ``mode: drop``).
        q0: initial configuration.
        pushes: push windows, in time order.
        control_every: plant steps per controller tick.
        log_every: plant steps per log row.
        n_steps: plant steps of the whole run.
    """

    scenario: ScenarioConfig
    biped: Biped
    plant: Any
    controller_terrain: Any
    controller: Any
    q0: np.ndarray
    pushes: tuple[PushWindow, ...]
    control_every: int
    log_every: int
    n_steps: int

    @property
    def plant_terrain(self):
        return self.plant.terrain

    @property
    def dt(self) -> float:
        return self.plant.dt

    @property
    def surface_height(self) -> float:
        return self.plant.terrain.surface_height

    @property
    def controller_terrain_name(self) -> str:
        return self.controller_terrain.name

    def new_state(self) -> "LoopState":
        """Fresh changing state at t = 0."""
        pdata = self.plant.new_data(self.q0)
        cdata = None
        if self.controller is not None:
            cdata = self.controller.new_data(self.q0, dt_wbc=self.control_every * self.dt)
        else:
            pdata.base_wrench = _GuideRig(self.scenario.rig, self.q0)
        rng = np.random.default_rng(np.random.SeedSequence(self.scenario.sim.seed))
        return LoopState(plant=pdata, controller=cdata, rng=rng)


def _steps(period: float, dt: float, what: str) -> int:
    n = int(round(period / dt))
    if n < 1:
        from .exceptions import ConfigError

        raise ConfigError(f"{what} period {period:g} s is shorter than sim.dt = {dt:g} s",
                          key="sim.dt")
    return n


def build_simulation(scenario: ScenarioConfig, *, biped: Biped | None = None,
                     extra_effects: Sequence = ()) -> Simulation:
    """Build robot, plant terrain, controller terrain, plant and controller.

    Args:
        scenario: the validated scenario.
        biped: a robot model built from ``scenario.robot`` (built here if ``None``).
        extra_effects: more :class:`~granular_mpc.config.EffectSpec` for the **plant's**
            terrain only (e.g. ``synth --effect``); the controller never sees them.
    """
    from .control.controller import WalkingController
    from .dynamics import Plant
    from .terrain import build_terrain

    if biped is None:
        biped = Biped.from_config(scenario.robot)
    plant_terrain = build_terrain(scenario.terrain, scenario.robot, extra_effects=extra_effects)
    ct_name = scenario.controller.terrain
    if ct_name == "plant" and not extra_effects:
        ctrl_terrain = plant_terrain
    elif ct_name == "plant":
        ctrl_terrain = build_terrain(scenario.terrain, scenario.robot)
    else:
        cfg = scenario.controller_terrain or load_terrain(ct_name)
        ctrl_terrain = build_terrain(cfg, scenario.robot)
    plant = Plant(biped, plant_terrain, scenario.sim)
    dt = scenario.sim.dt
    control_every = _steps(1.0 / scenario.controller.wbc.rate_hz, dt, "controller.wbc.rate_hz")
    log_every = _steps(1.0 / scenario.log_rate_hz, dt, "output.log_rate_hz")
    # the soles roll: start with the CoM exactly over their contact line (else the
    # standing robot tips at e^{ωt} before the first step)
    from .robot.kinematics import balanced_stance

    q0 = balanced_stance(biped, clearance=scenario.start_clearance)
    q0[2] += plant_terrain.surface_height
    controller = None
    pushes: tuple[PushWindow, ...] = ()
    if scenario.mode == "walk":
        controller = WalkingController.build(scenario.controller, scenario.command, biped,
                                             ctrl_terrain)
        pushes = _push_windows(scenario, controller.schedule, dt)
    return Simulation(scenario=scenario, biped=biped, plant=plant,
                      controller_terrain=ctrl_terrain, controller=controller, q0=q0,
                      pushes=pushes, control_every=control_every, log_every=log_every,
                      n_steps=int(round(scenario.sim.duration / dt)))


def _push_windows(scenario: ScenarioConfig, schedule, dt: float) -> tuple[PushWindow, ...]:
    """Resolve the pushes to start/end times (mid-stance from the gait schedule)."""
    out = []
    for i, p in enumerate(scenario.pushes):
        start = p.time
        if p.at == "mid_stance":
            start = _next_mid_stance(schedule, p.time, p.side, scenario.sim.duration, dt)
            if start is None:
                continue
        wrench = np.array(list(p.force_W) + list(p.torque), dtype=float)
        out.append(PushWindow(float(start), float(start + p.duration), wrench, i))
    return tuple(sorted(out, key=lambda w: w.start))


def _next_mid_stance(schedule, t0: float, side: str, t_max: float, dt: float) -> float | None:
    """First time ≥ t0 at which a planned stance (of ``side``) passes 50 % [s]."""
    feet = (0, 1) if side == "any" else (SIDES.index(side),)
    n = int(math.ceil((t_max - t0) / dt))
    for k in range(max(n, 0) + 1):
        t = t0 + k * dt
        if schedule.standing(t):
            continue
        for f in feet:
            if schedule.in_stance(t, f) and schedule.stance_phase(t, f) >= 0.5:
                # step back to the crossing: stance_phase rose past 0.5 within this dt
                if k == 0 or schedule.stance_phase(t - dt, f) < 0.5 or not schedule.in_stance(t - dt, f):
                    return t
    return None


class _GuideRig:
    """Trunk wrench of a vertical guide rail (drop tests), world frame at the trunk origin.

    f = −k (p − p0)_xy − c v_xy (no vertical force);  m = −k_r R0·log3(R0ᵀ R) − c_r R ω_B.
    """

    def __init__(self, rig, q0: np.ndarray) -> None:
        self.k, self.c = rig.stiffness, rig.damping
        self.kr, self.cr = rig.rot_stiffness, rig.rot_damping
        self.p0 = q0[0:3].copy()
        self.R0 = pin.Quaternion(q0[6], q0[3], q0[4], q0[5]).matrix()
        self._w = np.zeros(6)

    def __call__(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).normalized().matrix()
        vw = R @ v[0:3]
        w = self._w
        w[0] = -self.k * (q[0] - self.p0[0]) - self.c * vw[0]
        w[1] = -self.k * (q[1] - self.p0[1]) - self.c * vw[1]
        w[2] = 0.0
        err = self.R0 @ pin.log3(self.R0.T @ R)
        w[3:6] = -self.kr * err - self.cr * (R @ v[3:6])
        return w


# ======================================================================================
# Data: the changing state of one run
# ======================================================================================


@dataclass(frozen=True)
class FallEvent:
    """When and why the closed loop counted as fallen."""

    time: float
    reason: str


@dataclass
class LoopState:
    """Changing state of one closed-loop run.

    Attributes:
        plant: plant data (time, q, v, contact state).
        controller: controller data (``None`` in drop mode).
        step: plant steps taken.
        fall: the first fall, if any.
        stop_reason: set (e.g. by a signal handler) to end the loop at the next step.
        end_reason: why the loop ended (``duration reached``, ``fell: …``, the stop reason).
        pushes_applied: push windows that have started.
        rng: the run's random generator (seeded with ``sim.seed``): anything random in a
            run draws from it, so a seed reproduces the run.
    """

    plant: Any
    controller: Any
    rng: np.random.Generator
    step: int = 0
    fall: FallEvent | None = None
    stop_reason: str | None = None
    end_reason: str = ""
    pushes_applied: list = field(default_factory=list)

    def request_stop(self, reason: str) -> None:
        if self.stop_reason is None:
            self.stop_reason = reason


def trunk_roll_pitch(q: np.ndarray) -> tuple[float, float]:
    """Trunk roll and pitch [rad] (Z-Y-X Euler angles, R = Rz Ry Rx) from q's quaternion."""
    x, y, z, w = q[3], q[4], q[5], q[6]
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return roll, pitch


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


def _planned_stance(schedule, t: float) -> str:
    """Stance label of the gait plan: the single planned stance foot, else ``none``."""
    left, right = schedule.contacts(t)
    if schedule.standing(t) or left == right:
        return "none"
    return "left" if left else "right"


def _solver_columns(cd) -> dict:
    """The controller's latest solver outcome as log columns: status as data, per row."""
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

    Raises:
        PlantDivergedError: the plant state became non-finite or exploded.
        GranularMpcError: from the controller (e.g. a QP that cannot be set up).
    """
    from .runlog import PlantRecorder

    # the controller's matrices are tiny: multithreaded BLAS costs far more than it saves
    # (measured: MPC tick 16 ms → 2.4 ms, WBC 0.8 → 0.7 ms with one thread)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield from _closed_loop(sim, state, PlantRecorder)


def _closed_loop(sim: Simulation, state: LoopState | None, PlantRecorder) -> Iterator[dict]:
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
    while True:
        k = st.step
        t = pd.t
        last = k >= n_steps
        fall_row = False
        if k % sim.control_every == 0 and not last:
            if walk:
                tau = ctrl.compute(cd, t, pd.q, pd.v)
            else:
                qa = pd.q[sim.biped.idx_q]
                dqa = pd.v[sim.biped.idx_v]
                tau = np.clip(kp * (q_hold - qa) - kd * dqa, -tau_max, tau_max)
            pd.set_torque(tau)
            if fall_cfg.enabled and walk and st.fall is None:
                why = check_fall(sim, pd.q)
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
                _, v_ref, _ = cd.ramp.reference(t)
                extra = {"cmd_vx": float(v_ref[0]), "cmd_vy": float(v_ref[1])}
                extra.update(_solver_columns(cd))
                if active is not None:
                    extra.update(push_fx=float(active.wrench[0]), push_fy=float(active.wrench[1]),
                                 push_fz=float(active.wrench[2]))
                else:
                    extra.update(zero_push)
                stance = _planned_stance(ctrl.schedule, t)
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
        plant.step(pd)
        st.step += 1


# ======================================================================================
# Summary
# ======================================================================================


def _stats_ms(values: Sequence[float]) -> dict:
    if len(values) == 0:
        return {"median": None, "p99": None, "n": 0}
    a = np.asarray(values, dtype=float)
    return {"median": float(np.median(a)), "p99": float(np.percentile(a, 99)), "n": int(a.size)}


def averaging_window(sim: Simulation, t_first: float, t_last: float, ramp_duration: float
                     ) -> tuple[float, float, str]:
    """The window [a, b] [s] of the summary averages, and how it was chosen.

    Walk: from ``command.start_delay`` + speed-ramp duration + ``metrics.settle`` to the
    end of the log (the fall, if the run stopped there). If that leaves less than one gait
    period, the second half of the log is used instead (``window_note`` says so). Drop:
    the whole log.
    """
    sc = sim.scenario
    if sim.controller is None:
        return t_first, t_last, "whole run (drop test)"
    a = sc.command.start_delay + ramp_duration + sc.metrics.settle
    period = sc.controller.gait.period
    if t_last - a >= period:
        return a, t_last, ("after the speed ramp + settle: command.start_delay + ramp "
                           f"({ramp_duration:.3f} s) + metrics.settle")
    mid = t_first + 0.5 * (t_last - t_first)
    return mid, t_last, ("second half of the log: the run ended less than one gait period "
                         "after the speed ramp + metrics.settle")


def stance_metrics(log, t_start: float | None = None) -> dict:
    """Per-stance peaks of the stance foot's sinkage and slip, averaged over stances.

    Stances: complete single-stance segments (:func:`granular_mpc.analysis.segment_stances`,
    planned stance label and foot in contact) starting at or after ``t_start`` (all
    complete stances if none does). Per stance: peak sinkage = max ``intrusion_z`` (z_s,
    depth below the touchdown point, positive deeper); peak slip = max
    ‖(``intrusion_x``, ``intrusion_y``)‖ (horizontal displacement of the contact point from
    its touchdown point, which includes the rolling of the sole).

    Returns:
        ``sinkage_peak_mm_mean``, ``slip_mm_mean`` [mm] (None without stances), ``n_stances``.
    """
    from .analysis import segment_stances

    segs = segment_stances(log)
    if t_start is not None and len(segs):
        later = segs[segs["t_start"] >= t_start - 1e-9]
        if len(later):
            segs = later
    if len(segs) == 0:
        return {"sinkage_peak_mm_mean": None, "slip_mm_mean": None, "n_stances": 0}
    z = log["intrusion_z"].to_numpy(dtype=float)
    xy = np.hypot(log["intrusion_x"].to_numpy(dtype=float), log["intrusion_y"].to_numpy(dtype=float))
    sink = [z[s.row_start:s.row_stop].max() for s in segs.itertuples(index=False)]
    slip = [xy[s.row_start:s.row_stop].max() for s in segs.itertuples(index=False)]
    return {"sinkage_peak_mm_mean": 1e3 * float(np.mean(sink)),
            "slip_mm_mean": 1e3 * float(np.mean(slip)), "n_stances": int(len(segs))}


def summarize(log, sim: Simulation, state: LoopState, *, wall_time_s: float,
              complete: bool, reason: str) -> dict:
    """The run summary (``summary.json``).

    Walking metrics are averaged over the window of :func:`averaging_window`:
    ``mean_speed_mps`` = CoM forward displacement / window duration; ``cot`` =
    :func:`granular_mpc.analysis.cot_from_log` (paper definition, |net power|) and
    ``cot_decoupled`` = :func:`granular_mpc.analysis.cot_decoupled.cot_decoupled`
    (``actuation="exact"``) over the same window (None when the CoM did not move
    forward); ``sinkage_peak_mm_mean`` and ``slip_mm_mean`` from :func:`stance_metrics`
    over the stances in the window. Whole run: ``lateral_drift_m`` (final − initial CoM
    y), ``max_roll_deg``, ``max_pitch_deg`` (max |angle|), solver times from the
    controller's tick records, ``qp_failures``.
    """
    from .analysis import cot_from_log
    from .analysis.cot_decoupled import cot_decoupled
    from .viz.plots import trunk_rpy

    sc = sim.scenario
    biped = sim.biped
    pd, cd = state.plant, state.controller
    notes: dict[str, str] = {}

    def safe(name: str, fn: Callable[[], Any], default: Any = None) -> Any:
        try:
            return fn()
        except Exception as exc:  # a metric must never cost the summary
            notes[name] = f"{type(exc).__name__}: {exc}"
            return default

    out: dict[str, Any] = {
        "scenario": sc.name,
        "mode": sc.mode,
        "terrain": sc.terrain.name,
        "terrain_kind": sc.terrain.kind,
        "controller_terrain_model": sim.controller_terrain_name if cd is not None else "none",
        "controller_terrain_kind": sim.controller_terrain.kind if cd is not None else None,
        "commanded_speed_mps": float(sc.command.speed) if sc.mode == "walk" else 0.0,
        "mean_speed_mps": None,
        "sim_time_s": float(pd.t),
        "duration_s": float(sc.sim.duration),
        "wall_time_s": float(wall_time_s),
        "realtime_factor": float(pd.t / wall_time_s) if wall_time_s > 0 else None,
        "fell": state.fall is not None,
        "fall_time_s": state.fall.time if state.fall else None,
        "fall_reason": state.fall.reason if state.fall else None,
        "cot": None, "cot_decoupled": None, "energy_J": None, "distance_m": None,
        "sinkage_peak_mm_mean": None, "slip_mm_mean": None, "n_stances": 0,
        "mpc_solve_ms": _stats_ms([]), "wbc_solve_ms": _stats_ms([]), "qp_failures": 0,
        "lateral_drift_m": None, "max_roll_deg": None, "max_pitch_deg": None,
        "h_com_m": float(biped.com(sim.q0)[2] - biped.lowest_sole_point(sim.q0).min()),
        "seed": int(sc.sim.seed),
        "complete": bool(complete),
        "reason": reason,
    }
    if cd is not None:
        recs = cd.records
        out["mpc_solve_ms"] = _stats_ms([r.solve_ms for r in recs if r.kind == "mpc"])
        out["wbc_solve_ms"] = _stats_ms([r.solve_ms for r in recs if r.kind == "wbc"])
        out["qp_failures"] = int(cd.qp_failures)
    out["pushes"] = [{"start_s": w.start, "end_s": w.end, "force_N": w.wrench[:3].tolist(),
                      "torque_Nm": w.wrench[3:].tolist(), "impulse_Ns": w.impulse.tolist()}
                     for w in state.pushes_applied]
    if log is None or len(log) < 2:
        out["log_rows"] = 0 if log is None else int(len(log))
        notes["log"] = "fewer than 2 log rows: no metrics"
        out["notes"] = notes
        return json_safe(out)
    out["log_rows"] = int(len(log))
    out["log_rate_hz"] = float(sc.log_rate_hz)
    t = log["time"].to_numpy(dtype=float)
    rpy = safe("attitude", lambda: np.degrees(trunk_rpy(log)))
    if rpy is not None:
        out["max_roll_deg"] = float(np.max(np.abs(rpy[:, 0])))
        out["max_pitch_deg"] = float(np.max(np.abs(rpy[:, 1])))
    out["lateral_drift_m"] = float(log["com_y"].iloc[-1] - log["com_y"].iloc[0])
    if sc.mode == "drop":
        depth = np.stack([log[f"{s}_depth"].to_numpy(dtype=float) for s in SIDES])
        out["sinkage_peak_mm_mean"] = 1e3 * float(depth.max(axis=1).mean())
        out["sinkage_final_mm"] = 1e3 * float(depth[:, -1].mean())
        out["peak_grf_z_N"] = float((log["left_grf_z"] + log["right_grf_z"]).max())
        out["window_s"] = [float(t[0]), float(t[-1])]
        out["window_note"] = "whole run (drop test)"
        out["notes"] = notes
        return json_safe(out)
    ramp = cd.ramp.ramp_duration if cd is not None else 0.0
    a, b, note = averaging_window(sim, float(t[0]), float(t[-1]), ramp)
    out["window_s"] = [a, b]
    out["window_note"] = note
    sel = (t >= a - 1e-9) & (t <= b + 1e-9)
    part = log.loc[sel]
    if len(part) >= 2:
        tt = part["time"].to_numpy(dtype=float)
        out["mean_speed_mps"] = float((part["com_x"].iloc[-1] - part["com_x"].iloc[0])
                                      / (tt[-1] - tt[0]))
        res = safe("cot", lambda: cot_from_log(log, biped=biped, t_start=a, t_end=b))
        if res is not None:
            out.update(cot=res.cot, energy_J=res.energy_J, distance_m=res.distance_m)

            def dec():
                js = list(biped.joint_names)
                prt = np.radians(trunk_rpy(part))
                return cot_decoupled(
                    tt, part[[f"q_{j}" for j in js]].to_numpy(float),
                    part[[f"dq_{j}" for j in js]].to_numpy(float),
                    part[[f"tau_{j}" for j in js]].to_numpy(float),
                    prt[:, 1], prt[:, 0], part["stance"].astype(str).to_numpy(),
                    biped.weight, res.distance_m, biped=biped)
            out["cot_decoupled"] = safe("cot_decoupled", dec)
    out.update(safe("stances", lambda: stance_metrics(log, a), {}))
    out["notes"] = notes
    return json_safe(out)


# ======================================================================================
# run_scenario: the `granular-mpc run` command
# ======================================================================================


@dataclass(frozen=True)
class RunResult:
    """What :func:`run_scenario` wrote and found.

    Attributes:
        out_dir: the run folder.
        summary: the content of ``summary.json``.
        plots: figures written into ``out_dir/plots``.
        html: ``out_dir/animation.html`` if written.
    """

    out_dir: Path
    summary: dict
    plots: tuple[Path, ...] = ()
    html: Path | None = None

    @property
    def complete(self) -> bool:
        return bool(self.summary.get("complete"))

    @property
    def reason(self) -> str:
        return str(self.summary.get("reason", ""))

    @property
    def interrupted(self) -> bool:
        return self.reason.startswith("interrupted")

    @property
    def log_dir(self) -> Path:
        return self.out_dir / LOG_DIR


def default_out_dir(scenario: ScenarioConfig, root: str | Path = "runs") -> Path:
    """``runs/<scenario-name>-<YYYYmmdd-HHMMSS>`` (a suffix if that folder exists)."""
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    base = Path(root) / f"{scenario.name}-{stamp}"
    cand, k = base, 2
    while cand.exists():
        cand = base.with_name(f"{base.name}-{k}")
        k += 1
    return cand


def prepare_out_dir(out_dir: str | Path) -> Path:
    """Create the run folder (or reuse one), removing a previous run's outputs in it.

    Only the files a run writes are removed (``log/part-*.parquet``, ``summary.json``,
    ``config.resolved.yaml``, ``plots/*.png``, ``animation.html``); anything else stays.

    Raises:
        OutputError: the folder cannot be created or written.
    """
    out = make_output_folder(out_dir)
    stale = [out / SUMMARY_FILE, out / RESOLVED_FILE, out / HTML_FILE]
    stale += list((out / LOG_DIR).glob("part-*.parquet")) + list((out / LOG_DIR).glob("part-*.tmp"))
    stale += list((out / PLOTS_DIR).glob("*.png"))
    for p in stale:
        try:
            p.unlink(missing_ok=True)
        except OSError as exc:
            raise OutputError(f"cannot replace {p}: {exc.strerror or exc}") from None
    return out


def _write_json(path: Path, data: Mapping) -> None:
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        tmp.replace(path)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None


def write_resolved_config(scenario: ScenarioConfig, path: str | Path) -> Path:
    """Write the fully resolved scenario (files inlined) as YAML; it loads back equal."""
    import yaml

    path = Path(path)
    head = (f"# Resolved scenario '{scenario.name}' (granular_mpc {__version__}, "
            f"{_dt.datetime.now().isoformat(timespec='seconds')}).\n"
            "# Every file inlined; rerun with: granular-mpc run THIS_FILE\n")
    try:
        path.write_text(head + yaml.safe_dump(resolved_dict(scenario), sort_keys=False,
                                              allow_unicode=True), encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


class _StopOnSignal:
    """SIGINT/SIGTERM → ``state.request_stop`` (the loop ends cleanly at the next step).

    A second signal gets the previous handler (Ctrl-C twice: KeyboardInterrupt). Only
    installed in the main thread (signals cannot be caught elsewhere).
    """

    def __init__(self, state: LoopState) -> None:
        self.state = state
        self._old: dict[int, Any] = {}

    def __enter__(self) -> "_StopOnSignal":
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                try:
                    self._old[sig] = signal.signal(sig, self._handle)
                except (ValueError, OSError):  # pragma: no cover - exotic embedders
                    pass
        return self

    def _handle(self, signum, frame) -> None:
        self.state.request_stop(f"interrupted by {signal.Signals(signum).name}")
        old = self._old.get(signum)
        if old is not None:
            signal.signal(signum, old)

    def __exit__(self, *exc) -> None:
        for sig, old in self._old.items():
            try:
                signal.signal(sig, old)
            except (ValueError, OSError):  # pragma: no cover
                pass


class _Progress:
    """Progress bar (rich, on stderr): sim time, real-time factor, falls."""

    def __init__(self, enabled: bool, name: str, duration: float) -> None:
        self.enabled = enabled
        self._next = 0.0
        if not enabled:
            return
        from rich.console import Console
        from rich.progress import (BarColumn, Progress, TextColumn, TimeElapsedColumn)

        self._p = Progress(TextColumn("[bold]{task.description}"), BarColumn(),
                           TextColumn("t = {task.completed:.2f} / {task.total:.2f} s"),
                           TextColumn("RTF {task.fields[rtf]}"),
                           TextColumn("falls {task.fields[falls]}"),
                           TimeElapsedColumn(), console=Console(stderr=True))
        self._task = self._p.add_task(name, total=duration, rtf="-", falls=0)
        self._p.start()

    def update(self, t: float, wall: float, falls: int, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if not force and now < self._next:
            return
        self._next = now + 0.2
        rtf = f"{t / wall:.2f}" if wall > 0 else "-"
        self._p.update(self._task, completed=t, rtf=rtf, falls=falls)

    def close(self) -> None:
        if self.enabled:
            self._p.stop()


def run_scenario(scenario: ScenarioConfig, out_dir: str | Path, *, progress: bool = True,
                 html: bool = False, view: bool = False,
                 on_row: Callable[[dict], None] | None = None,
                 extra_effects: Sequence = ()) -> RunResult:
    """Run one scenario and write its folder (the ``granular-mpc run`` command).

    Writes, in this order: ``config.resolved.yaml`` (before the first step), ``log/``
    (chunked Parquet, flushed every ``output.flush_every`` rows as the run goes),
    ``summary.json``, ``plots/*.png`` (``output.plots``) and, with ``html``,
    ``animation.html``. A ``summary.json`` marked ``"complete": false, "reason":
    "running"`` stands from the start, so even a killed process leaves one.

    A run ends normally at ``sim.duration`` or at a fall (``fall.stop``): ``complete`` is
    true and ``reason`` says which. Ctrl-C (SIGINT) or SIGTERM, a diverged plant
    (:class:`PlantDivergedError`) or any :class:`GranularMpcError` end it early: the log
    parts written so far stay readable, the summary is computed from them and marked
    ``"complete": false`` with the ``reason``. Nothing is raised for these; other
    exceptions are re-raised after the summary is written.

    Args:
        scenario: the validated scenario (:func:`granular_mpc.scenario.load_scenario`).
        out_dir: the run folder (created; a previous run's outputs in it are replaced).
        progress: show a progress bar on stderr.
        html: also write ``animation.html`` (standalone Meshcat page).
        view: live Meshcat view while the run goes (prints the URL).
        on_row: called with every log row (a dict), e.g. to watch a run from a script.
        extra_effects: plant-only extra terrain effects (see :func:`build_simulation`).

    Returns:
        :class:`RunResult`.

    Raises:
        OutputError: the folder cannot be written (before anything runs).
        ConfigError: the scenario cannot be built.
    """
    from .runlog import RunLog, read_log

    sim = build_simulation(scenario, extra_effects=extra_effects)   # bad config: nothing written
    out = prepare_out_dir(out_dir)
    write_resolved_config(scenario, out / RESOLVED_FILE)
    _write_json(out / SUMMARY_FILE, {"scenario": scenario.name, "complete": False,
                                     "reason": "running"})
    log = RunLog(out / LOG_DIR, flush_every=scenario.output.flush_every)
    state = sim.new_state()
    viewer = None
    if view:
        from .viz.meshcat import LiveViewer, ViewerError

        try:
            viewer = LiveViewer(sim.biped, scenario.terrain, stream=sys.stderr)
        except ViewerError as exc:
            warnings.warn(f"live view not available ({exc}); running without it", stacklevel=2)
    bar = _Progress(progress, scenario.name, scenario.sim.duration)
    complete, reason = True, ""
    error: BaseException | None = None
    wall0 = time.perf_counter()
    try:
        with _StopOnSignal(state):
            try:
                for row in closed_loop(sim, state):
                    log.append(row)
                    if viewer is not None:
                        viewer.update(row)
                    if on_row is not None:
                        on_row(row)
                    bar.update(row["time"], time.perf_counter() - wall0,
                               int(state.fall is not None))
                reason = state.end_reason
                complete = not reason.startswith("interrupted")
            except KeyboardInterrupt:
                complete, reason = False, "interrupted by SIGINT"
            except PlantDivergedError as exc:
                complete, reason = False, f"plant diverged: {exc}"
            except GranularMpcError as exc:
                complete, reason = False, f"{type(exc).__name__}: {exc}"
            except BaseException as exc:  # unexpected: record it, then re-raise
                complete, reason, error = False, f"{type(exc).__name__}: {exc}", exc
    finally:
        wall = time.perf_counter() - wall0
        bar.update(state.plant.t, wall, int(state.fall is not None), force=True)
        bar.close()
        log.close()
        if viewer is not None:
            viewer.close()
    try:
        log_df = read_log(out / LOG_DIR) if log.n_rows else None
    except OutputError:
        log_df = None
    summary = summarize(log_df, sim, state, wall_time_s=wall, complete=complete, reason=reason)
    _write_json(out / SUMMARY_FILE, summary)
    if error is not None:
        raise error
    plots: list[Path] = []
    html_path: Path | None = None
    if log_df is not None and len(log_df) >= 2:
        if scenario.output.plots:
            try:
                from .viz.plots import make_run_plots

                plots = [Path(p) for p in make_run_plots(log_df, out / PLOTS_DIR, sim.biped)]
            except Exception as exc:
                summary["plots_error"] = f"{type(exc).__name__}: {exc}"
                warnings.warn(f"plots not written: {exc}", stacklevel=2)
        if html:
            try:
                from .viz.meshcat import export_html

                html_path = export_html(sim.biped, log_df, scenario.terrain, out / HTML_FILE,
                                        fps=scenario.output.html_fps, title=scenario.name)
            except Exception as exc:
                summary["html_error"] = f"{type(exc).__name__}: {exc}"
                warnings.warn(f"animation.html not written: {exc}", stacklevel=2)
        if "plots_error" in summary or "html_error" in summary:
            _write_json(out / SUMMARY_FILE, summary)
    return RunResult(out, summary, tuple(plots), html_path)


# ======================================================================================
# Sweeps: many runs in parallel (local process pool or Ray), one table
# ======================================================================================


@dataclass(frozen=True)
class SweepResult:
    """What :func:`run_sweep` wrote.

    Attributes:
        table: one row per run (``sweep.csv``): run name and folder, the swept values,
            then every scalar of the run's summary (nested values flattened with ``_``).
        csv: path of ``sweep.csv``.
        plot: path of ``cot_vs_speed.png`` (``None`` if no run had a finite CoT).
        ratio: CoT ratio to rigid ground per speed (``plot_cot_vs_speed``'s ``ratio``).
        complete: every run finished (not interrupted, no error).
        plot_note: which runs the plot shows.
    """

    out_dir: Path
    table: Any
    csv: Path
    plot: Path | None
    ratio: Any
    complete: bool
    plot_note: str = ""


def _sweep_worker_init() -> None:
    """Pool workers ignore SIGINT between runs (a run itself stops cleanly on it)."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # pragma: no cover
        pass


def sweep_task(payload: Mapping[str, Any]) -> dict:
    """Run one sweep task in this process (local pool worker, Ray task or in-process).

    Args:
        payload: ``{"name", "params", "scenario" (plain resolved scenario), "out_dir"}``.

    Returns:
        ``{"name", "params", "run_dir", "summary"}``; errors are reported in the summary
        (``complete: false``, ``reason``), never raised.
    """
    from .config import validate

    name, params = payload["name"], dict(payload["params"])
    run_dir = Path(payload["out_dir"])
    try:
        sc = validate(ScenarioConfig, payload["scenario"], source=name)
        res = run_scenario(sc, run_dir, progress=False)
        summary = res.summary
    except Exception as exc:
        summary = {"complete": False, "reason": f"{type(exc).__name__}: {exc}"}
    return {"name": name, "params": params, "run_dir": str(run_dir), "summary": summary}


def _flatten(prefix: str, value: Any, out: dict) -> None:
    if isinstance(value, Mapping):
        for k, v in value.items():
            _flatten(f"{prefix}_{k}" if prefix else str(k), v, out)
    elif isinstance(value, (list, tuple)):
        if prefix == "window_s" and len(value) == 2:
            out["window_start_s"], out["window_end_s"] = value
        else:
            out[prefix] = json.dumps(value)
    else:
        out[prefix] = value


def sweep_table(results: Sequence[Mapping[str, Any]]):
    """``sweep.csv`` rows from worker results (order kept)."""
    import pandas as pd

    rows = []
    for r in results:
        row: dict[str, Any] = {"run": r["name"], "run_dir": r["run_dir"]}
        row.update(r["params"])
        summary = dict(r["summary"])
        summary.pop("notes", None)
        _flatten("", summary, row)
        rows.append(row)
    df = pd.DataFrame(rows)
    for col in df.columns:   # None (JSON null) → NaN in numeric columns
        vals = [v for v in df[col] if v is not None]
        if df[col].dtype == object and vals and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
            df[col] = pd.to_numeric(df[col])
        elif df[col].dtype == object and not vals:
            df[col] = np.nan
    for col, default in (("terrain", ""), ("controller_terrain_model", ""),
                         ("commanded_speed_mps", np.nan), ("mean_speed_mps", np.nan),
                         ("fell", True), ("cot", np.nan), ("complete", False)):
        if col not in df.columns:
            df[col] = default
    return df


def _run_local(payloads: list[dict], workers: int, on_result: Callable[[dict], None]) -> bool:
    """Process pool (spawn); returns False if interrupted."""
    import concurrent.futures as cf
    import multiprocessing as mp

    if workers <= 1:
        for p in payloads:
            r = sweep_task(p)
            on_result(r)
            if str(r["summary"].get("reason", "")).startswith("interrupted"):
                return False
        return True
    with cf.ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                                initializer=_sweep_worker_init) as pool:
        futs = [pool.submit(sweep_task, p) for p in payloads]
        handled: set = set()
        try:
            for f in cf.as_completed(futs):
                handled.add(f)
                on_result(f.result())
        except KeyboardInterrupt:
            # queued runs are dropped; running ones end quickly (they got the SIGINT too)
            for f in futs:
                f.cancel()
            for f in futs:
                if f in handled or f.cancelled():
                    continue
                try:
                    on_result(f.result())
                except Exception:  # a worker lost to the interrupt
                    pass
            return False
    return True


def _run_ray(payloads: list[dict], workers: int | None, address: str | None,
             on_result: Callable[[dict], None]) -> bool:
    """The same tasks as Ray tasks (one CPU each); returns False if interrupted."""
    try:
        import ray
    except ImportError:
        from .exceptions import ConfigError

        raise ConfigError("Ray is not installed: pip install 'granular_mpc[cluster]' "
                          "(or pip install 'ray[default]')", key="--backend", value="ray") from None
    started = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"log_to_driver": False, "include_dashboard": False}
        if address:
            kwargs["address"] = address
        elif workers:
            kwargs["num_cpus"] = workers
        ray.init(**kwargs)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(sweep_task)
        refs = [remote.remote(p) for p in payloads]
        pending = list(refs)
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    on_result(ray.get(ref))
        except KeyboardInterrupt:
            for ref in pending:
                ray.cancel(ref, force=False)
            return False
        return True
    finally:
        if started:
            ray.shutdown()


def run_sweep(tasks: Sequence[Any], out_dir: str | Path, *, workers: int | None = None,
              backend: str = "local", ray_address: str | None = None, progress: bool = True,
              reference_terrain: str = "rigid",
              on_result: Callable[[dict], None] | None = None) -> SweepResult:
    """Run sweep tasks (:func:`granular_mpc.scenario.expand_sweep`) in parallel.

    Each run writes its own folder ``out_dir/runs/<task name>/`` (as ``run``, without
    plots unless ``sweep.plots``); then ``out_dir/sweep.csv`` (one row per run, task
    order) and ``out_dir/cot_vs_speed.png`` (CoT against v/√(g h_CoM), order-2 fits,
    CoT ratio to ``reference_terrain``) are written. The plot uses the runs that did not
    fall and have a finite CoT (all runs with a finite CoT if every run fell).

    Args:
        tasks: :class:`~granular_mpc.scenario.SweepTask` list.
        out_dir: sweep folder.
        workers: parallel runs (default: all cores); 1 runs them in this process.
        backend: ``local`` (``concurrent.futures`` process pool, spawn) or ``ray`` (Ray
            tasks; ``ray_address`` joins a running cluster, else a local Ray instance
            with ``workers`` CPUs is started, or the already initialised one is used).
        progress: progress bar on stderr.
        on_result: called with each finished run's result dict.

    Raises:
        ConfigError: unknown backend, Ray not installed.
        OutputError: the folder cannot be written.
    """
    from .exceptions import ConfigError

    if backend not in ("local", "ray"):
        raise ConfigError(f"unknown backend {backend!r}", key="--backend", value=backend,
                          allowed="local, ray")
    out = make_output_folder(out_dir)
    (out / "runs").mkdir(exist_ok=True)
    payloads = [{"name": t.name, "params": t.params, "scenario": resolved_dict(t.scenario),
                 "out_dir": str((out / "runs" / t.name).resolve())} for t in tasks]
    n_workers = max(1, min(workers or os.cpu_count() or 1, len(payloads)))
    results: dict[str, dict] = {}
    bar = None
    if progress:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        bar = Progress(TextColumn("[bold]sweep"), BarColumn(), MofNCompleteColumn(),
                       TextColumn("falls {task.fields[falls]}"), TimeElapsedColumn(),
                       console=Console(stderr=True))
        task_id = bar.add_task("sweep", total=len(payloads), falls=0)
        bar.start()
    falls = 0

    def got(r: dict) -> None:
        nonlocal falls
        results[r["name"]] = r
        falls += int(bool(r["summary"].get("fell")))
        if bar is not None:
            bar.update(task_id, completed=len(results), falls=falls)
        if on_result is not None:
            on_result(r)

    try:
        if backend == "local":
            finished = _run_local(payloads, n_workers, got)
        else:
            finished = _run_ray(payloads, workers, ray_address, got)
    finally:
        if bar is not None:
            bar.stop()
    ordered = [results[p["name"]] for p in payloads if p["name"] in results]
    table = sweep_table(ordered)
    csv = out / "sweep.csv"
    try:
        table.to_csv(csv, index=False)
    except OSError as exc:
        raise OutputError(f"cannot write {csv}: {exc.strerror or exc}") from None
    complete = finished and len(ordered) == len(payloads) and bool(table["complete"].all())
    plot, ratio, note = sweep_plot(table, out / "cot_vs_speed.png", reference_terrain)
    return SweepResult(out, table, csv, plot, ratio, complete, note)


def sweep_plot(table, path: Path, reference_terrain: str = "rigid"):
    """CoT vs v/√(g h_CoM) of a sweep table (``plot_cot_vs_speed``), written to ``path``.

    Uses the runs that did not fall and have a finite CoT; if every such run fell, the
    runs with a finite CoT (up to their fall). Returns ``(path or None, ratio table,
    note)`` — the note says which runs are shown.
    """
    import pandas as pd

    from .viz.plots import plot_cot_vs_speed

    empty = pd.DataFrame(columns=["series", "terrain", "controller_terrain_model",
                                  "commanded_speed_mps", "cot_ratio"])
    if table.empty or "h_com_m" not in table.columns:
        return None, empty, "no runs with a CoT: no plot"
    cot = pd.to_numeric(table["cot"], errors="coerce")
    finite = table[np.isfinite(cot.to_numpy(dtype=float))]
    good = finite[~finite["fell"].astype(bool)]
    if not good.empty:
        use, note = good, f"{len(good)} of {len(table)} runs (runs that fell are left out)"
    elif not finite.empty:
        use, note = finite, (f"every run with a CoT fell: the plot shows those {len(finite)} "
                             "runs anyway (CoT up to the fall)")
    else:
        return None, empty, "no run has a finite CoT (no forward progress): no plot"
    df = use.assign(h_com=use["h_com_m"].astype(float), cot=use["cot"].astype(float),
                    mean_speed_mps=use["mean_speed_mps"].astype(float))
    out = plot_cot_vs_speed(df, path, reference_terrain=reference_terrain)
    return out.path, out.data["ratio"], note


__all__ = ["Simulation", "LoopState", "FallEvent", "PushWindow", "RunResult", "SUMMARY_KEYS",
           "build_simulation", "closed_loop", "check_fall", "trunk_roll_pitch", "summarize",
           "stance_metrics", "averaging_window", "run_scenario", "default_out_dir",
           "prepare_out_dir", "write_resolved_config", "SweepResult", "run_sweep",
           "sweep_task", "sweep_table", "sweep_plot"]
