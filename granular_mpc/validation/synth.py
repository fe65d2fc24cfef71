"""Synthetic measurement data (format v1) from closed-loop walking of the plant.

``synthesize`` walks the plant with the walking controller at one or more commanded
speeds, optionally with **hidden effects** in the plant (the controller never sees them),
adds realistic **sensor noise**, and writes a data set in measurement format v1
(``docs/data-format.md``) whose ``meta.yaml`` records, under ``generator``, the scenario,
the seed, the effects *with all their true parameter values*, the noise and the true
terrain parameters — for tests that check what the workbench recovers. The workbench
(``validate`` / ``diagnose``) never reads the ``generator`` block.

Effects dispatch by kind (:mod:`granular_mpc.effects`):

* ``terrain_force``: compiled into the plant's terrain (``extra_effects``);
* ``joint``: the plant's joint-effect hook (``Plant.joint_effects``);
* ``geometry``: terrain parameters of the plant (e.g. its surface slope);
* ``sensor``: applied to the recorded columns before the noise.

**Stance labels** (``stance`` column): the *leading* foot — among the feet in contact,
the one that touched down last; ``none`` when no foot touches. A stance phase therefore
runs from the foot's touchdown (it includes the loading and sinking while the other foot
still carries weight) to the other foot's touchdown. ``grf_*`` and ``intrusion_*`` are
that foot's force and intrusion; contacts shorter than 20 samples (40 ms at 500 Hz: a
scuff of the swing foot) are ignored and a foot off the ground for at most 10 samples has
bounced, not lifted off.

**Noise**: the realistic sensor-noise model and per-column white noise of
:mod:`.sensor_noise` (``NOISE_MODEL``, ``add_noise``, ``normalise_noise`` are re-exported
here).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from ..columns import (BASE_COLUMNS, FOOT_SIDES, GRF_COLUMNS, INTRUSION_COLUMNS, JOINT_KINDS,
                       STANCE, TIME, foot_column, format_columns, joint_columns)
from ..config import EffectSpec, ScenarioConfig, validate
from ..control.gait import CommandRamp
from ..dynamics import Plant
from ..effects import (SensorContext, apply_sensor_effects, effect_info, geometry_theta,
                       joint_torque_function)
from ..exceptions import ConfigError, GranularMpcError
from ..parallel import map_tasks
from ..runner import build_simulation, closed_loop
from ..runner.build import stepping_plant
from ..scenario import find_scenario, load_scenario, resolved_dict, scenario_from_dict
from ..terrain import build_terrain
from .dataformat import check_trials, load_dataset, write_dataset
from .dataset_target import DatasetTarget, dataset_target
from .sensor_noise import NOISE_MODEL, add_noise, check_noise_prefixes, normalise_noise

#: contacts shorter than this many samples (a scuff of the swing foot) do not start a
#: stance phase
MIN_CONTACT_SAMPLES = 20
#: a foot off the ground for at most this many samples has bounced, not lifted off
MAX_BOUNCE_SAMPLES = 10


@dataclass(frozen=True)
class SynthResult:
    """What :func:`synthesize` wrote.

    Attributes:
        path: the data set folder.
        trials: trial name → commanded speed [m/s].
        n_stances: complete stance phases per trial.
        notes: remarks (falls, shortened trials).
        wall_time_s: time taken.
    """

    path: Path
    trials: dict
    n_stances: dict
    notes: tuple
    wall_time_s: float


# ----------------------------------------------------------------------------- helpers
def _scenario(scenario_or_name: ScenarioConfig | str | Path, overrides: Sequence[str]):
    if isinstance(scenario_or_name, ScenarioConfig):
        sc = scenario_or_name
        if overrides:
            sc = scenario_from_dict(resolved_dict(sc), list(overrides))
        return sc, None
    path = find_scenario(scenario_or_name)
    return load_scenario(str(path), list(overrides)), path


def _specs(effects: Sequence[Any]) -> list[EffectSpec]:
    out = []
    for e in effects or ():
        spec = e if isinstance(e, EffectSpec) else validate(EffectSpec, e, source="effect")
        effect_info(spec.name)           # unknown names: one clear error
        out.append(spec)
    return out


def resolve_effects(effects: Sequence[Any]) -> list[tuple[Any, dict[str, float]]]:
    """(EffectInfo, all parameter values) per effect spec (name string, mapping or spec)."""
    out = []
    for spec in _specs(effects):
        info = effect_info(spec.name)
        out.append((info, info.resolve_params(spec.params)))
    return out


def build_plant_simulation(scenario: ScenarioConfig, effects: Sequence[Any] = ()):
    """The closed-loop :class:`~granular_mpc.runner.Simulation` of ``scenario`` whose plant
    carries ``effects`` (any kind but ``sensor``); the controller never sees them.

    Terrain-force effects are compiled into the plant terrain, geometry effects set its
    terrain parameters, joint effects go to the plant's joint-effect hook.
    """
    resolved = resolve_effects(effects)
    terrain_specs = [EffectSpec(name=i.name, params=p) for i, p in resolved
                     if i.kind == "terrain_force"]
    geom = geometry_theta(resolved)
    joint_fn = joint_torque_function(resolved)
    if not terrain_specs and not geom and joint_fn is None:
        return build_simulation(scenario)
    # the plant is replaced below: build the rest without compiling a plant for nothing
    ref_sim = scenario.sim.model_copy(update={"plant": "reference"})
    sim = replace(build_simulation(scenario.model_copy(update={"sim": ref_sim})),
                  scenario=scenario)
    cfg = scenario.terrain
    if geom:
        upd: dict[str, Any] = {}
        slope = list(cfg.surface_slope)
        for k, v in geom.items():
            if k == "surface_slope_x":
                slope[0] = v
            elif k == "surface_slope_y":
                slope[1] = v
            else:
                upd[k] = v
        upd["surface_slope"] = slope
        cfg = cfg.model_copy(update=upd)
    terrain = build_terrain(cfg, scenario.robot, extra_effects=terrain_specs)
    plant, choice = stepping_plant(Plant(sim.biped, terrain, scenario.sim,
                                         joint_effects=() if joint_fn is None else (joint_fn,)),
                                   scenario)
    return replace(sim, plant=plant, plant_choice=choice)


def _runs_of(c: np.ndarray) -> list[tuple[int, int]]:
    m = np.concatenate(([False], c, [False])).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def leading_foot_labels(left: np.ndarray, right: np.ndarray,
                        min_samples: int = MIN_CONTACT_SAMPLES,
                        max_gap: int = MAX_BOUNCE_SAMPLES) -> np.ndarray:
    """Stance labels from per-foot contact flags: the foot in contact that touched down
    last (``left`` / ``right``), ``none`` when neither touches. A foot that leaves the
    ground for at most ``max_gap`` samples (a bounce) counts as in contact; contact runs
    shorter than ``min_samples`` are ignored."""
    flags = []
    for c in (np.asarray(left) > 0.5, np.asarray(right) > 0.5):
        c = c.copy()
        gaps = _runs_of(~c)
        for a, b in gaps:
            if 0 < a and b < len(c) and b - a <= max_gap:
                c[a:b] = True
        for a, b in _runs_of(c):
            if b - a < min_samples:
                c[a:b] = False
        flags.append(c)
    n = len(flags[0])
    last = [-1, -1]
    prev = [False, False]
    out = np.empty(n, dtype=object)
    for k in range(n):
        for i in range(2):
            if flags[i][k] and not prev[i]:
                last[i] = k
            prev[i] = bool(flags[i][k])
        if flags[0][k] and flags[1][k]:
            out[k] = "left" if last[0] >= last[1] else "right"
        elif flags[0][k]:
            out[k] = "left"
        elif flags[1][k]:
            out[k] = "right"
        else:
            out[k] = "none"
    return out


def _v1_frame(rows: list[dict], joint_names: Sequence[str]) -> pd.DataFrame:
    """Format-v1 columns (leading-foot stance labels) from closed-loop log rows."""
    log = pd.DataFrame.from_records(rows)
    labels = leading_foot_labels(*(log[foot_column(side, "contact")].to_numpy()
                                   for side in FOOT_SIDES))
    out = pd.DataFrame({TIME: log[TIME].to_numpy(dtype=float), STANCE: labels})
    for j in joint_names:
        for kind in JOINT_KINDS:
            col = joint_columns([j], kind)[0]
            out[col] = log[col].to_numpy(dtype=float)
    for c in BASE_COLUMNS:
        out[c] = log[c].to_numpy(dtype=float)
    for col in GRF_COLUMNS + INTRUSION_COLUMNS:
        val = np.zeros(len(log))
        for side in FOOT_SIDES:
            m = labels == side
            val[m] = log[foot_column(side, col)].to_numpy(dtype=float)[m]
        out[col] = val
    return out[format_columns(joint_names)]


def _count_stances(labels: np.ndarray) -> int:
    labels = np.asarray(labels).astype(str)
    runs = 0
    for k in range(1, len(labels)):
        if labels[k] != labels[k - 1] and labels[k] != "none":
            runs += 1
    # the first and the last run are incomplete
    return max(runs - 1, 0)


# ----------------------------------------------------------------------------- one trial
def _run_trial(payload: Mapping[str, Any]) -> dict:
    """Closed-loop walking of one trial (in a worker process). Returns the v1 frame."""
    sc: ScenarioConfig = payload["scenario"]
    with threadpool_limits(limits=1):
        sim = build_plant_simulation(sc, payload["effects"])
        state = sim.new_state()
        warmup = payload["warmup"]
        rows = []
        try:
            for row in closed_loop(sim, state):
                rows.append(row)
        except GranularMpcError as exc:       # keep what was recorded before the failure
            note = f"{payload['name']}: run ended early ({type(exc).__name__}: {exc})"
        else:
            note = ""
    fell_at = state.fall.time if state.fall is not None else None
    t = np.array([r[TIME] for r in rows])
    t_end = t[-1] if len(t) else 0.0
    if fell_at is not None:
        t_end = fell_at - 0.5
        note = f"{payload['name']}: fell at t = {fell_at:.2f} s ({state.fall.reason}); " \
               "kept the data up to 0.5 s before"
    period = 1.0 / sc.log_rate_hz
    keep = [r for r in rows if warmup - 1e-9 <= r[TIME] <= t_end + 1e-9
            and abs(r[TIME] / period - round(r[TIME] / period)) < 1e-3]   # log grid only
    frame = _v1_frame(keep, sim.biped.joint_names) if len(keep) > 2 else None
    if frame is not None:
        frame[TIME] = frame[TIME] - frame[TIME].iloc[0]
    return {"name": payload["name"], "frame": frame, "note": note, "warmup": warmup,
            "joint_names": list(sim.biped.joint_names)}


def torque_hold(sc: ScenarioConfig) -> float | None:
    """How long each logged torque is held after its stamp [s] (``meta.yaml``'s
    ``torque_hold_s``): the controller's period when every log row falls on a controller
    tick (the row then logs the command just set, held until the next tick); None
    otherwise (rows between ticks log a command set earlier)."""
    ratio = sc.controller.wbc.rate_hz / sc.log_rate_hz
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        return None
    return 1.0 / sc.controller.wbc.rate_hz


# ----------------------------------------------------------------------------- public
def synthesize(scenario_or_name: ScenarioConfig | str | Path, out_dir: str | Path, *,
               speeds: Sequence[float] | None = None, steps: int | None = None,
               duration: float | None = None, repeats: int = 1, seed: int = 0,
               effects: Sequence[Any] = (), noise: float | Mapping[str, float] | None = 1.0,
               format: str = "csv", overrides: Sequence[str] = (),
               scenario_path: str | Path | None = None, warmup: float | None = None,
               settle: float = 0.4, workers: int | None = None,
               description: str = "", overwrite: bool = False) -> SynthResult:
    """Generate a measurement data set (format v1) by closed-loop walking of the plant.

    The output folder must be new, empty, or hold a synthetic data set (``meta.yaml``
    with a ``generator`` section) — which is replaced only with ``overwrite``. Measured
    data (a ``meta.yaml`` without ``generator``) is never replaced, and a non-empty
    folder without ``meta.yaml`` is refused (:func:`dataset_target`). The folder is
    checked and locked before any trial runs.

    Args:
        scenario_or_name: a loaded scenario, or a scenario name / path (``sand_walk``).
        out_dir: data set folder to write.
        speeds: commanded forward speeds [m/s], one trial each (default: the scenario's).
        steps: stance phases to record per trial (≈ 0.2 s each for the paper's gait);
            mutually exclusive with ``duration``. Default: 10.
        duration: recorded seconds per trial (after the warm-up).
        repeats: trials per speed (different seeds).
        seed: seed of everything random (the plant runs, the noise); per trial a child of
            ``numpy.random.SeedSequence(seed)``.
        effects: hidden effects, as ``"name:k=v,…"`` strings, mappings or
            :class:`~granular_mpc.config.EffectSpec` (any kind, see the module docstring).
        noise: level of the realistic noise model (1 = realistic, 0 = none) or a mapping
            (``{"level": 1, "grf_": 0.5}``); see the module docstring.
        format: ``"csv"`` or ``"parquet"``.
        overrides: ``--set`` style scenario overrides (``"terrain.zeta=1.7"``).
        scenario_path: recorded in the meta (default: the resolved scenario file).
        warmup: seconds dropped at the start of every trial (default: the command's start
            delay + speed ramp + ``settle``).
        settle: see ``warmup`` [s].
        workers: processes for the trials (default: min(trials, CPUs)).
        description: free text for the meta.
        overwrite: replace a synthetic data set already in ``out_dir``.

    Returns:
        :class:`SynthResult`.

    Raises:
        ConfigError: bad arguments (steps < 1, a speed outside ``command.speed``'s range,
            a noise prefix that matches no column …).
        OutputError: the folder holds measured data, something that is not a data set,
            a synthetic data set and not ``overwrite``, or another process writes it.
    """
    t_wall = time.perf_counter()
    sc, path = _scenario(scenario_or_name, overrides)
    if sc.mode != "walk":
        raise ConfigError("synth needs a walking scenario", key="mode", value=sc.mode,
                          allowed="walk")
    if steps is not None and duration is not None:
        raise ConfigError("give steps or duration, not both", key="steps")
    if format not in ("csv", "parquet"):
        raise ConfigError(f"unknown format {format!r}", key="format", allowed="csv, parquet")
    if steps is not None and int(steps) < 1:
        raise ConfigError(f"must be at least 1, got {steps}", key="steps", value=steps)
    if duration is not None and not (math.isfinite(float(duration)) and float(duration) > 0):
        raise ConfigError(f"must be a positive number of seconds, got {duration}",
                          key="duration", value=duration)
    if int(repeats) < 1:
        raise ConfigError(f"must be at least 1, got {repeats}", key="repeats", value=repeats)
    specs = _specs(effects)
    resolved = resolve_effects(specs)
    level, white = normalise_noise(noise)
    check_noise_prefixes(white)
    speeds = [float(sc.command.speed)] if speeds is None else [float(v) for v in speeds]
    if not speeds:
        raise ConfigError("no speeds given", key="speeds")
    for v in speeds:    # the range of command.speed (validated, unlike a model_copy)
        validate(type(sc.command), {**sc.command.model_dump(), "speed": v}, source="speeds")
    out = Path(out_dir)
    with DatasetTarget(out, overwrite) as target:
        result = _synthesize(sc, path, target, speeds=speeds, steps=steps, duration=duration,
                             repeats=repeats, seed=seed, specs=specs, resolved=resolved,
                             level=level, white=white, format=format,
                             scenario_path=scenario_path, warmup=warmup, settle=settle,
                             workers=workers, description=description)
    return replace(result, wall_time_s=time.perf_counter() - t_wall)


def _synthesize(sc: ScenarioConfig, path, target: DatasetTarget, *, speeds, steps, duration,
                repeats, seed, specs, resolved, level, white, format, scenario_path, warmup,
                settle, workers, description) -> SynthResult:
    """The body of :func:`synthesize` once the arguments are checked and the folder is
    locked."""
    t_wall = time.perf_counter()
    half_period = 0.5 * sc.controller.gait.period
    if duration is None:
        duration = (10 if steps is None else int(steps)) * half_period + 2.5 * half_period
    children = np.random.SeedSequence(int(seed)).spawn(len(speeds) * int(repeats))
    payloads = []
    k = 0
    for v in speeds:
        command = sc.command.model_copy(update={"speed": v})
        if warmup is None:
            ramp = CommandRamp(command, 1.0 / sc.controller.wbc.rate_hz).ramp_duration
            w = command.start_delay + ramp + settle
        else:
            w = float(warmup)
        for _ in range(int(repeats)):
            run_seed = int(children[k].generate_state(1)[0] % (2 ** 31))
            name = f"trial_{k + 1:03d}"
            scv = sc.model_copy(update={
                "command": command,
                "sim": sc.sim.model_copy(update={"seed": run_seed, "duration": w + duration}),
            })
            payloads.append({"name": name, "scenario": scv, "effects": specs, "speed": v,
                             "warmup": w, "seed": run_seed})
            k += 1
    run = map_tasks(_run_trial, payloads, workers=workers or None)
    if run.interrupted:               # Ctrl-C: nothing is written
        raise KeyboardInterrupt
    results = list(run.results)
    joint_names = results[0]["joint_names"]
    check_noise_prefixes(white, joint_names)
    fs = float(sc.log_rate_hz)
    trials: dict[str, pd.DataFrame] = {}
    entries: dict[str, dict] = {}
    notes: list[str] = []
    n_st: dict[str, int] = {}
    for p, res, child in zip(payloads, results, children):
        if res["note"]:
            notes.append(res["note"])
        frame = res["frame"]
        if frame is None or _count_stances(frame[STANCE].to_numpy()) < 1:
            notes.append(f"{p['name']}: no complete stance recorded; trial dropped")
            continue
        ctx = SensorContext(frame[STANCE].to_numpy().astype(str),
                            frame[TIME].to_numpy(dtype=float), tuple(joint_names))
        cols = {c: frame[c].to_numpy() for c in frame.columns if c != STANCE}
        changed = apply_sensor_effects(cols, resolved, ctx)
        for c, v in changed.items():
            if c in frame.columns and c not in (TIME, STANCE):
                frame[c] = v
        rng = np.random.default_rng(child.spawn(1)[0])
        frame = add_noise(frame, joint_names, level, white, rng, fs)
        trials[p["name"]] = frame
        n_st[p["name"]] = _count_stances(frame[STANCE].to_numpy())
        entries[p["name"]] = {"commanded_speed_mps": p["speed"],
                              "description": f"synthetic, plant seed {p['seed']}"}
    if not trials:
        raise GranularMpcError("synth recorded no usable trial: " + "; ".join(notes))
    t = sc.terrain
    true_terrain = {k: v for k, v in t.model_dump(mode="json").items()
                    if k not in ("rft", "effects", "description", "source")}
    meta = {
        "schema_version": 1,
        "robot": sc.robot.name,
        "terrain": f"{t.name} ({t.kind}), synthetic data from granular-mpc synth",
        "sample_rate_hz": fs,
        "description": description or (f"synthetic walking on {t.name}: speeds "
                                       f"{', '.join(f'{v:g}' for v in speeds)} m/s"),
        "trials": entries,
        **({"torque_hold_s": hold} if (hold := torque_hold(sc)) is not None else {}),
        "generator": {
            "scenario": str(scenario_path or path or sc.name),
            "seed": int(seed),
            "effects": [{"name": i.name, "params": p} for i, p in resolved],
            "noise": ({"level": level, **white}),
            "settings": {
                "effect_kinds": {i.name: i.kind for i, _ in resolved},
                "true_terrain": true_terrain,
                "stance_labels": "leading foot (last touchdown among the feet in contact)",
                "speeds_mps": speeds, "repeats": int(repeats),
                "recorded_s_per_trial": float(duration),
                "warmup_s": {r["name"]: float(r["warmup"]) for r in results},
                "plant_dt_s": float(sc.sim.dt),
                "controller_terrain": sc.controller.terrain,
                "noise_model_level_1": dict(NOISE_MODEL),
                "notes": notes,
            },
        },
    }
    # a run that went wild before it counted as a fall can break the format's plausibility
    # checks: cut such a trial 0.5 s before its first problem (or drop it)
    suffix = ".csv" if format == "csv" else ".parquet"
    for _ in range(3):
        meta["trials"] = {n: {**e, "file": f"{n}{suffix}"} for n, e in entries.items()}
        problems = check_trials(meta, trials)
        if not problems:
            break
        by_trial: dict[str, list] = {}
        for prob in problems:
            by_trial.setdefault(Path(prob.file).stem, []).append(prob)
        for name, probs in by_trial.items():
            if name not in trials:
                continue
            df = trials[name]
            rows = [p.row for p in probs if p.row is not None]
            why = "; ".join(f"{p.column}: {p.message}" for p in probs)[:300]
            keep = None
            if rows:
                t_cut = float(df[TIME].iloc[min(max(min(rows) - 1, 0), len(df) - 1)]) - 0.5
                keep = df[df[TIME] <= t_cut].reset_index(drop=True)
            if keep is None or len(keep) < 3 or _count_stances(keep[STANCE].to_numpy()) < 1:
                notes.append(f"{name}: dropped ({why})")
                trials.pop(name)
                entries.pop(name, None)
                n_st.pop(name, None)
            else:
                notes.append(f"{name}: cut at t = {t_cut:.2f} s ({why})")
                trials[name] = keep
                n_st[name] = _count_stances(keep[STANCE].to_numpy())
        meta["trials"] = {n: {**e, "file": f"{n}{suffix}"} for n, e in entries.items()}
        if not trials:
            raise GranularMpcError("synth recorded no usable trial: " + "; ".join(notes))
    out = target.folder
    target.clear()
    write_dataset(out, meta, trials, format)
    return SynthResult(out, {n: e["commanded_speed_mps"] for n, e in entries.items()}, n_st,
                       tuple(notes), time.perf_counter() - t_wall)


def noisy_copy(src: str | Path, dst: str | Path, noise: float | Mapping[str, float], *,
               seed: int = 0, format: str = "parquet", overwrite: bool = False) -> Path:
    """Write a copy of data set ``src`` with sensor noise added (same model as
    :func:`synthesize`); ``generator.noise`` and ``generator.seed`` record it. Handy to
    study one plant run at several noise levels. ``dst`` follows the rules of
    :func:`synthesize` (``overwrite`` replaces a synthetic data set there)."""
    ds = load_dataset(src)
    level, white = normalise_noise(noise)
    check_noise_prefixes(white, ds.joint_names)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 7919]))
    trials = {n: add_noise(df, ds.joint_names, level, white, rng, ds.meta.sample_rate_hz)
              for n, df in ds.trials.items()}
    meta = ds.meta.model_dump(mode="json")
    gen = meta.get("generator") or {}
    gen["noise"] = {"level": level, **white}
    gen.setdefault("settings", {})["noise_seed"] = int(seed)
    meta["generator"] = gen
    with DatasetTarget(Path(dst), overwrite) as target:
        target.clear()
        return write_dataset(target.folder, meta, trials, format)


__all__ = ["synthesize", "SynthResult", "NOISE_MODEL", "add_noise", "noisy_copy",
           "leading_foot_labels",
           "build_plant_simulation", "resolve_effects", "normalise_noise", "dataset_target",
           "DatasetTarget", "torque_hold"]
