"""The run summary (``summary.json``): averaging window, stance sinkage/slip, CoT, solver
statistics.

:func:`summarize` turns a run log and the run's final state into the summary dict that
``granular-mpc run`` writes; its keys are the user-facing contract (:data:`SUMMARY_KEYS`,
``docs/user-guide.md``). The pieces are usable on their own: :func:`averaging_window`
(which part of the log the walking averages use), :func:`stance_metrics` (per-stance peak
sinkage and slip), :func:`solve_time_stats` (median / p99 of solver times).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from ..columns import COM_POSITION, FOOT_SIDES, TIME, foot_column
from ..output import json_safe
from .attitude import trunk_rpy
from .cot import COT_READINGS
from .cot_readings import cot_readings_report
from .metrics import stance_peaks

if TYPE_CHECKING:  # the runner sits above analysis: types only, no import at run time
    from ..runner.build import Simulation
    from ..runner.state import LoopState

#: Keys every summary.json holds (the user-facing contract, DESIGN.md).
SUMMARY_KEYS = (
    "terrain", "controller_terrain_model", "commanded_speed_mps", "mean_speed_mps",
    "sim_time_s", "wall_time_s", "realtime_factor", "fell", "cot", "cot_decoupled",
    "sinkage_peak_mm_mean", "slip_mm_mean", "mpc_solve_ms", "wbc_solve_ms", "qp_failures",
    "lateral_drift_m", "max_roll_deg", "max_pitch_deg", "complete", "reason",
    "cot_reading", "cot_abs_per_joint", "cot_abs_net", "cot_positive",
    "cot_decoupled_abs_per_joint", "cot_decoupled_abs_net", "cot_decoupled_positive",
    "stance_source",
)

_COM_X, _COM_Y, _ = COM_POSITION


def solve_time_stats(values: Sequence[float]) -> dict:
    """Median and 99th percentile of solver times.

    Args:
        values: solve times [ms].

    Returns:
        ``{"median", "p99", "n"}`` (median and p99 in ms, ``None`` without values).
    """
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
    the whole log. Playback: from the start of the recorded run's window (it walked the
    same references) to the end of the log.

    Args:
        sim: the simulation (its scenario and whether it has a walking controller).
        t_first: time of the first log row [s].
        t_last: time of the last log row [s].
        ramp_duration: duration of the speed ramp [s].
    """
    sc = sim.scenario
    playback = getattr(sim, "playback", None)
    if playback is not None:
        w = playback.reference.window_s
        if w is None or t_last - w[0] < sc.controller.gait.period:
            return t_first, t_last, "whole run (playback; the recorded run gives no usable window)"
        return w[0], t_last, "the recorded run's window (playback)"
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
    """Per-stance peak sinkage and slip over the *planned* stances (the historical
    segmentation; the summary uses touchdown to lift-off, :func:`~.metrics.stance_peaks`).

    Stances: complete single-stance segments of the planned stance label with the foot in
    contact, starting at or after ``t_start`` (all complete stances if none does). Per
    stance: peak sinkage = max ``intrusion_z`` (z_s, depth below the touchdown point,
    positive deeper); peak slip = max ‖(``intrusion_x``, ``intrusion_y``)‖.

    Returns:
        ``sinkage_peak_mm_mean``, ``slip_mm_mean`` [mm] (None without stances), ``n_stances``.
    """
    peaks = stance_peaks(log, t_start, source="planned")
    return {"sinkage_peak_mm_mean": peaks.sinkage_peak_mm_mean,
            "slip_mm_mean": peaks.slip_mm_mean, "n_stances": peaks.n_stances}


def summarize(log, sim: Simulation, state: LoopState, *, wall_time_s: float,
              complete: bool, reason: str) -> dict:
    """The run summary (``summary.json``).

    Walking metrics are averaged over the window of :func:`averaging_window`:
    ``mean_speed_mps`` = CoM forward displacement / window duration. Cost of transport
    over the same window under every reading of the paper's E (docs/analysis.md §1,
    :func:`granular_mpc.analysis.cot_readings_report`): ``cot_abs_per_joint``
    (Σ_i |τ_i q̇_i|), ``cot_abs_net`` (|Σ_i τ_i q̇_i|, the literal reading),
    ``cot_positive`` (Σ_i max(τ_i q̇_i, 0)), and the decoupled sagittal + frontal form of
    each (``cot_decoupled_<reading>``); ``cot`` and ``cot_decoupled`` are the default
    reading (``cot_reading``: ``abs_per_joint``). ``sinkage_peak_mm_mean`` and
    ``slip_mm_mean``: per-stance peaks averaged over the stances in the window, stances
    from touchdown to lift-off (:func:`granular_mpc.analysis.stance_peaks`;
    ``stance_source`` says from what). Whole run: ``lateral_drift_m`` (final − initial CoM
    y), ``max_roll_deg``, ``max_pitch_deg`` (max |angle|), solver times from the
    controller's tick records, ``qp_failures``. A metric that fails is left ``None`` and
    its error is recorded under ``notes``.

    Args:
        log: the run log (DataFrame, :func:`granular_mpc.runlog.read_log`) or ``None``.
        sim: the simulation that was run.
        state: its final state.
        wall_time_s: wall-clock duration of the run [s].
        complete: the run ended normally (duration or fall).
        reason: why it ended.

    Returns:
        A JSON-safe dict (NaN/inf → ``None``) holding at least :data:`SUMMARY_KEYS`.
    """
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
        "cot": None, "cot_decoupled": None, "cot_reading": None, "energy_J": None,
        "distance_m": None,
        **{f"cot_{r}": None for r in COT_READINGS},
        **{f"cot_decoupled_{r}": None for r in COT_READINGS},
        "sinkage_peak_mm_mean": None, "slip_mm_mean": None, "n_stances": 0,
        "stance_source": None,
        "mpc_solve_ms": solve_time_stats([]), "wbc_solve_ms": solve_time_stats([]),
        "qp_failures": 0,
        "lateral_drift_m": None, "max_roll_deg": None, "max_pitch_deg": None,
        "h_com_m": float(biped.com(sim.q0)[2] - biped.lowest_sole_point(sim.q0).min()),
        "seed": int(sc.sim.seed),
        "complete": bool(complete),
        "reason": reason,
    }
    if cd is not None:
        recs = cd.records
        out["mpc_solve_ms"] = solve_time_stats([r.solve_ms for r in recs if r.kind == "mpc"])
        out["wbc_solve_ms"] = solve_time_stats([r.solve_ms for r in recs if r.kind == "wbc"])
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
    t = log[TIME].to_numpy(dtype=float)
    rpy = safe("attitude", lambda: np.degrees(trunk_rpy(log)))
    if rpy is not None:
        out["max_roll_deg"] = float(np.max(np.abs(rpy[:, 0])))
        out["max_pitch_deg"] = float(np.max(np.abs(rpy[:, 1])))
    out["lateral_drift_m"] = float(log[_COM_Y].iloc[-1] - log[_COM_Y].iloc[0])
    if sc.mode == "drop":
        depth = np.stack([log[foot_column(s, "depth")].to_numpy(dtype=float) for s in FOOT_SIDES])
        out["sinkage_peak_mm_mean"] = 1e3 * float(depth.max(axis=1).mean())
        out["sinkage_final_mm"] = 1e3 * float(depth[:, -1].mean())
        out["peak_grf_z_N"] = float((log[foot_column("left", "grf_z")]
                                     + log[foot_column("right", "grf_z")]).max())
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
        tt = part[TIME].to_numpy(dtype=float)
        out["mean_speed_mps"] = float((part[_COM_X].iloc[-1] - part[_COM_X].iloc[0])
                                      / (tt[-1] - tt[0]))
        rep = safe("cot", lambda: cot_readings_report(log, biped=biped, t_start=a, t_end=b))
        if rep is not None:
            default = rep.full.get(rep.default_reading)
            out.update(cot=default.cot, energy_J=default.energy_J,
                       distance_m=default.distance_m, cot_reading=rep.default_reading,
                       cot_decoupled=(None if rep.decoupled is None
                                      else rep.decoupled.get(rep.default_reading)))
            out.update(rep.summary_items())
    out.update(safe("stances", lambda: stance_peaks(log, a).summary_items(), {}))
    out["notes"] = notes
    return json_safe(out)


__all__ = ["SUMMARY_KEYS", "summarize", "averaging_window", "stance_metrics",
           "solve_time_stats"]
