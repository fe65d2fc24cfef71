"""Closed-loop runs: build the plant and the controller, step, log, summarise, sweep.

Three layers, each usable on its own:

* :func:`build_simulation` (``build.py``) — the immutable :class:`Simulation` (robot,
  plant terrain, controller terrain, plant, controller, push windows) of a
  :class:`~granular_mpc.config.ScenarioConfig`;
* :func:`closed_loop` (``loop.py``) — a generator that steps one :class:`LoopState`
  (``state.py``) and yields one log row (a dict with the run-log columns of
  :mod:`granular_mpc.runlog`) every ``1 / output.log_rate_hz`` simulated seconds, until the
  duration or a fall. Nothing is written: ``synth`` and user scripts consume the rows as
  they like;
* :func:`run_scenario` (``run.py``) — the ``granular-mpc run`` command: output folder
  (``rundir.py``), ``config.resolved.yaml`` (before the run starts), the chunked Parquet
  log written as the run goes, progress bar (``progress.py``), Ctrl-C / SIGTERM
  (``signals.py``), divergence / error handling, ``summary.json``
  (:mod:`granular_mpc.analysis.summary`), plots and the standalone HTML page.

Sweeps (``sweep.py``): :func:`run_sweep` runs many scenarios on a process pool
(:mod:`granular_mpc.parallel`) or Ray (``sweep_ray.py``) and writes ``sweep.csv`` and the
CoT plot (``sweep_report.py``). Drop tests hang the trunk on a guide rig (``rig.py``).
``mode: playback`` replays a recorded run's joint references by joint PD (``playback.py``).

Every name below stays importable from ``granular_mpc.runner``.
"""

from ..analysis.summary import SUMMARY_KEYS, averaging_window, stance_metrics, summarize
from ..columns import HTML_FILE, LOG_DIR, PLOTS_DIR, RESOLVED_FILE, SUMMARY_FILE
from .build import PushWindow, Simulation, build_simulation
from .loop import check_fall, closed_loop, trunk_roll_pitch
from .playback import JointPlayback, JointReference
from .run import RunResult, run_scenario
from .rundir import default_out_dir, prepare_out_dir, write_resolved_config
from .state import FallEvent, LoopState
from .sweep import SweepResult, run_sweep, sweep_task
from .sweep_report import sweep_plot, sweep_table

__all__ = ["Simulation", "LoopState", "FallEvent", "PushWindow", "RunResult", "SUMMARY_KEYS",
           "build_simulation", "closed_loop", "check_fall", "trunk_roll_pitch", "summarize",
           "stance_metrics", "averaging_window", "run_scenario", "default_out_dir",
           "prepare_out_dir", "write_resolved_config", "SweepResult", "run_sweep",
           "sweep_task", "sweep_table", "sweep_plot", "JointPlayback", "JointReference",
           "LOG_DIR", "PLOTS_DIR", "SUMMARY_FILE", "RESOLVED_FILE", "HTML_FILE"]
