"""The ``granular-mpc`` command line (typer).

    granular-mpc run CONFIG [--set key.path=value …] [--out DIR] [--view] [--html]
    granular-mpc sweep CONFIG [--set …] [--out DIR] [--workers N] [--backend local|ray]
    granular-mpc view RUN_DIR [--html PATH]
    granular-mpc synth CONFIG --effect NAME[:k=v,…] --noise PREFIX=STD --seed N --out DATA_DIR
    granular-mpc validate DATA_DIR [--model granular|rigid|planar] [--effect NAME …] --out DIR
    granular-mpc diagnose DATA_DIR --out DIR
    granular-mpc import SOURCE --mapping MAP.yaml --out DATA_DIR
    granular-mpc paper --out DIR [--quick] [--workers N] [--overwrite]
    granular-mpc bench [--json DIR]

Bad input (malformed YAML, a key given twice, unknown key, wrong type, a ``--set`` of a
key that does not exist, a missing robot/terrain/scenario file or data folder, a broken
data set or robot description, a file that is not UTF-8, an effect file that cannot be
imported, an output folder that cannot be written, is locked by another process or holds
results that are not to be replaced) prints **one** message naming the file, key and value
on stderr, without a traceback unless ``--debug``.

Exit codes, the same for every command:

====  ==========================================================================
0     done (a run that fell is done: the fall is its result)
1     failed: a run ended early (plant diverged, controller error), a sweep with
      failed runs, a failing bench script, or an internal error (a bug: please
      report it with ``--debug``)
2     bad input: configuration, command-line value, data set, model file,
      environment variable, output folder
130   interrupted by SIGINT (Ctrl-C); what finished is written
143   interrupted by SIGTERM (``kill``, ``timeout``, a job scheduler); likewise
====  ==========================================================================

See docs/user-guide.md.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import traceback
from pathlib import Path
from typing import Annotated, Any, Iterator, Optional

import typer

from .exceptions import (ConfigError, DataFormatError, GranularMpcError, Interrupted,
                         ModelError, OutputError)

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
EXIT_TERMINATED = 143
"""Exit code after SIGTERM (128 + 15)."""
#: errors that are the user's input, not a failure of the package: exit 2
BAD_INPUT_ERRORS = (ConfigError, DataFormatError, OutputError, ModelError)

app = typer.Typer(
    name="granular-mpc",
    help="Bipedal walking on granular terrain: closed-loop runs, sweeps, replays, validation.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)

# ----------------------------------------------------------------------------- options
SetOpt = Annotated[Optional[list[str]], typer.Option(
    "--set", "-s", metavar="KEY.PATH=VALUE",
    help="Override a scenario key (repeatable); the value is parsed as YAML. "
         "'terrain=NAME' swaps the plant's terrain file, 'controller.terrain=NAME' the "
         "controller's.")]
DebugOpt = Annotated[bool, typer.Option("--debug", help="Show tracebacks.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")]


def _err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


@contextlib.contextmanager
def _errors(debug: bool) -> Iterator[None]:
    """One clear message on stderr and a non-zero exit for every error; traceback only
    with ``--debug``."""
    old_term = _sigterm_interrupts()
    try:
        _check_environment()
        yield
    except typer.Exit:
        raise
    except Interrupted as exc:
        _err(str(exc))
        raise typer.Exit(exc.exit_code) from None
    except KeyboardInterrupt:
        _err("interrupted")
        raise typer.Exit(EXIT_INTERRUPTED) from None
    except BAD_INPUT_ERRORS as exc:
        if debug:
            traceback.print_exc()
        _err(f"error: {exc}")
        raise typer.Exit(EXIT_BAD_INPUT) from None
    except GranularMpcError as exc:
        if debug:
            traceback.print_exc()
        _err(f"error: {exc}")
        raise typer.Exit(EXIT_FAILED) from None
    except Exception as exc:
        if debug:
            traceback.print_exc()
        _err(f"error: unexpected {type(exc).__name__}: {exc}"
             + ("" if debug else " (run again with --debug for the traceback)"))
        raise typer.Exit(EXIT_FAILED) from None
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)


def _raise_interrupted(signum, frame) -> None:
    raise Interrupted(signum)


def _sigterm_interrupts():
    """SIGTERM raises :class:`Interrupted` (like Ctrl-C) while a command runs, so that
    ``finally`` blocks run and the exit code is 143; returns the previous handler."""
    try:
        return signal.signal(signal.SIGTERM, _raise_interrupted)
    except ValueError:       # not the main thread (e.g. a test runner)
        return None


def _check_environment() -> None:
    """The environment variables the package reads, checked before any work.

    Raises:
        ConfigError: ``GRANULAR_MPC_PROXSUITE`` names no ProxSuite build.
    """
    from .control.solvers.proxqp import PROXSUITE_BUILDS

    build = os.environ.get("GRANULAR_MPC_PROXSUITE")
    if build is not None and build not in PROXSUITE_BUILDS:
        raise ConfigError(f"{build!r} is not a ProxSuite build",
                          key="GRANULAR_MPC_PROXSUITE (environment)",
                          value=build, allowed=", ".join(PROXSUITE_BUILDS))


def _exit_code_of(reason: str) -> int:
    """130 or 143 for a run interrupted by SIGINT or SIGTERM."""
    return EXIT_TERMINATED if "SIGTERM" in reason else EXIT_INTERRUPTED


def _fmt(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, dict):
        return ", ".join(f"{k} {_fmt(v)}" for k, v in value.items() if k != "n")
    return str(value)


#: Summary lines printed after a run: (key, label, unit).
_SUMMARY_LINES = (
    ("terrain", "terrain (plant)", ""), ("controller_terrain_model", "controller terrain", ""),
    ("commanded_speed_mps", "commanded speed", "m/s"), ("mean_speed_mps", "mean speed", "m/s"),
    ("sim_time_s", "simulated", "s"), ("wall_time_s", "wall time", "s"),
    ("realtime_factor", "real-time factor", ""), ("fell", "fell", ""),
    ("cot", "CoT", ""), ("cot_decoupled", "CoT decoupled", ""),
    ("sinkage_peak_mm_mean", "peak sinkage (mean)", "mm"), ("slip_mm_mean", "slip (mean)", "mm"),
    ("lateral_drift_m", "lateral drift", "m"), ("max_roll_deg", "max |roll|", "deg"),
    ("max_pitch_deg", "max |pitch|", "deg"), ("mpc_solve_ms", "MPC solve", "ms"),
    ("wbc_solve_ms", "WBC solve", "ms"), ("qp_failures", "QP failures", ""),
    ("complete", "complete", ""), ("reason", "reason", ""),
)


def print_summary(summary: dict, out_dir: Path) -> None:
    """The run's key figures on stdout, one ``label: value unit`` line each."""
    for key, label, unit in _SUMMARY_LINES:
        if key in summary:
            val = _fmt(summary[key])
            print(f"{label + ':':<22}{val}{(' ' + unit) if unit and val != '-' else ''}")
    print(f"{'outputs:':<22}{out_dir}")


# ----------------------------------------------------------------------------- run
@app.command()
def run(
    config: Annotated[str, typer.Argument(help="Scenario YAML (e.g. sim/sand_walk.yaml) or a shipped scenario name.")],
    set_: SetOpt = None,
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Run folder (default runs/<scenario>-<time>).")] = None,
    view: Annotated[bool, typer.Option("--view", help="Live Meshcat view while the run goes (prints the URL).")] = False,
    html: Annotated[bool, typer.Option("--html", help="Also write DIR/animation.html (standalone page).")] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace a previous run in DIR (else refused).")] = False,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Run one closed-loop scenario: DIR/summary.json, config.resolved.yaml, log/, plots/."""
    from .runner import default_out_dir, run_scenario
    from .scenario import load_scenario

    with _errors(debug):
        scenario = load_scenario(config, set_ or [])
        out_dir = out if out is not None else default_out_dir(scenario)
        result = run_scenario(scenario, out_dir, progress=not quiet, html=html, view=view,
                              overwrite=overwrite)
        print_summary(result.summary, result.out_dir)
        if view:
            _err(f"the live view closed with the run; replay it with: granular-mpc view {result.out_dir}")
        if result.interrupted:
            _err(f"run interrupted: {result.reason}; the log so far is in {result.log_dir}")
            raise typer.Exit(_exit_code_of(result.reason))
        if not result.complete:
            _err(f"run ended early: {result.reason}")
            raise typer.Exit(EXIT_FAILED)


# ----------------------------------------------------------------------------- sweep
@app.command()
def sweep(
    config: Annotated[str, typer.Argument(help="Scenario YAML with a 'sweep:' section (e.g. sim/velocity_sweep.yaml).")],
    set_: SetOpt = None,
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Sweep folder (default runs/<scenario>-<time>).")] = None,
    workers: Annotated[Optional[int], typer.Option("--workers", "-j", min=1, help="Parallel runs (default: all cores).")] = None,
    backend: Annotated[str, typer.Option("--backend", help="local (process pool) or ray.")] = "local",
    ray_address: Annotated[Optional[str], typer.Option("--ray-address", help="Join a running Ray cluster (e.g. auto or ray://host:10001).")] = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace a previous sweep in DIR (else refused).")] = False,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Run speeds × terrains (× controller terrains × grid) in parallel: DIR/sweep.csv + CoT plot."""
    from .runner import default_out_dir, run_sweep
    from .scenario import expand_sweep

    with _errors(debug):
        if backend not in ("local", "ray"):
            raise ConfigError(f"unknown backend {backend!r}", key="--backend", allowed="local, ray")
        base, tasks = expand_sweep(config, set_ or [])
        out_dir = out if out is not None else default_out_dir(base)
        print(f"sweep '{base.name}': {len(tasks)} runs, backend {backend}, output {out_dir}",
              flush=True)

        def line(r: dict) -> None:
            s = r["summary"]
            print(f"  {r['name']}: mean speed {_fmt(s.get('mean_speed_mps'))} m/s, "
                  f"CoT {_fmt(s.get('cot'))}, fell {_fmt(s.get('fell'))}"
                  + ("" if s.get("complete") else f", INCOMPLETE ({s.get('reason')})"),
                  flush=True)

        res = run_sweep(tasks, out_dir, workers=workers, backend=backend,
                        ray_address=ray_address, progress=not quiet, on_result=line,
                        overwrite=overwrite)
        print(f"sweep table: {res.csv}")
        if res.plot is not None:
            print(f"CoT plot: {res.plot} ({res.plot_note})")
        else:
            print(f"CoT plot: none ({res.plot_note})")
        print_ratio(res.ratio)
        if res.interrupted:
            _err(f"sweep interrupted by {res.interrupted}: queued runs dropped; sweep.csv "
                 "lists the runs that finished or were stopped (column complete, reason)")
            raise typer.Exit(_exit_code_of(res.interrupted))
        if not res.complete:
            _err("sweep incomplete: some runs were interrupted or failed (see sweep.csv: complete, reason)")
            raise typer.Exit(EXIT_FAILED)


def print_ratio(ratio) -> None:
    """The CoT ratio to rigid ground per speed, as a small table on stdout."""
    if ratio is None or len(ratio) == 0:
        print("CoT ratio to rigid ground: no pairs (needs runs on 'rigid' and another terrain "
              "at the same speed, with a finite CoT)")
        return
    print("CoT ratio to rigid ground per commanded speed:")
    print(f"  {'series':<34}{'speed [m/s]':>12}{'CoT ratio':>12}")
    for r in ratio.itertuples(index=False):
        print(f"  {str(r.series):<34}{r.commanded_speed_mps:>12.3g}{r.cot_ratio:>12.3f}")


# ----------------------------------------------------------------------------- view
@app.command()
def view(
    run_dir: Annotated[Path, typer.Argument(help="A run folder written by 'granular-mpc run'.")],
    html: Annotated[Optional[Path], typer.Option("--html", help="Write the standalone page here instead of serving it live.")] = None,
    fps: Annotated[float, typer.Option("--fps", min=1.0, help="Animation frame rate.")] = 30.0,
    debug: DebugOpt = False,
) -> None:
    """Replay a saved run: live in Meshcat (until Ctrl-C), or as one HTML page with --html."""
    from .viz.meshcat import replay

    with _errors(debug):
        if not run_dir.is_dir():
            raise OutputError(f"no run folder {run_dir}")
        out = replay(run_dir, html, fps=fps)
        if html is not None:
            print(f"wrote {out}")


# ----------------------------------------------------------------------------- bench
def _bench_dir(given: Optional[Path]) -> Path | None:
    if given is not None:
        return given
    for cand in (Path.cwd() / "bench", Path(__file__).resolve().parent.parent / "bench"):
        if cand.is_dir():
            return cand
    return None


@app.command()
def bench(
    json_dir: Annotated[Optional[Path], typer.Option("--json", help="Also write each script's figures to DIR/<script>.json.")] = None,
    bench_dir: Annotated[Optional[Path], typer.Option("--dir", help="Folder of the bench scripts (default ./bench).")] = None,
    debug: DebugOpt = False,
) -> None:
    """Run the bench/*.py scripts and print their 'name: value unit' lines."""
    with _errors(debug):
        folder = _bench_dir(bench_dir)
        scripts = sorted(folder.glob("*.py")) if folder is not None and folder.is_dir() else []
        scripts = [s for s in scripts if not s.name.startswith("_")]
        if not scripts:
            print(f"no benchmark scripts (bench/*.py) found{f' in {folder}' if folder else ''}")
            return
        if json_dir is not None:
            try:
                json_dir.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise OutputError(f"cannot write {json_dir}: {exc.strerror or exc}") from None
        failed = []
        for script in scripts:
            cmd = [sys.executable, str(script)]
            if json_dir is not None:
                cmd += ["--json", str(json_dir / f"{script.stem}.json")]
            print(f"# {script.name}", flush=True)
            proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            for ln in proc.stdout.splitlines():
                if ln.strip():
                    print(ln, flush=True)
            if proc.returncode != 0:
                failed.append(script.name)
                tail = "\n".join(proc.stderr.strip().splitlines()[-5:])
                _err(f"error: {script.name} exited with code {proc.returncode}"
                     + (f":\n{tail}" if tail else ""))
        if failed:
            raise typer.Exit(EXIT_FAILED)


# ----------------------------------------------------------------------------- workbench
def _parse_noise(items: list[str]) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in items:
        key, eq, val = item.partition("=")
        if not eq or not key.strip():
            raise ConfigError(f"{item!r} must look like COLUMN_OR_PREFIX=STD (e.g. grf_=0.5)",
                              key="--noise")
        try:
            out[key.strip()] = float(val)
        except ValueError:
            raise ConfigError(f"{item!r}: the standard deviation must be a number",
                              key="--noise") from None
        if out[key.strip()] < 0:
            raise ConfigError(f"{item!r}: the standard deviation must be ≥ 0", key="--noise")
    return out


def _effects(items: list[str]):
    from .config import EffectSpec, validate
    from .effects import effect_info

    specs = [validate(EffectSpec, e, source=f"--effect {e}") for e in items]
    for s in specs:
        effect_info(s.name)  # unknown name → one clear error listing the registered ones
    return specs


def _load_effect_files(files: list[Path] | None) -> list[str]:
    from .effects import load_effect_file

    names: list[str] = []
    for f in files or []:
        if f.suffix != ".py":
            raise ConfigError(f"{f}: an effect file must be a Python file (*.py)",
                              key="--effect-file", value=str(f))
        try:
            names += load_effect_file(str(f))
        except GranularMpcError:
            raise
        except Exception as exc:        # the user's code raised while it was imported
            raise ConfigError(f"{f} raised {type(exc).__name__} while it was imported: {exc}",
                              key="--effect-file", value=str(f)) from exc
    return names


def _speeds(items: list[str] | None) -> list[float] | None:
    if not items:
        return None
    out = []
    for item in items:
        for part in filter(None, (p.strip() for p in item.split(","))):
            try:
                out.append(float(part))
            except ValueError:
                raise ConfigError(f"speed {part!r} is not a number", key="--speeds") from None
    return out


EffectOpt = Annotated[Optional[list[str]], typer.Option(
    "--effect", "-e", metavar="NAME[:k=v,…]", help="A registered physical effect of any kind "
    "(terrain force, joint, sensor, geometry; repeatable).")]
EffectFileOpt = Annotated[Optional[list[Path]], typer.Option(
    "--effect-file", metavar="FILE.py", help="Python file registering user effects (repeatable).")]
TerrainOpt = Annotated[str, typer.Option("--terrain", help="The model's terrain (name in models/terrain or a path).")]
WorkersOpt = Annotated[Optional[int], typer.Option("--workers", min=1, help="Processes for the replays (default: all CPUs).")]
ReplaySegmentsOpt = Annotated[int, typer.Option(
    "--replay-segments",
    help="Replays per stance: the stance is replayed again from the measured state "
         "mid-stance (multiple shooting; needs measured intrusion; docs/validation.md "
         "§5.3.14).")]


@app.command()
def synth(
    config: Annotated[str, typer.Argument(help="Scenario YAML the plant is built from.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Data set folder to write (format v1).")],
    effect: EffectOpt = None,
    noise: Annotated[Optional[list[str]], typer.Option("--noise", metavar="PREFIX=STD", help="Gaussian noise std. dev. per column or column prefix, column units (repeatable), e.g. grf_=0.5; 'level=L' scales the realistic sensor model (default level=1; level=0: none).")] = None,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed (default: the scenario's sim.seed).")] = None,
    speeds: Annotated[Optional[list[str]], typer.Option("--speeds", metavar="V[,V…]", help="Commanded speeds [m/s], one trial each (default: the scenario's).")] = None,
    steps: Annotated[Optional[int], typer.Option("--steps", help="Stance phases recorded per trial (default 10).")] = None,
    duration: Annotated[Optional[float], typer.Option("--duration", help="Recorded seconds per trial (instead of --steps).")] = None,
    repeats: Annotated[int, typer.Option("--repeats", help="Trials per speed.")] = 1,
    fmt: Annotated[str, typer.Option("--format", help="csv or parquet.")] = "csv",
    effect_file: EffectFileOpt = None,
    set_: SetOpt = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace a synthetic data set in DATA_DIR (measured data is never replaced).")] = False,
    debug: DebugOpt = False,
) -> None:
    """Generate a measurement data set with the plant (+ hidden effects, sensor noise)."""
    from .scenario import find_scenario, load_scenario
    from .validation.synth import synthesize

    with _errors(debug):
        _load_effect_files(effect_file)
        scenario = load_scenario(config, set_ or [])
        res = synthesize(scenario, out, effects=_effects(effect or []),
                         noise=_parse_noise(noise or []),
                         seed=scenario.sim.seed if seed is None else seed,
                         scenario_path=find_scenario(config), speeds=_speeds(speeds),
                         steps=steps, duration=duration, repeats=repeats, format=fmt,
                         overwrite=overwrite)
        for note in res.notes:
            _err(f"note: {note}")
        print(f"wrote {out}")


@app.command()
def validate(
    data_dir: Annotated[Path, typer.Argument(help="Measurement data set folder (format v1).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Report folder (report.json + figures).")],
    model: Annotated[str, typer.Option("--model", help="granular, rigid or planar.")] = "granular",
    effect: EffectOpt = None,
    params: Annotated[Optional[Path], typer.Option("--params", help="diagnosis.json (or its folder) with calibrated and fitted parameters.")] = None,
    terrain: TerrainOpt = "dry_sand",
    effect_file: EffectFileOpt = None,
    replay_segments: ReplaySegmentsOpt = 1,
    workers: WorkersOpt = None,
    debug: DebugOpt = False,
) -> None:
    """Compare the model with measurements: DIR/report.json (RMSE by channel, phase, speed)."""
    from .validation.replay import validate as run_validate

    with _errors(debug):
        if model not in ("granular", "rigid", "planar"):
            raise ConfigError(f"unknown model {model!r}", key="--model",
                              allowed="granular, rigid, planar")
        _load_effect_files(effect_file)
        rep = run_validate(data_dir, out, model=model, effects=_effects(effect or []),
                           params=params, terrain=terrain, workers=workers,
                           replay_segments=replay_segments)
        for ch, d in rep.report.get("before_after", {}).items():
            if d["change_pct"] is not None:
                print(f"{ch}: RMSE {d['before']:.4g} -> {d['after']:.4g} "
                      f"({d['change_pct']:+.0f} %)")
        print(f"wrote {out / 'report.json'}")


@app.command()
def diagnose(
    data_dir: Annotated[Path, typer.Argument(help="Measurement data set folder (format v1).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for diagnosis.json + report.md + figures.")],
    candidate: Annotated[Optional[list[str]], typer.Option("--candidate", metavar="NAME", help="Candidate effect to test (repeatable; default: every registered effect).")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Bootstrap seed.")] = 0,
    terrain: TerrainOpt = "dry_sand",
    effect_file: EffectFileOpt = None,
    measurement: Annotated[bool, typer.Option("--measurement", help="Also test the measurement model: per-joint torque gain/offset, encoder offsets and gains, force-sensor gain, torque time offset, trunk attitude bias (granular_mpc.effects.measurement).")] = False,
    variants: Annotated[bool, typer.Option("--variants", help="Also test per-foot and layered variants of the terrain law: stress_scale_left/right (one foot's track of other sand, a worn sole), stress_scale, hard_layer (granular_mpc.effects.variants).")] = False,
    replay_segments: ReplaySegmentsOpt = 1,
    workers: WorkersOpt = None,
    debug: DebugOpt = False,
) -> None:
    """Calibrate the model, then find which physical effect it misses: DIR/diagnosis.json."""
    from .validation.diagnose import diagnose as run_diagnose

    with _errors(debug):
        if measurement:
            from .effects.measurement import register_measurement
            register_measurement()
        if variants:
            from .effects.variants import register_variants
            register_variants()
        _load_effect_files(effect_file)
        if candidate:
            for c in candidate:
                _effects([c])
        res = run_diagnose(data_dir, out, candidates=candidate or None, seed=seed,
                           terrain=terrain, workers=workers, replay_segments=replay_segments)
        print(res.verdict.text)
        print(f"wrote {out / 'diagnosis.json'}")


@app.command("import")
def import_(
    source: Annotated[Path, typer.Argument(help="A ROS 2 bag folder (sqlite3 or MCAP), or a folder / file of CSV or Parquet streams.")],
    mapping: Annotated[Path, typer.Option("--mapping", "-m", help="Mapping file: topic/column -> channel, units, frames, clocks (docs/import.md).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Data set folder to write (format v1 with declared channels).")],
    format: Annotated[str, typer.Option("--format", help="Trial file format: csv or parquet.")] = "csv",
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace a data set this command wrote before.")] = False,
    debug: DebugOpt = False,
) -> None:
    """Import a lab log into a checked data set: DATA_DIR/meta.yaml + one file per trial."""
    from .importers import import_log
    from .validation.dataformat import load_dataset

    with _errors(debug):
        if format not in ("csv", "parquet"):
            raise ConfigError(f"unknown format {format!r}", key="--format", value=format,
                              allowed="csv, parquet")
        res = import_log(source, mapping, out, format=format, overwrite=overwrite)
        print(load_dataset(res.path).channel_report())
        print(f"wrote {res.path}")


@app.command("drop-channels")
def drop_channels_(
    data_dir: Annotated[Path, typer.Argument(help="Data set to copy.")],
    groups: Annotated[list[str], typer.Argument(help="Channel groups to remove (intrusion, foot_force, trunk_position, …).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder of the copy.")],
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace a data set there.")] = False,
    debug: DebugOpt = False,
) -> None:
    """Copy a data set without some channel groups (what a lab without those sensors has)."""
    from .validation.dataformat import load_dataset
    from .validation.dataformat.drop import drop_channels

    with _errors(debug):
        path = drop_channels(data_dir, out, groups, overwrite=overwrite)
        print(load_dataset(path).channel_report())
        print(f"wrote {path}")


@app.command()
def merge(
    sources: Annotated[list[Path], typer.Argument(help="Two or more data sets of the same experiment (robot, rate, channels, ground).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder of the merged data set.")],
    terrain: Annotated[Optional[str], typer.Option("--terrain", help="Ground description of the merged set, when the sources' descriptions differ.")] = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace a data set there.")] = False,
    debug: DebugOpt = False,
) -> None:
    """Merge the trials of several data sets into one (e.g. one imported log per trial)."""
    from .validation.dataformat import load_dataset
    from .validation.dataformat.merge import merge_datasets

    with _errors(debug):
        path = merge_datasets(sources, out, terrain=terrain, overwrite=overwrite)
        print(load_dataset(path).channel_report())
        print(f"wrote {path}")


@app.command()
def paper(
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for paper_comparison.md, its figures and the runs.")],
    quick: Annotated[bool, typer.Option("--quick", help="Fewer, shorter runs (every row still filled; for tests).")] = False,
    workers: WorkersOpt = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace the runs of an earlier comparison in DIR.")] = False,
    gaps: Annotated[Optional[Path], typer.Option("--gaps", help="Ablation figures (bench/paper_gaps.py --json) for the reasons; default: the shipped ones.")] = None,
    debug: DebugOpt = False,
) -> None:
    """Regenerate the comparison with the paper: DIR/paper_comparison.md (docs/paper.md)."""
    from .paper import paper_comparison

    with _errors(debug):
        res = paper_comparison(out, quick=quick, workers=workers, overwrite=overwrite,
                               gaps=gaps)
        print(f"{len(res.rows)} claims compared in {res.wall_time_s:.0f} s")
        print(f"wrote {res.table}")


def main() -> None:
    """Console entry point (``granular-mpc``)."""
    app(prog_name="granular-mpc")


if __name__ == "__main__":
    main()
