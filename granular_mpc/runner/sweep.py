"""Sweeps: many runs in parallel (local process pool or Ray), one table and one plot.

:func:`run_sweep` runs the tasks of :func:`granular_mpc.scenario.expand_sweep`, each with
:func:`sweep_task` (one run folder per task), then writes ``sweep.csv``
(:func:`~granular_mpc.runner.sweep_report.sweep_table`) and ``cot_vs_speed.png``
(:func:`~granular_mpc.runner.sweep_report.sweep_plot`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from ..columns import SWEEP_TABLE_FILE
from ..config import ScenarioConfig, validate
from ..exceptions import ConfigError, OutputError
from ..output import OutputLock, make_output_folder, refuse_existing, remove_files
from ..parallel import map_tasks, stop_requested, worker_count
from ..scenario import resolved_dict
from .progress import SweepProgress
from .run import run_scenario
from .status import StatusWriter, end_state
from .sweep_ray import ray_map
from .sweep_report import sweep_plot, sweep_table

RUNS_DIR = "runs"
"""Sub-folder of a sweep folder holding one run folder per task."""
PLOT_FILE = "cot_vs_speed.png"
"""The sweep's CoT-vs-speed figure."""


@dataclass(frozen=True)
class SweepResult:
    """What :func:`run_sweep` wrote.

    Attributes:
        out_dir: the sweep folder.
        table: one row per run (``sweep.csv``): run name and folder, the swept values,
            then every scalar of the run's summary (nested values flattened with ``_``).
        csv: path of ``sweep.csv``.
        plot: path of ``cot_vs_speed.png`` (``None`` if no run had a finite CoT).
        ratio: CoT ratio to rigid ground per speed (``plot_cot_vs_speed``'s ``ratio``).
        complete: every run finished (not interrupted, no error).
        plot_note: which runs the plot shows.
        interrupted: ``"SIGINT"`` / ``"SIGTERM"`` if the sweep was interrupted (queued
            runs dropped), else ``""``.
        dropped: names of the runs that never started.
    """

    out_dir: Path
    table: Any
    csv: Path
    plot: Path | None
    ratio: Any
    complete: bool
    plot_note: str = ""
    interrupted: str = ""
    dropped: tuple[str, ...] = ()


def sweep_task(payload: Mapping[str, Any]) -> dict:
    """Run one sweep task in this process (local pool worker, Ray task or in-process).

    Args:
        payload: ``{"name", "params", "scenario" (plain resolved scenario), "out_dir",
            "overwrite" (optional)}``.

    Returns:
        ``{"name", "params", "run_dir", "summary", "dropped"}``; errors are reported in the
        summary (``complete: false``, ``reason``), never raised. ``dropped``: the sweep
        was interrupted before this run started (nothing was run or written).
    """
    name, params = payload["name"], dict(payload["params"])
    run_dir = Path(payload["out_dir"])
    if stop_requested():
        return {"name": name, "params": params, "run_dir": str(run_dir), "dropped": True,
                "summary": {"complete": False, "reason": "not started: sweep interrupted"}}
    try:
        sc = validate(ScenarioConfig, payload["scenario"], source=name)
        res = run_scenario(sc, run_dir, progress=False,
                           overwrite=bool(payload.get("overwrite", False)))
        summary = res.summary
    except KeyboardInterrupt as exc:     # a signal before the run folder was touched
        summary = {"complete": False,
                   "reason": f"{exc or 'interrupted by SIGINT'} before the run started"}
    except Exception as exc:
        summary = {"complete": False, "reason": f"{type(exc).__name__}: {exc}"}
    return {"name": name, "params": params, "run_dir": str(run_dir), "summary": summary,
            "dropped": False}


def _interrupted(result: Mapping[str, Any]) -> bool:
    """The run of this result was stopped by Ctrl-C / SIGTERM."""
    return str(result["summary"].get("reason", "")).startswith("interrupted")


def sweep_outputs(out_dir: str | Path) -> list[Path]:
    """A previous sweep's files in ``out_dir``: ``sweep.csv``, the plot, ``status.json``
    and every run folder under ``runs/`` that is not empty."""
    out = Path(out_dir)
    found = [out / SWEEP_TABLE_FILE, out / PLOT_FILE, out / "status.json"]
    runs = out / RUNS_DIR
    if runs.is_dir():
        found += [d for d in runs.iterdir() if not d.is_dir() or any(d.iterdir())]
    return [p for p in found if p.exists()]


def run_sweep(tasks: Sequence[Any], out_dir: str | Path, *, workers: int | None = None,
              backend: str = "local", ray_address: str | None = None, progress: bool = True,
              reference_terrain: str = "rigid",
              on_result: Callable[[dict], None] | None = None,
              overwrite: bool = False) -> SweepResult:
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
        reference_terrain: terrain of the CoT ratio's denominator.
        on_result: called with each finished run's result dict.
        overwrite: replace a previous sweep in ``out_dir`` (else refused).

    Raises:
        ConfigError: unknown backend, Ray not installed.
        OutputError: the folder cannot be written, holds a previous sweep (without
            ``overwrite``) or is being written by another process.
    """
    if backend not in ("local", "ray"):
        raise ConfigError(f"unknown backend {backend!r}", key="--backend", value=backend,
                          allowed="local, ray")
    out = make_output_folder(out_dir)
    with OutputLock(out):
        old = refuse_existing(out, sweep_outputs(out), what="a previous sweep",
                              overwrite=overwrite)
        remove_files(p for p in old if p.is_file())
        status = StatusWriter(out, {"sweep_runs": len(tasks)}).start()
        try:
            res = _sweep(tasks, out, workers, backend, ray_address, progress, reference_terrain,
                         on_result, overwrite)
        except BaseException as exc:
            status.finish("interrupted" if isinstance(exc, KeyboardInterrupt) else "failed",
                          f"{type(exc).__name__}: {exc}")
            raise
        reason = (f"interrupted by {res.interrupted}" if res.interrupted else
                  "" if res.complete else "some runs failed")
        status.finish(end_state(res.complete, reason), reason)
        return res


def _sweep(tasks: Sequence[Any], out: Path, workers, backend, ray_address, progress,
           reference_terrain, on_result, overwrite) -> SweepResult:
    """The body of :func:`run_sweep` once the folder is locked."""
    (out / RUNS_DIR).mkdir(exist_ok=True)
    payloads = [{"name": t.name, "params": t.params, "scenario": resolved_dict(t.scenario),
                 "out_dir": str((out / RUNS_DIR / t.name).resolve()), "overwrite": overwrite}
                for t in tasks]
    results: dict[str, dict] = {}
    bar = SweepProgress(progress, len(payloads))
    falls = 0
    signame = ""

    def got(r: dict) -> None:
        nonlocal falls
        if r.get("dropped"):
            return
        results[r["name"]] = r
        falls += int(bool(r["summary"].get("fell")))
        bar.update(len(results), falls)
        if on_result is not None:
            on_result(r)

    try:
        if backend == "local":
            # workers=0 means all cores, as None does
            pool = map_tasks(sweep_task, payloads,
                             workers=worker_count(workers or None, len(payloads)),
                             ordered=False, on_result=got, start_method="spawn",
                             ignore_sigint=True, stop_when=_interrupted,
                             handle_signals=True, forward_signals=True)
            finished = not pool.interrupted
            signame = pool.signal or (_signal_of(results) if pool.interrupted else "")
            for i in pool.killed:
                p = payloads[i]
                got({"name": p["name"], "params": p["params"], "run_dir": p["out_dir"],
                     "summary": {"complete": False, "reason": f"killed: its worker was "
                                 f"killed after {signame or 'the interruption'}"}})
        else:
            finished = ray_map(sweep_task, payloads, workers, ray_address, got)
    finally:
        bar.close()
    ordered = [results[p["name"]] for p in payloads if p["name"] in results]
    dropped = tuple(p["name"] for p in payloads if p["name"] not in results)
    table = sweep_table(ordered)
    csv = out / SWEEP_TABLE_FILE
    try:
        table.to_csv(csv, index=False)
    except OSError as exc:
        raise OutputError(f"cannot write {csv}: {exc.strerror or exc}") from None
    complete = finished and len(ordered) == len(payloads) and bool(table["complete"].all())
    plot, ratio, note = sweep_plot(table, out / PLOT_FILE, reference_terrain)
    return SweepResult(out, table, csv, plot, ratio, complete, note, signame, dropped)


def _signal_of(results: Mapping[str, dict]) -> str:
    """The signal named by an interrupted run's reason (in-process sweeps)."""
    for r in results.values():
        reason = str(r["summary"].get("reason", ""))
        if reason.startswith("interrupted by "):
            return reason.split()[2]
    return "SIGINT"


__all__ = ["SweepResult", "run_sweep", "sweep_task", "sweep_outputs", "RUNS_DIR", "PLOT_FILE"]
