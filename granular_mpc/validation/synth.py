"""Synthetic measurement data (format v1) from closed-loop walking of the plant.

``synthesize`` walks the plant with the walking controller at one or more commanded
speeds, optionally with **hidden effects** in the plant (the controller never sees them),
adds realistic **sensor noise**, and writes a data set in measurement format v1
(``docs/data-format.md``) whose ``meta.yaml`` records, under ``generator``, the scenario,
the seed, the effects *with all their true parameter values*, the noise and the true
terrain parameters — for tests that check what the workbench recovers. The workbench
(``validate`` / ``diagnose``) never reads the ``generator`` block.

Effects dispatch by kind (:mod:`granular_mpc.terrain.effects_library`):

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

**Noise model** (``noise=level``; level 1 = a realistic laboratory set-up, 0 = none):

=====================  =====================================================================
column                 noise (σ at level 1; scales with the level)
=====================  =====================================================================
``q_*``                encoder: white, 1e-3 rad
``dq_*``               differentiated encoder noise: backward difference of the q noise,
                       low-passed (2nd-order Butterworth, 80 Hz): ≈ 0.2 rad/s
``tau_*``              motor-current torque: white, 3 % of |τ| + 0.02 N·m
``grf_*``              foot force sensor: white, 1 N + 1 % of |F| (stance rows only)
``base_x,y,z``         motion capture: white, 1 mm
``base_q*``            motion capture: white rotation vector, 0.5° per axis (renormalised)
``base_v*``            state estimate: low-passed (40 Hz) noise, 0.02 m/s
``base_w*``            IMU gyro: white, 0.01 rad/s
``intrusion_*``        foot marker: white, 1 mm (stance rows only)
=====================  =====================================================================

``noise`` may instead be a mapping: ``{"level": L}`` selects the model above and any other
key ``PREFIX: σ`` replaces the model by white Gaussian noise of σ (column units) on the
columns starting with PREFIX (longest prefix wins) — the ``--noise PREFIX=STD`` of the
command line.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd

from ..config import EffectSpec, ScenarioConfig
from ..exceptions import ConfigError, GranularMpcError, OutputError
from ..terrain.effects_library import (SensorContext, apply_sensor_effects, effect_info,
                                       geometry_theta, joint_torque_function)
from .dataformat import META_FILE, format_columns

#: default noise standard deviations at level 1 (see the module docstring)
NOISE_MODEL = {
    "q": 1e-3, "dq_cutoff_hz": 80.0, "tau_rel": 0.03, "tau_abs": 0.02, "grf_abs": 1.0,
    "grf_rel": 0.01, "base_pos": 1e-3, "base_rot_deg": 0.5, "base_v": 0.02,
    "base_v_cutoff_hz": 40.0, "base_w": 0.01, "intrusion": 1e-3,
}

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
    from ..scenario import find_scenario, load_scenario

    if isinstance(scenario_or_name, ScenarioConfig):
        sc = scenario_or_name
        if overrides:
            from ..scenario import resolved_dict, scenario_from_dict
            sc = scenario_from_dict(resolved_dict(sc), list(overrides))
        return sc, None
    path = find_scenario(scenario_or_name)
    return load_scenario(str(path), list(overrides)), path


def _specs(effects: Sequence[Any]) -> list[EffectSpec]:
    out = []
    for e in effects or ():
        spec = e if isinstance(e, EffectSpec) else EffectSpec.model_validate(e)
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
    from ..dynamics import Plant
    from ..runner import build_simulation
    from ..terrain import build_terrain

    resolved = resolve_effects(effects)
    terrain_specs = [EffectSpec(name=i.name, params=p) for i, p in resolved
                     if i.kind == "terrain_force"]
    geom = geometry_theta(resolved)
    joint_fn = joint_torque_function(resolved)
    sim = build_simulation(scenario)
    if not terrain_specs and not geom and joint_fn is None:
        return sim
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
    plant = Plant(sim.biped, terrain, scenario.sim,
                  joint_effects=() if joint_fn is None else (joint_fn,))
    return replace(sim, plant=plant)


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


def _butter_lowpass(x: np.ndarray, cutoff_hz: float, fs: float) -> np.ndarray:
    """Causal 2nd-order Butterworth low-pass along axis 0."""
    from scipy.signal import butter, lfilter

    wn = min(cutoff_hz / (0.5 * fs), 0.99)
    b, a = butter(2, wn)
    return lfilter(b, a, x, axis=0)


def _quat_noise(quat_wxyz: np.ndarray, sigma_rad: float, rng) -> np.ndarray:
    """Perturb unit quaternions (w, x, y, z) by a random body rotation of σ per axis."""
    n = quat_wxyz.shape[0]
    rv = rng.normal(0.0, sigma_rad, size=(n, 3))
    ang = np.linalg.norm(rv, axis=1)
    half = 0.5 * ang
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(ang > 1e-12, np.sin(half) / np.where(ang > 0, ang, 1.0), 0.5)
    dq = np.column_stack([np.cos(half), rv * s[:, None]])
    w1, x1, y1, z1 = quat_wxyz.T
    w2, x2, y2, z2 = dq.T
    out = np.column_stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                           w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                           w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                           w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    out *= np.sign(out[:, :1] + (out[:, :1] == 0))
    return out


def normalise_noise(noise: float | Mapping[str, float] | None) -> tuple[float, dict[str, float]]:
    """(level of the realistic model, per-prefix white-noise overrides)."""
    if noise is None:
        return 1.0, {}
    if isinstance(noise, (int, float)):
        if noise < 0 or not math.isfinite(noise):
            raise ConfigError(f"noise level must be a finite number ≥ 0, got {noise}", key="noise")
        return float(noise), {}
    items = dict(noise)
    level = float(items.pop("level", 0.0 if items else 1.0))
    for k, v in items.items():
        if not (float(v) >= 0.0 and math.isfinite(float(v))):
            raise ConfigError(f"noise {k!r}: the standard deviation must be ≥ 0", key="noise")
    if level < 0:
        raise ConfigError("noise level must be ≥ 0", key="noise.level")
    return level, {k: float(v) for k, v in items.items()}


def add_noise(df: pd.DataFrame, joint_names: Sequence[str], level: float,
              white: Mapping[str, float], rng: np.random.Generator,
              sample_rate_hz: float) -> pd.DataFrame:
    """A copy of the format-v1 frame ``df`` with sensor noise (see the module docstring)."""
    out = df.copy()
    n = len(df)
    stance = (df["stance"].astype(str).to_numpy() != "none").astype(float)
    L = float(level)
    M = NOISE_MODEL
    fs = sample_rate_hz
    if L > 0:
        qn = rng.normal(0.0, M["q"] * L, size=(n, len(joint_names)))
        dqn = np.vstack([np.zeros((1, qn.shape[1])), np.diff(qn, axis=0) * fs])
        dqn = _butter_lowpass(dqn, M["dq_cutoff_hz"], fs)
        for k, j in enumerate(joint_names):
            out[f"q_{j}"] = df[f"q_{j}"].to_numpy() + qn[:, k]
            out[f"dq_{j}"] = df[f"dq_{j}"].to_numpy() + dqn[:, k]
            tau = df[f"tau_{j}"].to_numpy()
            out[f"tau_{j}"] = tau + rng.normal(0.0, 1.0, n) * L * (M["tau_rel"] * np.abs(tau)
                                                                  + M["tau_abs"])
        for ax in "xyz":
            f = df[f"grf_{ax}"].to_numpy()
            out[f"grf_{ax}"] = f + stance * rng.normal(0.0, 1.0, n) * L * (
                M["grf_abs"] + M["grf_rel"] * np.abs(f))
            out[f"intrusion_{ax}"] = (df[f"intrusion_{ax}"].to_numpy()
                                      + stance * rng.normal(0.0, M["intrusion"] * L, n))
            out[f"base_{ax}"] = df[f"base_{ax}"].to_numpy() + rng.normal(0.0, M["base_pos"] * L, n)
        vn = _butter_lowpass(rng.normal(0.0, 1.0, size=(n, 3)), M["base_v_cutoff_hz"], fs)
        vn *= M["base_v"] * L / max(float(np.std(vn)), 1e-12)
        for k, ax in enumerate("xyz"):
            out[f"base_v{ax}"] = df[f"base_v{ax}"].to_numpy() + vn[:, k]
            out[f"base_w{ax}"] = df[f"base_w{ax}"].to_numpy() + rng.normal(0.0, M["base_w"] * L, n)
        quat = df[["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy(dtype=float)
        quat = _quat_noise(quat, math.radians(M["base_rot_deg"]) * L, rng)
        out[["base_qw", "base_qx", "base_qy", "base_qz"]] = quat
    for prefix, sigma in sorted(white.items(), key=lambda kv: len(kv[0])):
        cols = [c for c in df.columns if c.startswith(prefix) and c not in ("time", "stance")]
        for c in cols:
            mask = stance if c.startswith(("grf_", "intrusion_")) else 1.0
            out[c] = df[c].to_numpy(dtype=float) + mask * rng.normal(0.0, sigma, n)
        if any(c.startswith("base_q") for c in cols):
            quat = out[["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy(dtype=float)
            quat /= np.linalg.norm(quat, axis=1, keepdims=True)
            out[["base_qw", "base_qx", "base_qy", "base_qz"]] = quat
    return out


def _v1_frame(rows: list[dict], joint_names: Sequence[str]) -> pd.DataFrame:
    """Format-v1 columns (leading-foot stance labels) from closed-loop log rows."""
    log = pd.DataFrame.from_records(rows)
    labels = leading_foot_labels(log["left_contact"].to_numpy(), log["right_contact"].to_numpy())
    out = pd.DataFrame({"time": log["time"].to_numpy(dtype=float), "stance": labels})
    for j in joint_names:
        for pre in ("q_", "dq_", "tau_"):
            out[pre + j] = log[pre + j].to_numpy(dtype=float)
    for c in ("base_x", "base_y", "base_z", "base_qw", "base_qx", "base_qy", "base_qz",
              "base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz"):
        out[c] = log[c].to_numpy(dtype=float)
    for what in ("grf", "intrusion"):
        for ax in "xyz":
            val = np.zeros(len(log))
            for side in ("left", "right"):
                m = labels == side
                val[m] = log[f"{side}_{what}_{ax}"].to_numpy(dtype=float)[m]
            out[f"{what}_{ax}"] = val
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
    from threadpoolctl import threadpool_limits

    from ..runner import closed_loop

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
    t = np.array([r["time"] for r in rows])
    t_end = t[-1] if len(t) else 0.0
    if fell_at is not None:
        t_end = fell_at - 0.5
        note = f"{payload['name']}: fell at t = {fell_at:.2f} s ({state.fall.reason}); " \
               "kept the data up to 0.5 s before"
    period = 1.0 / sc.log_rate_hz
    keep = [r for r in rows if warmup - 1e-9 <= r["time"] <= t_end + 1e-9
            and abs(r["time"] / period - round(r["time"] / period)) < 1e-3]   # log grid only
    frame = _v1_frame(keep, sim.biped.joint_names) if len(keep) > 2 else None
    if frame is not None:
        frame["time"] = frame["time"] - frame["time"].iloc[0]
    return {"name": payload["name"], "frame": frame, "note": note, "warmup": warmup,
            "joint_names": list(sim.biped.joint_names)}


# ----------------------------------------------------------------------------- public
def synthesize(scenario_or_name: ScenarioConfig | str | Path, out_dir: str | Path, *,
               speeds: Sequence[float] | None = None, steps: int | None = None,
               duration: float | None = None, repeats: int = 1, seed: int = 0,
               effects: Sequence[Any] = (), noise: float | Mapping[str, float] | None = 1.0,
               format: str = "csv", overrides: Sequence[str] = (),
               scenario_path: str | Path | None = None, warmup: float | None = None,
               settle: float = 0.4, workers: int | None = None,
               description: str = "") -> SynthResult:
    """Generate a measurement data set (format v1) by closed-loop walking of the plant.

    Args:
        scenario_or_name: a loaded scenario, or a scenario name / path (``sand_walk``).
        out_dir: data set folder to write (a previous data set there is replaced).
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

    Returns:
        :class:`SynthResult`.
    """
    import time as _time

    from .dataformat import write_dataset

    t_wall = _time.perf_counter()
    sc, path = _scenario(scenario_or_name, overrides)
    if sc.mode != "walk":
        raise ConfigError("synth needs a walking scenario", key="mode", value=sc.mode,
                          allowed="walk")
    if steps is not None and duration is not None:
        raise ConfigError("give steps or duration, not both", key="steps")
    if format not in ("csv", "parquet"):
        raise ConfigError(f"unknown format {format!r}", key="format", allowed="csv, parquet")
    specs = _specs(effects)
    resolved = resolve_effects(specs)
    level, white = normalise_noise(noise)
    speeds = [float(sc.command.speed)] if speeds is None else [float(v) for v in speeds]
    if not speeds:
        raise ConfigError("no speeds given", key="speeds")
    half_period = 0.5 * sc.controller.gait.period
    if duration is None:
        duration = (10 if steps is None else int(steps)) * half_period + 2.5 * half_period
    children = np.random.SeedSequence(int(seed)).spawn(len(speeds) * int(repeats))
    from ..control.gait import CommandRamp

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
    n_workers = workers or min(len(payloads), os.cpu_count() or 1)
    if n_workers > 1 and len(payloads) > 1:
        with ProcessPoolExecutor(max_workers=n_workers) as ex:
            results = list(ex.map(_run_trial, payloads))
    else:
        results = [_run_trial(p) for p in payloads]
    joint_names = results[0]["joint_names"]
    fs = float(sc.log_rate_hz)
    trials: dict[str, pd.DataFrame] = {}
    entries: dict[str, dict] = {}
    notes: list[str] = []
    n_st: dict[str, int] = {}
    for p, res, child in zip(payloads, results, children):
        if res["note"]:
            notes.append(res["note"])
        frame = res["frame"]
        if frame is None or _count_stances(frame["stance"].to_numpy()) < 1:
            notes.append(f"{p['name']}: no complete stance recorded; trial dropped")
            continue
        ctx = SensorContext(frame["stance"].to_numpy().astype(str),
                            frame["time"].to_numpy(dtype=float), tuple(joint_names))
        cols = {c: frame[c].to_numpy() for c in frame.columns if c not in ("stance",)}
        changed = apply_sensor_effects(cols, resolved, ctx)
        for c, v in changed.items():
            if c in frame.columns and c not in ("time", "stance"):
                frame[c] = v
        rng = np.random.default_rng(child.spawn(1)[0])
        frame = add_noise(frame, joint_names, level, white, rng, fs)
        trials[p["name"]] = frame
        n_st[p["name"]] = _count_stances(frame["stance"].to_numpy())
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
    from .dataformat import check_trials

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
                t_cut = float(df["time"].iloc[min(max(min(rows) - 1, 0), len(df) - 1)]) - 0.5
                keep = df[df["time"] <= t_cut].reset_index(drop=True)
            if keep is None or len(keep) < 3 or _count_stances(keep["stance"].to_numpy()) < 1:
                notes.append(f"{name}: dropped ({why})")
                trials.pop(name)
                entries.pop(name, None)
                n_st.pop(name, None)
            else:
                notes.append(f"{name}: cut at t = {t_cut:.2f} s ({why})")
                trials[name] = keep
                n_st[name] = _count_stances(keep["stance"].to_numpy())
        meta["trials"] = {n: {**e, "file": f"{n}{suffix}"} for n, e in entries.items()}
        if not trials:
            raise GranularMpcError("synth recorded no usable trial: " + "; ".join(notes))
    out = Path(out_dir)
    _clear_previous(out)
    write_dataset(out, meta, trials, format, overwrite=True)
    return SynthResult(out, {n: e["commanded_speed_mps"] for n, e in entries.items()}, n_st,
                       tuple(notes), _time.perf_counter() - t_wall)


def noisy_copy(src: str | Path, dst: str | Path, noise: float | Mapping[str, float], *,
               seed: int = 0, format: str = "parquet") -> Path:
    """Write a copy of data set ``src`` with sensor noise added (same model as
    :func:`synthesize`); ``generator.noise`` and ``generator.seed`` record it. Handy to
    study one plant run at several noise levels."""
    from .dataformat import load_dataset, write_dataset

    ds = load_dataset(src)
    level, white = normalise_noise(noise)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 7919]))
    trials = {n: add_noise(df, ds.joint_names, level, white, rng, ds.meta.sample_rate_hz)
              for n, df in ds.trials.items()}
    meta = ds.meta.model_dump(mode="json")
    gen = meta.get("generator") or {}
    gen["noise"] = {"level": level, **white}
    gen.setdefault("settings", {})["noise_seed"] = int(seed)
    meta["generator"] = gen
    out = Path(dst)
    _clear_previous(out)
    return write_dataset(out, meta, trials, format, overwrite=True)


def _clear_previous(folder: Path) -> None:
    """Remove a previous data set's meta and listed trial files from ``folder``."""
    meta = folder / META_FILE
    if not meta.is_file():
        return
    import yaml

    try:
        data = yaml.safe_load(meta.read_text(encoding="utf-8")) or {}
        for entry in (data.get("trials") or {}).values():
            f = folder / str(entry.get("file", ""))
            if f.is_file() and f.parent == folder and f.suffix in (".csv", ".parquet"):
                f.unlink()
        meta.unlink()
    except (OSError, yaml.YAMLError, AttributeError) as exc:
        raise OutputError(f"cannot replace the data set in {folder}: {exc}") from None


__all__ = ["synthesize", "SynthResult", "NOISE_MODEL", "add_noise", "noisy_copy",
           "leading_foot_labels",
           "build_plant_simulation", "resolve_effects", "normalise_noise"]
