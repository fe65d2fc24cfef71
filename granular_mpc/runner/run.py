"""One run: the ``granular-mpc run`` command (:func:`run_scenario`) and its result.

Writes the run folder (:mod:`granular_mpc.runner.rundir`, locked while written,
``status.json`` with a heartbeat: :mod:`granular_mpc.runner.status`): ``config.resolved.yaml``
(before the run starts), the chunked Parquet log written as the run goes, a progress bar,
Ctrl-C / divergence / error handling, ``summary.json``
(:func:`granular_mpc.analysis.summary.summarize`), plots and the standalone HTML page.
"""

from __future__ import annotations

import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from ..analysis.summary import summarize
from ..columns import HTML_FILE, LOG_DIR, PLOTS_DIR, RESOLVED_FILE, SUMMARY_FILE
from ..config import ScenarioConfig
from ..exceptions import GranularMpcError, OutputError, PlantDivergedError
from ..output import OutputLock, make_output_folder, write_json
from ..runlog import RunLog, read_log
from .build import build_simulation
from .loop import closed_loop
from .progress import RunProgress
from .rundir import prepare_out_dir, write_resolved_config
from .signals import RunSignals
from .status import StatusWriter, end_state


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
        """The run ended normally (duration reached or a fall)."""
        return bool(self.summary.get("complete"))

    @property
    def reason(self) -> str:
        """Why the run ended."""
        return str(self.summary.get("reason", ""))

    @property
    def interrupted(self) -> bool:
        """The run was stopped by SIGINT or SIGTERM."""
        return self.reason.startswith("interrupted")

    @property
    def log_dir(self) -> Path:
        """The folder of the log parts."""
        return self.out_dir / LOG_DIR


def run_scenario(scenario: ScenarioConfig, out_dir: str | Path, *, progress: bool = True,
                 html: bool = False, view: bool = False,
                 on_row: Callable[[dict], None] | None = None,
                 extra_effects: Sequence = (), overwrite: bool = False) -> RunResult:
    """Run one scenario and write its folder (the ``granular-mpc run`` command).

    The folder is locked while the run writes it (a second writer gets an
    :class:`OutputError` naming this process's PID) and ``status.json``
    (:mod:`granular_mpc.runner.status`) says ``running`` with a heartbeat every few
    seconds, then ``complete``, ``interrupted`` or ``failed``. Writes, in this order:
    ``config.resolved.yaml`` (before the first step), ``log/`` (chunked Parquet, flushed
    every ``output.flush_every`` rows as the run goes), ``summary.json``, ``plots/*.png``
    (``output.plots``) and, with ``html``, ``animation.html``. A ``summary.json`` marked
    ``"complete": false, "reason": "running"`` stands from the start, so even a killed
    process leaves one (and ``status.json`` tells it is dead).

    A run ends normally at ``sim.duration`` or at a fall (``fall.stop``): ``complete`` is
    true and ``reason`` says which. Ctrl-C (SIGINT) or SIGTERM — during start-up, the
    loop (a second one too) or the summary — a diverged plant
    (:class:`PlantDivergedError`) or any :class:`GranularMpcError` end it early: the log
    parts written so far stay readable, the summary is computed from them and marked
    ``"complete": false`` with the ``reason``. Nothing is raised for these; other
    exceptions are re-raised after the summary is written. ``summary.json`` and
    ``status.json`` record the package version and the ProxSuite build.

    Args:
        scenario: the validated scenario (:func:`granular_mpc.scenario.load_scenario`).
        out_dir: the run folder (created).
        progress: show a progress bar on stderr.
        html: also write ``animation.html`` (standalone Meshcat page).
        view: live Meshcat view while the run goes (prints the URL).
        on_row: called with every log row (a dict), e.g. to watch a run from a script.
        extra_effects: plant-only extra terrain effects (see :func:`build_simulation`).
        overwrite: replace a previous run's outputs in ``out_dir`` (else refused).

    Returns:
        :class:`RunResult`.

    Raises:
        OutputError: the folder cannot be written, holds a previous run (without
            ``overwrite``) or is being written by another process (before anything runs).
        ConfigError: the scenario cannot be built.
        Interrupted: SIGINT / SIGTERM before the folder was touched.
    """
    with RunSignals() as signals:
        sim = build_simulation(scenario, extra_effects=extra_effects)   # bad config: nothing written
        out = make_output_folder(out_dir)
        with OutputLock(out):
            prepare_out_dir(out, overwrite=overwrite)
            status = StatusWriter(out, {"scenario": scenario.name})
            try:
                status.start()
                write_resolved_config(scenario, out / RESOLVED_FILE)
                write_json(out / SUMMARY_FILE, {"scenario": scenario.name, "complete": False,
                                                "reason": "running", **_provenance(status)})
                log = RunLog(out / LOG_DIR, flush_every=scenario.output.flush_every)
                state = sim.new_state()
            except BaseException as exc:        # start-up error or signal: say so, final
                signals.hold()
                stopped = isinstance(exc, KeyboardInterrupt)
                reason = (f"{exc or 'interrupted by SIGINT'} during start-up" if stopped else
                          f"start-up failed: {type(exc).__name__}: {exc}")
                summary = {"scenario": scenario.name, "complete": False, "reason": reason,
                           **_provenance(status)}
                write_json(out / SUMMARY_FILE, summary)
                status.finish(end_state(False, reason), reason)
                if stopped:
                    return RunResult(out, summary)
                raise
            return _run_loop(sim, state, out, log, status, signals, progress=progress,
                             html=html, view=view, on_row=on_row)


def _provenance(status: StatusWriter) -> dict:
    return {k: status.data[k] for k in ("package_version", "proxsuite_build")}


def _run_loop(sim, state, out: Path, log: RunLog, status: StatusWriter, signals: RunSignals, *,
              progress: bool, html: bool, view: bool,
              on_row: Callable[[dict], None] | None) -> RunResult:
    """The loop of :func:`run_scenario` once the folder is ready, then the summary (while
    signals are held) and the figures."""
    scenario = sim.scenario
    viewer = None
    complete, reason = True, ""
    error: BaseException | None = None
    wall0 = time.perf_counter()
    bar = None
    try:
        signals.attach(state)
        if view:
            # the viewer (meshcat, zmq) is imported only when asked for
            from ..viz.meshcat import LiveViewer, ViewerError

            try:
                viewer = LiveViewer(sim.biped, scenario.terrain, stream=sys.stderr)
            except ViewerError as exc:
                warnings.warn(f"live view not available ({exc}); running without it",
                              stacklevel=3)
        bar = RunProgress(progress, scenario.name, scenario.sim.duration)
        wall0 = time.perf_counter()
        for row in closed_loop(sim, state):
            log.append(row)
            if viewer is not None:
                viewer.update(row)
            if on_row is not None:
                on_row(row)
            status.data["sim_time_s"] = row["time"]
            bar.update(row["time"], time.perf_counter() - wall0, int(state.fall is not None))
        reason = state.end_reason
        complete = not reason.startswith("interrupted")
    except KeyboardInterrupt as exc:
        name = signals.first or getattr(exc, "signame", "SIGINT")
        again = " (second signal: stopped at once)" if len(signals.received) > 1 else ""
        complete, reason = False, f"interrupted by {name}{again}"
    except PlantDivergedError as exc:
        complete, reason = False, f"plant diverged: {exc}"
    except GranularMpcError as exc:
        complete, reason = False, f"{type(exc).__name__}: {exc}"
    except BaseException as exc:  # unexpected: record it, then re-raise
        complete, reason, error = False, f"{type(exc).__name__}: {exc}", exc
    finally:
        signals.hold()           # from here to the final summary: signals are only noted
        wall = time.perf_counter() - wall0
        if bar is not None:
            bar.update(state.plant.t, wall, int(state.fall is not None), force=True)
            bar.close()
        try:
            log.close()
        finally:
            if viewer is not None:
                viewer.close()
    try:
        log_df = read_log(out / LOG_DIR) if log.n_rows else None
    except OutputError:
        log_df = None
    summary = summarize(log_df, sim, state, wall_time_s=wall, complete=complete, reason=reason)
    summary.update(_provenance(status))
    summary["plant"] = sim.plant_choice.resolved        # the plant that stepped
    summary["plant_note"] = sim.plant_choice.reason     # why, when not the one asked for
    write_json(out / SUMMARY_FILE, summary)
    status.finish(end_state(complete, reason), reason)
    signals.release()
    if error is not None:
        raise error
    try:
        plots, html_path = _figures(summary, log_df, sim, out, html)
    except KeyboardInterrupt as exc:
        plots, html_path = [], None
        summary["plots_error"] = f"figures skipped: {exc or 'interrupted'}"
    if "plots_error" in summary or "html_error" in summary:
        write_json(out / SUMMARY_FILE, summary)
    return RunResult(out, summary, tuple(plots), html_path)


def _figures(summary: dict, log_df, sim, out: Path, html: bool) -> tuple[list[Path], Path | None]:
    """Write ``plots/*.png`` and (with ``html``) ``animation.html``; a failure is recorded
    in ``summary`` (``plots_error``, ``html_error``) and warned about, never raised."""
    scenario = sim.scenario
    plots: list[Path] = []
    html_path: Path | None = None
    if log_df is None or len(log_df) < 2:
        return plots, html_path
    if scenario.output.plots:
        try:
            # matplotlib is imported only when figures are made
            from ..viz.plots import make_run_plots

            plots = [Path(p) for p in make_run_plots(log_df, out / PLOTS_DIR, sim.biped)]
        except Exception as exc:
            summary["plots_error"] = f"{type(exc).__name__}: {exc}"
            warnings.warn(f"plots not written: {exc}", stacklevel=3)
    if html:
        try:
            from ..viz.meshcat import export_html

            html_path = export_html(sim.biped, log_df, scenario.terrain, out / HTML_FILE,
                                    fps=scenario.output.html_fps, title=scenario.name)
        except Exception as exc:
            summary["html_error"] = f"{type(exc).__name__}: {exc}"
            warnings.warn(f"animation.html not written: {exc}", stacklevel=3)
    return plots, html_path


__all__ = ["RunResult", "run_scenario"]
