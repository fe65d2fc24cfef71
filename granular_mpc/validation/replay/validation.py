"""``validate``: replay every stance of a data set with one model and score it.

Each complete stance phase (:mod:`..prepare`) is replayed from its measured first sample
with the measured torques (multiple shooting) on the ``granular``, ``rigid`` or ``planar``
model (:data:`~.model.MODELS`), optionally with extra effects; the predicted joint angles,
ground reaction force and intrusion are compared with the measured ones: RMSE by channel
× stance-phase bin × commanded speed with intervals from resampling whole trials,
``report.json`` and figures (``docs/validation.md`` §2).
"""

from __future__ import annotations

import json
import time as _time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import pandas as pd

from ...analysis.metrics import phase_bands, resample_by_phase
from ...config import SimConfig
from ...exceptions import ConfigError, GranularMpcError
from ...output import json_safe, make_output_folder
from ...robot.model import load_biped
from ...effects import load_effect_file
from ...viz.plots import plot_model_vs_measurement, plot_residual_heatmap, plot_rmse_vs_speed
from ..channel_coverage import channel_coverage
from ..dataformat import load_dataset
from ..diagnosis.result import DIAGNOSIS_FILE, FittedParameters
from ..prepare import StanceWindow, channel_names, channel_unit, stance_windows, windows_frame
from ..restarts import check_segments
from .measurement import check_sensor_inversion, check_sensor_specs
from .model import (MODELS, REPLAY_PARAMS, Variant, build_replay_model, effect_variant,
                    model_terrain, resolve_effect_specs)
from .pool import ReplayPool
from .scoring import rmse_tables, role_channels, table_records


def load_fitted(params: str | Path | Mapping | None) -> tuple[dict, dict]:
    """(calibrated terrain θ, fitted effect parameters by effect name) from a mapping or a
    ``diagnosis.json`` file or its folder (read by
    :class:`~granular_mpc.validation.diagnosis.result.FittedParameters`: its
    ``calibration.values`` and ``fitted_effects``). A mapping without those keys is taken
    as ``{θ name: value, effect name: {param: value}}``.

    Raises:
        ConfigError: the file cannot be read.
    """
    if params is None:
        return {}, {}
    where = "the --params mapping"
    if isinstance(params, (str, Path)):
        p = Path(params)
        if p.is_dir():
            p = p / DIAGNOSIS_FILE
        try:
            where = str(p)
            params = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ConfigError(f"cannot read fitted parameters from {p}: {exc}",
                              key="--params") from None
    shape = ("a diagnosis.json (with 'calibration.values' and/or 'fitted_effects'), or an "
             "object {θ name: number, effect name: {parameter: number}}")
    if not isinstance(params, Mapping):
        raise ConfigError(f"fitted parameters in {where} must be {shape}, got a "
                          f"{type(params).__name__}", key="--params", value=where)
    try:
        if FittedParameters.is_diagnosis(params):
            fitted = FittedParameters.from_dict(params)
            cal = {k: float(v) for k, v in fitted.calibration.items()}
            eff = {k: {n: float(x) for n, x in dict(v).items()} for k, v in fitted.effects.items()}
            return cal, eff
        return ({k: float(v) for k, v in params.items() if not isinstance(v, Mapping)},
                {k: {n: float(x) for n, x in v.items()} for k, v in params.items()
                 if isinstance(v, Mapping)})
    except (TypeError, ValueError, AttributeError) as exc:
        raise ConfigError(f"fitted parameters in {where} must be {shape} ({exc})",
                          key="--params", value=where) from None


@dataclass(frozen=True)
class ValidationReport:
    """What :func:`validate` computed and wrote.

    Attributes:
        report: the content of ``report.json``.
        tables: model label → RMSE tables (:func:`rmse_tables`).
        windows: the replayed stance windows.
        predictions: model label → per-window outputs.
        out_dir: where the report was written (or None).
        figures: written figure paths.
    """

    report: dict
    tables: dict
    windows: list
    predictions: dict
    out_dir: Path | None
    figures: tuple = ()

    def rmse(self, label: str, channel: str) -> float:
        """Whole-data RMSE of one channel for one model label."""
        t = self.tables[label]["overall"]
        return float(t.loc[t["channel"] == channel, "rmse"].iloc[0])


def validate(data_dir: str | Path, out_dir: str | Path | None = None, *,
             model: str = "granular", effects: Sequence[Any] = (),
             params: str | Path | Mapping | None = None, terrain: Any = "dry_sand",
             sim: SimConfig | None = None, phase_bins: int = 10, n_boot: int = 1000,
             workers: int | None = None, figures: bool = True, seed: int = 0,
             effect_files: Sequence[str | Path] = (),
             replay_segments: int = 1) -> ValidationReport:
    """Replay every complete stance of a data set and score the model against it.

    Args:
        data_dir: measurement data set (format v1).
        out_dir: report folder (``report.json`` + figures); None: nothing written.
        model: ``granular``, ``rigid`` or ``planar`` (see the module docstring).
        effects: effects to add (``"name:k=v"``, mappings or EffectSpec); with effects
            the report holds the model *before* (``<model>``) and *after*
            (``<model>+effects``) and the change of every RMSE.
        params: calibrated terrain parameters and fitted effect parameters: a mapping or
            a ``diagnosis.json`` (or its folder). Effects given without values take the
            fitted ones.
        terrain: the model's terrain (name/path in ``models/terrain`` or a config).
        sim: plant settings for the replay (default: ``SimConfig()``, dt = 0.5 ms).
        phase_bins: stance-phase bins of the tables.
        n_boot: bootstrap replicates of the intervals.
        workers: processes for the replays (default: all CPUs).
        figures: write the figures.
        seed: bootstrap seed.
        effect_files: user Python files registering effects (imported first).
        replay_segments: replays per stance of the ``granular`` model: each stance is
            replayed again from the measured state ``replay_segments − 1`` times
            (:mod:`~granular_mpc.validation.restarts`; needs measured intrusion).

    Returns:
        :class:`ValidationReport`.
    """
    t0 = _time.perf_counter()
    if model not in MODELS:
        raise ConfigError(f"unknown model {model!r}", key="model", allowed=", ".join(MODELS))
    if check_segments(replay_segments) > 1 and model != "granular":
        raise ConfigError(f"restarts within a stance are replayed by the granular model only, "
                          f"not {model!r}", key="replay_segments", value=replay_segments,
                          allowed="1 with the rigid and planar models")
    for f in effect_files:
        load_effect_file(str(f))
    ds = load_dataset(data_dir)
    # checked before the replays, so that a bad folder does not cost the computation
    out = make_output_folder(out_dir) if out_dir is not None else None
    biped = load_biped(ds.meta.robot, with_visuals=False)
    cal, fitted = load_fitted(params)
    cfg = model_terrain(terrain, cal)
    specs = resolve_effect_specs(effects, fitted)
    terrain_names = [i.name for i, _ in specs if i.kind == "terrain_force"]
    rm = build_replay_model(biped, cfg, sample_rate_hz=ds.meta.sample_rate_hz, sim=sim,
                            terrain_effects=terrain_names)
    windows = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness,
                             segments=replay_segments)
    if not windows:
        raise GranularMpcError(f"{data_dir}: no complete stance phase to replay")
    J = list(ds.joint_names)
    channels = channel_names(J, ds.channels)          # measured channels only
    coverage = channel_coverage(ds)
    check_sensor_specs(specs, windows[0], J)      # a clear error before any replay
    check_sensor_inversion(specs, windows[0], J)  # … and one a replay can invert
    base = Variant(theta={k: float(v) for k, v in cal.items() if k in REPLAY_PARAMS},
                   label=model)
    variants = {model: base}
    if specs:
        if model == "rigid" and any(i.kind != "sensor" for i, _ in specs):
            raise ConfigError("the rigid-ground model takes sensor effects only", key="--effect")
        variants[f"{model}+effects"] = effect_variant(specs, base, f"{model}+effects")
    t_rep = _time.perf_counter()
    with ReplayPool(rm, windows, workers=workers) as pool:
        preds = {k: v for k, v in pool.run(variants, kind=model).items()}
    t_rep = _time.perf_counter() - t_rep
    tables = {k: rmse_tables(windows, preds[k], channels, phase_bins=phase_bins,
                             n_boot=n_boot, seed=seed) for k in variants}
    n_div = {k: int(sum(bool(p["diverged"]) for p in preds[k])) for k in variants}
    report: dict[str, Any] = {
        "data": str(data_dir), "model": model, "robot": ds.meta.robot,
        "terrain": getattr(cfg, "name", str(terrain)),
        "calibrated_params": cal,
        "effects": [{"name": i.name, "kind": i.kind, "params": p} for i, p in specs],
        "n_trials": len(ds.trials), "n_stances": len(windows),
        "speeds_mps": sorted({w.speed for w in windows}),
        "channels": channels, "units": {c: channel_unit(c) for c in channels},
        "coverage": coverage.to_dict(),
        "phase_bins": phase_bins,
        "replay_segments": replay_segments,
        "restarts": int(sum(len(w.restarts) for w in windows)),
        "interval": {"ci": 0.95, "n_boot": n_boot,
                     "unit": tables[model]["overall"]["interval_unit"].iloc[0]},
        "diverged_stances": n_div,
        "models": {k: {name: table_records(t) for name, t in tb.items()} for k, tb in tables.items()},
        "overall_rmse": {k: dict(zip(tb["overall"]["channel"], tb["overall"]["rmse"]))
                         for k, tb in tables.items()},
    }
    if specs:
        b = report["overall_rmse"][model]
        a = report["overall_rmse"][f"{model}+effects"]
        report["before_after"] = {c: {"before": b[c], "after": a[c],
                                      "change_pct": 100.0 * (a[c] - b[c]) / b[c] if b[c] else None}
                                  for c in channels}
    figs: list[Path] = []
    if out is not None:
        if figures:
            figs = _figures(out, windows, preds, tables, J, model)
        report["figures"] = [str(p.name) for p in figs]
    report["timing_s"] = {"replay": t_rep, "total": _time.perf_counter() - t0}
    if out is not None:
        (out / "report.json").write_text(json.dumps(json_safe(report), indent=1),
                                         encoding="utf-8")
        (out / "report.md").write_text(_markdown(report, coverage), encoding="utf-8")
    return ValidationReport(report, tables, windows, preds, out, tuple(figs))


def _markdown(report: Mapping[str, Any], coverage) -> str:
    """``report.md``: the overall RMSE per model and the channel coverage."""
    labels = list(report["overall_rmse"])
    lines = [f"# Validation of `{report['data']}`", "",
             f"Model `{report['model']}`, {report['n_stances']} stances from "
             f"{report['n_trials']} trial(s); RMSE over all stances.", "",
             "| channel | unit | " + " | ".join(labels) + " |",
             "|---|---|" + "---|" * len(labels)]
    for c in report["channels"]:
        lines.append(f"| {c} | {report['units'][c]} | "
                     + " | ".join(f"{report['overall_rmse'][k][c]:.4g}" for k in labels) + " |")
    return "\n".join(lines + [""] + coverage.markdown())


def _figures(out: Path, windows: Sequence[StanceWindow], preds: dict, tables: dict,
             J: Sequence[str], model: str) -> list[Path]:
    """``bands.png``, ``rmse_vs_speed.png`` and one ``heatmap_<model>.png`` per model label."""
    paths = []
    role_meas = [role_channels(w, w.meas, J) for w in windows]
    role_chans = list(role_meas[0].keys())
    frames = []
    for label, src in [("measurement", role_meas)] + [
            (k, [role_channels(w, p, J) for w, p in zip(windows, preds[k])]) for k in preds]:
        f = windows_frame(windows, src, role_chans)
        for c in role_chans:
            if c.startswith("intrusion"):
                f[c] = 1e3 * f[c]
        f["source"] = label
        frames.append(f)
    long = pd.concat(frames, ignore_index=True)
    long["_id"] = long["source"] + ":" + long["stance_id"].astype(str)
    res = resample_by_phase(long, role_chans, id_col="_id", n_phase=51, keep=["source"])
    bands = phase_bands(res, role_chans, by=["source"])
    units = {c: ("rad" if c.startswith("q_") else "N" if c.startswith("grf") else "mm")
             for c in role_chans}
    paths.append(plot_model_vs_measurement(bands, out / "bands.png", units=units).path)
    speed_tables = []
    for k, tb in tables.items():
        t = tb["by_speed"].copy()
        t["model"] = k
        speed_tables.append(t)
    st = pd.concat(speed_tables, ignore_index=True)
    paths.append(plot_rmse_vs_speed(st, out / "rmse_vs_speed.png",
                                    units={c: channel_unit(c) for c in st["channel"].unique()}).path)
    for k, tb in tables.items():
        safe = k.replace("+", "_plus_")
        paths.append(plot_residual_heatmap(tb["by_phase"], out / f"heatmap_{safe}.png",
                                           title=f"{k}: RMSE by channel and stance phase").path)
    return [p for p in paths if p is not None]


__all__ = ["validate", "ValidationReport", "load_fitted"]
