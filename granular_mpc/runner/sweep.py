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
from ..output import make_output_folder
from ..parallel import map_tasks, worker_count
from ..scenario import resolved_dict
from .progress import SweepProgress
from .run import run_scenario
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
    """

    out_dir: Path
    table: Any
    csv: Path
    plot: Path | None
    ratio: Any
    complete: bool
    plot_note: str = ""


def sweep_task(payload: Mapping[str, Any]) -> dict:
    """Run one sweep task in this process (local pool worker, Ray task or in-process).

    Args:
        payload: ``{"name", "params", "scenario" (plain resolved scenario), "out_dir"}``.

    Returns:
        ``{"name", "params", "run_dir", "summary"}``; errors are reported in the summary
        (``complete: false``, ``reason``), never raised.
    """
    name, params = payload["name"], dict(payload["params"])
    run_dir = Path(payload["out_dir"])
    try:
        sc = validate(ScenarioConfig, payload["scenario"], source=name)
        res = run_scenario(sc, run_dir, progress=False)
        summary = res.summary
    except Exception as exc:
        summary = {"complete": False, "reason": f"{type(exc).__name__}: {exc}"}
    return {"name": name, "params": params, "run_dir": str(run_dir), "summary": summary}


def _interrupted(result: Mapping[str, Any]) -> bool:
    """The run of this result was stopped by Ctrl-C / SIGTERM."""
    return str(result["summary"].get("reason", "")).startswith("interrupted")


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
        reference_terrain: terrain of the CoT ratio's denominator.
        on_result: called with each finished run's result dict.

    Raises:
        ConfigError: unknown backend, Ray not installed.
        OutputError: the folder cannot be written.
    """
    if backend not in ("local", "ray"):
        raise ConfigError(f"unknown backend {backend!r}", key="--backend", value=backend,
                          allowed="local, ray")
    out = make_output_folder(out_dir)
    (out / RUNS_DIR).mkdir(exist_ok=True)
    payloads = [{"name": t.name, "params": t.params, "scenario": resolved_dict(t.scenario),
                 "out_dir": str((out / RUNS_DIR / t.name).resolve())} for t in tasks]
    results: dict[str, dict] = {}
    bar = SweepProgress(progress, len(payloads))
    falls = 0

    def got(r: dict) -> None:
        nonlocal falls
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
                             ignore_sigint=True, stop_when=_interrupted)
            finished = not pool.interrupted
        else:
            finished = ray_map(sweep_task, payloads, workers, ray_address, got)
    finally:
        bar.close()
    ordered = [results[p["name"]] for p in payloads if p["name"] in results]
    table = sweep_table(ordered)
    csv = out / SWEEP_TABLE_FILE
    try:
        table.to_csv(csv, index=False)
    except OSError as exc:
        raise OutputError(f"cannot write {csv}: {exc.strerror or exc}") from None
    complete = finished and len(ordered) == len(payloads) and bool(table["complete"].all())
    plot, ratio, note = sweep_plot(table, out / PLOT_FILE, reference_terrain)
    return SweepResult(out, table, csv, plot, ratio, complete, note)


__all__ = ["SweepResult", "run_sweep", "sweep_task", "RUNS_DIR", "PLOT_FILE"]
