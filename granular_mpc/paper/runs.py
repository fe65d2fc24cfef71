"""The runs behind the paper comparison: what is run, with which protocol, and where.

Three groups, each through the package's public entry points:

* **speed sweep** (``sim/paper_sweep.yaml``, :func:`granular_mpc.runner.run_sweep`): the
  rigid-ground controller with the paper's gait plus the measured 39 ms load-transfer
  double support, 0.1–0.5 m/s, on dry sand and on rigid ground → ``OUT/sweep/``;
* **track** (``sim/paper_protocol.yaml``): the paper's protocol exactly (rigid platform,
  then sand; no double support) and the same with the 39 ms variant → ``OUT/track/``;
* **data set** (:func:`granular_mpc.validation.synth.synthesize`): stances of the sweep's
  sand scenario, for the model comparison → ``OUT/dataset/``.

``quick`` shortens everything (fewer speeds, seconds, stances) so that the whole
comparison runs in about a minute; the protocol column of the table says ``quick``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..paths import sim_dir
from ..runner import run_sweep
from ..scenario import SweepTask, expand_sweep, load_scenario
from ..validation.synth import synthesize

#: the paper's speeds [m/s] (Sec. III-B) and the speed of its Figs. 4 and 6a–c
PAPER_SPEEDS = (0.1, 0.2, 0.3, 0.4, 0.5)
FIG6_SPEED = 0.2
#: the measured touchdown double support that lets the rigid controller walk on sand [s]
#: (docs/paper-experiment-notes.md, row ``rigid_transfer``)
LOAD_TRANSFER_S = 0.039
SAND, RIGID, TRACK = "dry_sand", "rigid", "paper_track"


@dataclass(frozen=True)
class RunPlan:
    """Sizes of the runs (full or quick).

    Attributes:
        quick: the shortened form (for tests).
        speeds: sweep speeds [m/s].
        sweep_duration: seconds per sweep run.
        sweep_overrides: extra scenario overrides of every sweep run.
        track_duration: seconds per track run.
        track_overrides: extra overrides of the track runs.
        synth_speeds: speeds of the model-comparison data set [m/s].
        synth_steps: stances recorded per data-set trial.
    """

    quick: bool
    speeds: tuple[float, ...]
    sweep_duration: float
    sweep_overrides: tuple[str, ...]
    track_duration: float
    track_overrides: tuple[str, ...]
    synth_speeds: tuple[float, ...]
    synth_steps: int

    @classmethod
    def make(cls, quick: bool) -> "RunPlan":
        if quick:
            return cls(True, (0.1, 0.2, 0.5), 3.0,
                       ("metrics.settle=0.2", "command.max_acceleration=1.0"), 5.0,
                       ("command.start_delay=0.8",), (FIG6_SPEED,), 3)
        return cls(False, PAPER_SPEEDS, 12.0, (), 12.0, (), PAPER_SPEEDS, 10)

    @property
    def label(self) -> str:
        """``"quick"`` or ``"full"``, for the protocol column."""
        return "quick" if self.quick else "full"


@dataclass(frozen=True)
class PaperRuns:
    """Where the runs of one comparison are (all under ``out_dir``).

    Attributes:
        out_dir: the comparison folder.
        plan: the run sizes.
        sweep_dir: the speed sweep (``runs/<name>/`` per run).
        track_dir: the track runs (``runs/exact``, ``runs/transfer``).
        dataset_dir: the synthesized data set.
    """

    out_dir: Path
    plan: RunPlan

    @property
    def sweep_dir(self) -> Path:
        return self.out_dir / "sweep"

    @property
    def track_dir(self) -> Path:
        return self.out_dir / "track"

    @property
    def dataset_dir(self) -> Path:
        return self.out_dir / "dataset"

    def sweep_run(self, terrain: str, speed: float) -> Path:
        """Folder of the sweep run on ``terrain`` at ``speed`` [m/s]."""
        return self.sweep_dir / "runs" / f"{terrain}_ctrl-rigid_v{speed:g}"

    def track_run(self, variant: str) -> Path:
        """Folder of the track run ``exact`` (the paper's gait) or ``transfer`` (+39 ms)."""
        return self.track_dir / "runs" / variant

    def rel(self, path: Path) -> str:
        """``path`` relative to the comparison folder (for the table)."""
        return str(Path(path).relative_to(self.out_dir))


def _scenario_file(name: str) -> Path:
    folder = sim_dir()
    if folder is None:  # pragma: no cover - an installed package ships sim/
        raise FileNotFoundError("the shipped scenarios (sim/) are not installed")
    return folder / f"{name}.yaml"


def sweep_tasks(plan: RunPlan) -> list[SweepTask]:
    """The speed sweep's tasks (``sim/paper_sweep.yaml`` at the plan's sizes)."""
    speeds = "[" + ", ".join(f"{v:g}" for v in plan.speeds) + "]"
    overrides = [f"sweep.speeds={speeds}", f"sweep.duration={plan.sweep_duration:g}",
                 *plan.sweep_overrides]
    _, tasks = expand_sweep(_scenario_file("paper_sweep"), overrides)
    return tasks


def track_tasks(plan: RunPlan) -> list[SweepTask]:
    """The two track runs at 0.2 m/s: ``exact`` (the paper's protocol) and ``transfer``."""
    base = [f"sim.duration={plan.track_duration:g}", f"command.speed={FIG6_SPEED:g}",
            "output.plots=false", *plan.track_overrides]
    out = []
    for name, extra in (("exact", []),
                        ("transfer", [f"controller.gait.load_transfer={LOAD_TRANSFER_S:g}"])):
        sc = load_scenario(_scenario_file("paper_protocol"), base + extra)
        params = {"terrain": sc.terrain.name, "controller_terrain": "rigid",
                  "commanded_speed_mps": FIG6_SPEED, "seed": int(sc.sim.seed)}
        out.append(SweepTask(name, params, sc.model_copy(update={"name": f"{sc.name}-{name}"})))
    return out


def dataset_scenario(plan: RunPlan):
    """The sweep's sand scenario (one run's settings) for the synthesized data set."""
    return load_scenario(_scenario_file("paper_sweep"), ["sweep=null", *plan.sweep_overrides])


def run_all(out_dir: Path, plan: RunPlan, *, workers: int | None = None,
            progress: bool = False, overwrite: bool = False) -> PaperRuns:
    """Run the sweep, the track runs and the data set into ``out_dir`` (``overwrite``:
    replace those of an earlier comparison there)."""
    runs = PaperRuns(Path(out_dir), plan)
    run_sweep(sweep_tasks(plan), runs.sweep_dir, workers=workers, progress=progress,
              overwrite=overwrite)
    run_sweep(track_tasks(plan), runs.track_dir, workers=workers, progress=progress,
              overwrite=overwrite)
    synthesize(dataset_scenario(plan), runs.dataset_dir, speeds=list(plan.synth_speeds),
               steps=plan.synth_steps, workers=workers, seed=0, overwrite=overwrite,
               description="paper comparison: rigid-ground controller + 39 ms load "
                           "transfer on dry sand (sim/paper_sweep.yaml)")
    return runs


__all__ = ["RunPlan", "PaperRuns", "PAPER_SPEEDS", "FIG6_SPEED", "LOAD_TRANSFER_S", "SAND",
           "RIGID", "TRACK", "sweep_tasks", "track_tasks", "dataset_scenario", "run_all"]
