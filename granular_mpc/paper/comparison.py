"""One call that regenerates the paper comparison: runs, figures, ``paper_comparison.md``."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from ..config import load_terrain
from ..output import make_output_folder
from .claims import ClaimBuilder, ClaimRow
from .gaps import load_gaps
from .figures import plot_cot_speed, plot_stance_curves
from .measures import first_touchdown_on, stance_curves
from .model_check import ModelCheck, model_check
from .runs import FIG6_SPEED, RIGID, SAND, PaperRuns, RunPlan, run_all
from .table import write_comparison


@dataclass(frozen=True)
class PaperComparison:
    """What :func:`paper_comparison` wrote.

    Attributes:
        out_dir: the comparison folder.
        table: ``out_dir/paper_comparison.md``.
        rows: the claims, in table order.
        figures: the figure files.
        runs: where the runs are.
        model: the model comparison (both replays).
        wall_time_s: wall-clock time of the whole comparison [s].
    """

    out_dir: Path
    table: Path
    rows: tuple[ClaimRow, ...]
    figures: tuple[Path, ...]
    runs: PaperRuns
    model: ModelCheck
    wall_time_s: float

    def row(self, key: str) -> ClaimRow:
        """The row with ``key`` (KeyError if none)."""
        for r in self.rows:
            if r.key == key:
                return r
        raise KeyError(key)


def paper_comparison(out_dir: str | Path, *, quick: bool = False,
                     workers: int | None = None, overwrite: bool = False,
                     gaps: str | Path | None = None) -> PaperComparison:
    """Run what the paper comparison needs and write ``out_dir/paper_comparison.md``.

    Runs (``granular_mpc.paper.runs``): the speed sweep ``sim/paper_sweep.yaml`` (rigid-
    ground controller, paper gait + 39 ms load transfer, 0.1–0.5 m/s, sand and rigid), the
    paper's protocol on the track ``sim/paper_protocol.yaml`` (exactly, and with the 39 ms
    variant), and a data set synthesized from the sweep's sand scenario, replayed by the
    granular and the rigid-ground model. Then one table row per claim of the paper, and the
    figures ``figures/cot_vs_speed.png``, ``figures/stance_cot.png``,
    ``figures/dtheta_r.png``.

    Args:
        out_dir: the comparison folder (created if absent).
        overwrite: replace the runs of an earlier comparison in ``out_dir`` (without it,
            an earlier comparison there is an OutputError, nothing is replaced).
        quick: shortened runs (about a minute; for tests): every row is still produced,
            the protocol column says ``quick``.
        workers: processes for the runs and replays (default: all cores).
        gaps: the ablation figures (``bench/paper_gaps.py --json``) that the reasons of
            the rows differing from the paper cite; default: the ones measured on the
            submitted code (:data:`granular_mpc.paper.gaps.DEFAULT_GAPS`).

    Returns:
        :class:`PaperComparison`.

    Raises:
        OutputError: the folder cannot be written.
        ConfigError: a shipped scenario does not load.
    """
    t0 = time.perf_counter()
    out = make_output_folder(out_dir)
    runs = run_all(out, RunPlan.make(quick), workers=workers, overwrite=overwrite)
    return tabulate(runs, workers=workers, t0=t0, gaps=gaps)


def tabulate(runs: PaperRuns, *, workers: int | None = None,
             t0: float | None = None, gaps: str | Path | None = None) -> PaperComparison:
    """The table and figures of runs already made by :func:`paper_comparison` (the two
    replays are redone; the closed-loop runs are read from ``runs.out_dir``).

    Args:
        runs: where the runs are (``PaperRuns(out_dir, RunPlan.make(quick))``).
        workers: processes for the replays.
        t0: ``time.perf_counter()`` at the start, for the wall time in the table.
        gaps: see :func:`paper_comparison`.
    """
    t0 = time.perf_counter() if t0 is None else t0
    out, plan = runs.out_dir, runs.plan
    speeds = plan.speeds
    curves = {(t, v): stance_curves(runs.sweep_run(t, v))
              for t in (SAND, RIGID) for v in speeds}
    model = model_check(runs.dataset_dir, out, workers=workers)
    x_edge = load_terrain("paper_track").edges[0]
    builder = ClaimBuilder(runs, curves, model, x_edge,
                           first_touchdown_on(runs.track_run("exact"), x_edge),
                           load_gaps(gaps))
    rows = tuple(builder.rows())
    fig_dir = out / "figures"
    figs = (
        plot_cot_speed({t: [builder.cot(t, v) for v in speeds] for t in (SAND, RIGID)}, speeds,
                       fig_dir / "cot_vs_speed.png"),
        plot_stance_curves({f"{t} {FIG6_SPEED:g} m/s": curves[(t, FIG6_SPEED)]
                            for t in (SAND, RIGID)}, fig_dir / "stance_cot.png", what="cot"),
        plot_stance_curves({f"{t} {v:g} m/s": curves[(t, v)]
                            for t in (SAND, RIGID) for v in (FIG6_SPEED, speeds[-1])},
                           fig_dir / "dtheta_r.png", what="dtheta"),
    )
    wall = time.perf_counter() - t0
    table = write_comparison(out, rows, figs, quick=plan.quick, wall_time_s=wall)
    return PaperComparison(out, table, rows, figs, runs, model, wall)


__all__ = ["PaperComparison", "paper_comparison", "tabulate"]
