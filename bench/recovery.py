"""Recovery study of ``diagnose``: hidden effect × seed × noise level, and the null test.

    python bench/recovery.py [--seeds 1 2 3] [--levels 0.5 1.0] [--effects NAME:k=v …]
                             [--nulls 10] [--mismatch KEY=VALUE …] [--steps 9] [--replay-segments 1]
                             [--out DIR [--reuse]] [--json PATH] [--quick]
    python bench/recovery.py --workbench [--out DIR] [--json PATH]
    python bench/recovery.py --retab STUDY.json DIR [--retab STUDY.json DIR …] [--json PATH]

For every hidden effect and seed, one plant run (``synth``, no noise: 5 speeds × ``steps``
stances) is turned into one data set per noise level (``noisy_copy``, the realistic sensor
model at that level) and diagnosed with the whole effects library as candidates. Per case:

* ``rank`` — position of the injected effect in the final ranking (1 = added first);
* ``added`` — what the diagnosis added;
* ``coef`` / ``true`` — the injected effect's main coefficient (the injected parameter
  furthest from its neutral value), fitted (refined) and true; ``coef_err`` = (fitted −
  true) / (true − neutral): relative error of the *magnitude* (for ``depth_hardening`` of
  n − 1, the excess exponent);
* ``channel`` / ``heldout_red`` — the channel whose held-out RMSE (trial-grouped CV,
  stance by stance) the added effect reduces most, and that reduction;
* ``replay_red`` — the same channel's in-sample replay RMSE reduction (all stances replayed
  with the fitted effect);
* ``signal`` / ``signal_channel`` — how far the hidden effect moves its channel in units of
  that channel's noise: max over channels of s_c / σ_c, s_c the replay RMSE the true effect
  explains on the noise-free data, σ_c the std of (noisy − clean) over stance rows
  (``bench/recovery_signal.py``; our reading of issue 11's "moves its channel ≥ 2 σ" is
  ``signal`` ≥ 2); two secondary readings: ``signal_moved`` / ``signal_moved_channel`` —
  max_c m_c / σ_c, m_c the RMS change of the replay's prediction of channel c by the true
  effect; ``signal_floor`` / ``signal_floor_channel`` — s_c over sqrt(after_c² + σ_c²), the
  noise-free replay's error floor with the true effect and the noise together. Computed
  from the data sets only (cached beside them), one noise-free replay per plant run.

Null test: data sets with no hidden effect (``--nulls`` seeds × levels); the figure is the
share of them where nothing was added. Parameter mismatch (``--mismatch KEY=VALUE``, by
default ζ = 1.768, +30 % on the model file's 1.36; seeds 200 + ``--seeds``): the plant runs
with the other value, no effect; the figure is the share calibrated within 10 % with
nothing added.

Summary lines (``name: value unit``): rank1_rate, coef_within_15pct_rate,
rank1_rate_signal2 and coef_within_15pct_rate_signal2 (the same over the cases with
``signal`` ≥ 2 — issue 11's population; the all-cases figures stay beside them),
rank1_rate_moved2 and coef_within_15pct_rate_moved2 (over ``signal_moved`` ≥ 2),
heldout_reduction_ge_50pct_rate, null_nothing_added_rate, mismatch_calibrated_rate,
cases, cases_signal2, cases_moved2, null_cases, mismatch_cases. ``--quick``: 2 effects ×
1 seed × 1 level + 1 null.

``--retab STUDY.json DIR`` (repeatable): re-tabulate a stored study without synthesising or
diagnosing — the rows of its summary JSON, the signal from the data sets in DIR
(``<effect>_s<seed>_clean`` and ``<effect>_s<seed>_n<level>``; caches are written there, so
work on a copy). Prints the per-case table and the figures per study and over all of them;
``--json`` writes ``figures`` (all studies), ``studies`` (per study) and ``rows``.

``--workbench [--out DIR]``: the held-out threshold study of the test suite
(docs/testing.md). The workbench data sets of tests/workbench.py are made again with the
plant and noise seeds shifted by ``HELDOUT_SEED_OFFSET`` (seeds no assertion uses) and two
noise seeds each; every figure that tests/test_diagnose.py and tests/test_replay.py assert
on is printed (``case noise_seed figure: value``), to set or check the thresholds.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the helper below, when imported

from _report import emit_study  # noqa: E402
from recovery_signal import SIGNAL_THRESHOLD, case_signal  # noqa: E402

DEFAULT_EFFECTS = [
    "inertial_drag:c_d=4",
    "cohesion:suction=3000",
    "depth_hardening:n=1.5",
    "elastic_unloading:pressure=4000",
    "joint_friction:coulomb=0.1,viscous=0.02",
    "force_sensor_bias:bias_z=6",
    "terrain_slope:slope_y=0.03",
]
SPEEDS = [0.1, 0.2, 0.3, 0.4, 0.5]


def run_case(data: Path, effect: str | None, out: Path, seed: int,
             mismatch: str | None = None, segments: int = 1) -> dict:
    from granular_mpc.validation.diagnose import diagnose

    t0 = time.perf_counter()
    diag = diagnose(data, out, seed=seed, n_boot=100, replay_segments=segments)
    row = {"added": ",".join(diag.added) or "-", "diagnose_s": time.perf_counter() - t0,
           "status": diag.verdict.status}
    if effect is None:
        row.update(rank=None, coef=None, true=None, coef_err=None, channel=None,
                   heldout_red=None, replay_red=None, nothing_added=not diag.added)
        if mismatch:       # "terrain.zeta=1.768": the calibrated value against the truth
            key, _, value = mismatch.partition("=")
            param, true = key.split(".")[-1], float(value)
            coef = diag.calibration.values[param]
            row.update(param=param, coef=coef, true=true, coef_err=(coef - true) / true)
        return row
    row.update(effect_figures(diag, effect), nothing_added=not diag.added)
    return row


def effect_figures(diag, effect: str) -> dict:
    """One injected effect's figures in a diagnosis: its rank, its main coefficient (the
    injected parameter furthest from its neutral value, relative to its range) fitted and
    true, the relative error of its magnitude, the channel whose held-out error the
    diagnosis cut most (in units of its scatter) and that channel's held-out and replay
    reductions."""
    from granular_mpc.config import parse_effect_string
    from granular_mpc.terrain.effects_library import effect_info

    spec = parse_effect_string(effect)
    name = spec["name"]
    info = effect_info(name)
    true_all = info.resolve_params(spec["params"])
    neutral_all = info.neutral_params()
    main = max(info.neutral, key=lambda p: abs(true_all[p] - neutral_all[p])
               / (info.params[p].upper - info.params[p].lower))
    true, neutral = true_all[main], neutral_all[main]
    entry = next(e for e in diag.ranking if e.effect == name)
    coef = entry.value_of(main)
    red = {c: d for c, d in diag.heldout_reduction_by_channel.items()
           if c != "touchdown_z" or info.kind == "geometry"}
    sigma = diag.design.sigma
    channel = (max(red, key=lambda c: (red[c].before - red[c].after) / sigma.get(c, 1.0))
               if red else None)
    rep = diag.replay_rmse_by_channel
    return dict(rank=entry.rank, coef=coef, true=true, param=main,
                coef_err=(coef - true) / (true - neutral), channel=channel,
                heldout_red=red[channel].reduction if channel else None,
                replay_red=rep[channel].reduction if channel in rep else None,
                added_self=name in diag.added)


def _rel(value: float, true: float) -> float:
    return abs(value - true) / abs(true)


def _diagnosis_figures(wb, name: str, d) -> dict:
    """The figures tests/test_diagnose.py asserts on, for one case's diagnosis."""
    f = {"added": ",".join(d.added) or "-"}
    if name == "null":
        f["zeta_rel_err"] = _rel(d.calibration.values["zeta"], 1.36)
    elif name == "cohesion":
        top = d.ranking[0]
        red = d.heldout_reduction_by_channel
        f.update(top=top.effect, heldout_red=top.heldout_error_reduction,
                 inclusion=top.inclusion_probability,
                 suction_rel_err=_rel(top.value_of("suction"), 3000.0),
                 q_heldout_red_max=max(v.reduction for k, v in red.items() if k.startswith("q_")),
                 q_right_knee_replay_red=d.replay_rmse_by_channel["q_right_knee"].reduction)
    elif name == "zeta_off":
        cal = d.calibration
        lo, hi = cal.equation_error.ci_boot["zeta"]
        f.update(eq_zeta_rel_err=_rel(cal.equation_error.values["zeta"], 1.768),
                 zeta_rel_err=_rel(cal.values["zeta"], 1.768),
                 eq_ci_contains=lo < cal.equation_error.values["zeta"] < hi)
    elif name == "unknown":
        loc = d.localization.before
        lateral = {"grf_y", "intrusion_y", "q_left_hip_abd", "q_right_hip_abd"}
        f.update(lateral_in_top8=bool(lateral & {c.channel for c in loc.significant_cells[:8]}),
                 lateral_share_max=max(loc.by_channel[c].systematic_share for c in lateral),
                 lateral_p_min=min(e.p_value for c in lateral for e in loc.correlates[c][:3]))
        if wb.USER_OBLIQUE in d.fitted_effects:
            f["oblique_c_rel_err"] = _rel(d.fitted_effects[wb.USER_OBLIQUE]["c"], 18.0)
    elif name == "loose_bed":
        start = next((s for s in d.force_starts if s.effect == wb.USER_LOOSE), None)
        f.update(start_passes=bool(start and start.passes),
                 start_k_rel_err=_rel(start.value, 1000.0) if start else float("nan"),
                 zeta_abs_err=d.calibration.values["zeta"] - 1.36)
        if wb.USER_LOOSE in d.fitted_effects:
            f["k_rel_err"] = _rel(d.fitted_effects[wb.USER_LOOSE]["k"], 1000.0)
    return f


def _replay_figures(wb, clean: Path) -> dict:
    """The figures tests/test_replay.py asserts on, from the held-out noise-free null data."""
    import numpy as np

    from granular_mpc.robot.model import load_biped
    from granular_mpc.validation import load_dataset
    from granular_mpc.validation.prepare import stance_windows
    from granular_mpc.validation.replay import (Variant, build_replay_model, effect_variant,
                                                model_terrain, replay_granular,
                                                resolve_effect_specs)

    ds = load_dataset(clean)
    biped = load_biped(ds.meta.robot, with_visuals=False)
    rm = build_replay_model(biped, model_terrain("dry_sand"),
                            sample_rate_hz=ds.meta.sample_rate_hz, terrain_effects=["cohesion"])
    ws = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness)
    trail = [w.feet[1 - w.foot] for w in ws]
    lead = [w.feet[w.foot] for w in ws]
    err = {c: [] for c in ("q_left_knee", "q_right_knee", "grf_z", "intrusion_z")}
    for w in ws:
        out = replay_granular(rm, w, Variant(theta={"touchdown_depth": 2e-4}))
        for c in err:
            err[c].append(out[c] - w.meas[c])
    f = {"n_windows": len(ws), "trail_force_min": min(t.force[2] for t in trail),
         "trail_depth_min": min(t.depth for t in trail),
         "trail_depth_max": max(t.depth for t in trail),
         "lead_height_max": max(-x.depth for x in lead)}
    f.update({f"noise_free_rms_{c}": float(np.sqrt(np.mean(np.concatenate(v) ** 2)))
              for c, v in err.items()})
    soft_d, coh_d = [], []
    for w in ws:
        base = replay_granular(rm, w, Variant())
        soft = replay_granular(rm, w, Variant(theta={"zeta": 0.9}))
        coh = replay_granular(rm, w, effect_variant([(*resolve_effect_specs(["cohesion"])[0],)]))
        soft_d.append(soft["intrusion_z"][-1] - base["intrusion_z"][-1])
        coh_d.append(float(np.max(np.abs(coh["q_right_knee"] - base["q_right_knee"]))))
    f.update(soft_deeper_min=min(soft_d), cohesion_knee_change_min=min(coh_d))
    return f


def _validate_figures(noisy: Path, out: Path) -> dict:
    """test_replay.py's model comparison and "adding the true effect" figures."""
    from granular_mpc.validation.replay import validate

    rep = {m: validate(noisy, out / m, model=m, n_boot=200, figures=False).report
           for m in ("rigid", "planar")}
    rep["added"] = validate(noisy, out / "added", effects=["cohesion:suction=3000"],
                            n_boot=200, figures=False).report
    g = rep["added"]["overall_rmse"]["granular"]
    rg, pl = rep["rigid"]["overall_rmse"]["rigid"], rep["planar"]["overall_rmse"]["planar"]
    ba = rep["added"]["before_after"]
    return {"rigid_over_granular_intrusion_z": rg["intrusion_z"] / g["intrusion_z"],
            "rigid_over_granular_grf_z": rg["grf_z"] / g["grf_z"],
            "planar_over_rigid_intrusion_z": pl["intrusion_z"] / rg["intrusion_z"],
            **{f"added_after_over_before_{c}": ba[c]["after"] / ba[c]["before"]
               for c in ("q_left_knee", "q_right_knee", "q_left_hip_pitch")}}


def heldout_study(out: Path | None, json_path: Path | None) -> dict:
    """Print (and return) every asserted figure on the held-out workbench data sets."""
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    import workbench as wb
    from granular_mpc.validation.synth import noisy_copy

    tmp = tempfile.TemporaryDirectory()
    root = out or Path(tmp.name)
    results: dict = {}
    for name, case in wb.WB_CASES.items():
        plant_seed = case["seed"] + wb.HELDOUT_SEED_OFFSET
        clean = wb.make_clean(name, root / f"{name}_s{plant_seed}_clean", plant_seed)
        if name == "null":
            results["replay null s%d" % plant_seed] = _replay_figures(wb, clean)
        for noise_seed in (plant_seed, plant_seed + 10):
            noisy = noisy_copy(clean, root / f"{name}_s{plant_seed}_n{noise_seed}", 1.0,
                               seed=noise_seed, overwrite=True)
            d, _ = wb.diagnose_case(name, noisy, None, figures=False)
            results[f"diagnose {name} s{plant_seed} n{noise_seed}"] = _diagnosis_figures(wb, name, d)
            if name == "cohesion" and noise_seed == plant_seed:
                results[f"validate {name} s{plant_seed} n{noise_seed}"] = _validate_figures(
                    noisy, root / f"validate_{noise_seed}")
    for key, figs in results.items():
        for k, v in figs.items():
            print(f"{key} {k}: {v:.4g}" if isinstance(v, float) else f"{key} {k}: {v}",
                  flush=True)
    if json_path:
        json_path.write_text(json.dumps(results, indent=1, default=str), encoding="utf-8")
    tmp.cleanup()
    return results


def _rate(rs: list[dict], f) -> float:
    return sum(1 for r in rs if f(r)) / len(rs) if rs else float("nan")


def _within_15pct(r: dict) -> bool:
    return r["coef_err"] is not None and abs(r["coef_err"]) <= 0.15


def study_figures(rows: list[dict]) -> dict:
    """The summary figures of a study's rows (all effect cases, and those whose effect
    moves its channel ≥ 2 σ: ``signal`` ≥ 2, see ``bench/recovery_signal.py``)."""
    eff = [r for r in rows if r["effect"] != "none" and not r["effect"].startswith("mismatch")]
    nul = [r for r in rows if r["effect"] == "none"]
    mis = [r for r in rows if r["effect"].startswith("mismatch")]
    sig = [r for r in eff if (r.get("signal") or 0.0) >= SIGNAL_THRESHOLD]
    moved = [r for r in eff if (r.get("signal_moved") or 0.0) >= SIGNAL_THRESHOLD]
    return {
        "rank1_rate": _rate(eff, lambda r: r["rank"] == 1),
        "coef_within_15pct_rate": _rate(eff, _within_15pct),
        "rank1_rate_signal2": _rate(sig, lambda r: r["rank"] == 1),
        "coef_within_15pct_rate_signal2": _rate(sig, _within_15pct),
        "rank1_rate_moved2": _rate(moved, lambda r: r["rank"] == 1),
        "coef_within_15pct_rate_moved2": _rate(moved, _within_15pct),
        "heldout_reduction_ge_50pct_rate": _rate(eff, lambda r: (r["heldout_red"] or 0) >= 0.5),
        "null_nothing_added_rate": _rate(nul, lambda r: r["nothing_added"]),
        # nothing missing, so no structure either (verdict no_significant_missing_effect)
        "null_no_structure_rate": _rate(nul, lambda r: r["status"]
                                        == "no_significant_missing_effect"),
        "mismatch_calibrated_rate": _rate(mis, lambda r: r["nothing_added"]
                                          and abs(r["coef_err"]) <= 0.10),
        "cases": len(eff), "cases_signal2": len(sig), "cases_moved2": len(moved),
        "null_cases": len(nul),
        "mismatch_cases": len(mis),
    }


def case_tag(effect: str | None, mismatch: str | None, seed: int,
             several_mismatches: bool = False) -> str:
    """The folder tag of one case: ``<effect>_s<seed>`` (the effect's parameters appended
    when given, ``depth_hardening_n_1.3_s4``: two magnitudes of one effect in a run must
    not write the same folders), ``mismatch_s<seed>`` (the override appended when the run
    has several), ``null_s<seed>``."""
    def clean(text: str) -> str:
        return re.sub(r"[^A-Za-z0-9.]+", "_", text).strip("_")

    if effect:
        name, _, params = effect.partition(":")
        return f"{name}_{clean(params)}_s{seed}" if params else f"{name}_s{seed}"
    if mismatch:
        return f"mismatch_{clean(mismatch)}_s{seed}" if several_mismatches else f"mismatch_s{seed}"
    return f"null_s{seed}"


def add_signal(row: dict, root: Path) -> dict:
    """Put the case's ``signal`` (max_c s_c / σ_c), ``signal_channel``, ``signal_moved`` /
    ``signal_moved_channel`` (max_c m_c / σ_c) and ``signal_floor`` / ``signal_floor_channel``
    (s_c over the noise-free replay's floor and the noise together) into an effect row, from
    ``<tag>_clean`` and ``<tag>_n<level>`` in ``root`` (``bench/recovery_signal.py``; cached
    there; no diagnosis). Null and mismatch rows get None."""
    effect = row["effect"]
    if effect == "none" or effect.startswith("mismatch"):
        row.update(signal=None, signal_channel=None, signal_moved=None,
                   signal_moved_channel=None, signal_floor=None, signal_floor_channel=None)
        return row
    tag = case_tag(effect, None, row["seed"])
    cs = case_signal(root, tag, row["noise"], effect, row["seed"])
    row.update(signal=cs.signal.value, signal_channel=cs.signal.channel,
               signal_moved=cs.moved.value, signal_moved_channel=cs.moved.channel,
               signal_floor=cs.floor.value, signal_floor_channel=cs.floor.channel)
    return row


def _pct(v) -> str:
    return "-" if v is None else format(v, "+.1%")


def signal_table(rows: list[dict]) -> str:
    """The per-case table (markdown) of effect rows carrying a signal."""
    lines = ["| study | effect | seed | noise | signal | channel | moved | channel "
             "| over floor | channel | rank | added | coef_err |", "|" + "---|" * 13]
    for r in rows:
        if r.get("signal") is None:
            continue
        lines.append(f"| {r.get('study', '')} | `{r['effect']}` | {r['seed']} | {r['noise']:g} "
                     f"| {r['signal']:.1f} | {r['signal_channel']} | {r['signal_moved']:.1f} "
                     f"| {r['signal_moved_channel']} | {r['signal_floor']:.2f} "
                     f"| {r['signal_floor_channel']} | {r['rank']} | {r['added']} "
                     f"| {_pct(r['coef_err'])} |")
    return "\n".join(lines)


def retabulate(studies: list[tuple[Path, Path]], json_path: Path | None) -> dict:
    """Re-tabulate stored studies without diagnosing: each (summary JSON, data folder) pair's
    rows get their signal (:func:`add_signal`); prints the per-case table and the figures per
    study and over all of them."""
    all_rows: list[dict] = []
    per_study = {}
    for summary, root in studies:
        name = summary.stem
        rows = json.loads(summary.read_text(encoding="utf-8"))["rows"]
        for r in rows:
            r["study"] = name
            add_signal(r, root)
            if r["signal"] is not None:
                print(f"{name:12s} {r['effect']:42s} seed {r['seed']:3d} noise {r['noise']:3.1f}"
                      f"  signal {r['signal']:6.1f} ({r['signal_channel']})  moved "
                      f"{r['signal_moved']:6.1f} ({r['signal_moved_channel']})  floor "
                      f"{r['signal_floor']:5.2f} ({r['signal_floor_channel']})  rank "
                      f"{r['rank']}  added {r['added']}  coef_err {_pct(r['coef_err'])}",
                      flush=True)
        per_study[name] = study_figures(rows)
        all_rows += rows
    combined = study_figures(all_rows)
    print(signal_table(all_rows))
    for name, figs in [*per_study.items(), ("all", combined)]:
        for k in ("rank1_rate", "coef_within_15pct_rate", "cases", "rank1_rate_signal2",
                  "coef_within_15pct_rate_signal2", "cases_signal2", "rank1_rate_moved2",
                  "coef_within_15pct_rate_moved2", "cases_moved2"):
            v = figs[k]
            print(f"{name} {k}: {v:.3g}" if isinstance(v, float) else f"{name} {k}: {v}")
    out = {"figures": combined, "studies": per_study, "rows": all_rows}
    if json_path:
        json_path.write_text(json.dumps(out, indent=1, default=str), encoding="utf-8")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--levels", type=float, nargs="+", default=[0.5, 1.0])
    ap.add_argument("--effects", nargs="*", default=DEFAULT_EFFECTS)
    ap.add_argument("--mismatch", nargs="*", default=["terrain.zeta=1.768"],
                    help="parameter mismatches (scenario overrides of the plant), no effect")
    ap.add_argument("--nulls", type=int, default=10, help="null seeds (× levels)")
    ap.add_argument("--steps", type=int, default=9, help="stances per trial (5 trials)")
    ap.add_argument("--out", type=Path, default=None, help="keep data and reports here")
    ap.add_argument("--replay-segments", type=int, default=1,
                    help="replays per stance of every diagnosis (restarts mid-stance)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--workbench", action="store_true",
                    help="held-out threshold study of the test suite's workbench data sets")
    ap.add_argument("--reuse", action="store_true",
                    help="with --out: reuse data sets already there (re-diagnose only)")
    ap.add_argument("--retab", nargs=2, action="append", type=Path, metavar=("JSON", "DIR"),
                    help="re-tabulate a stored study (its summary JSON and data folder) with "
                         "the signal per case, without diagnosing; repeatable")
    args = ap.parse_args()
    if args.replay_segments < 1:
        ap.error(f"--replay-segments: {args.replay_segments} — give 1 (whole stances) or more")
    if args.retab:
        retabulate(args.retab, args.json)
        return
    if args.workbench:
        heldout_study(args.out, args.json)
        return
    if args.quick:
        args.effects, args.seeds, args.levels, args.nulls = args.effects[1:3], [1], [1.0], 1
        args.mismatch = []

    from granular_mpc.validation.synth import noisy_copy, synthesize

    tmp = tempfile.TemporaryDirectory()
    root = args.out or Path(tmp.name)
    rows = []
    cases = [(e, None, s) for e in args.effects for s in args.seeds]
    cases += [(None, None, 100 + k) for k in range(args.nulls)]
    cases += [(None, m, 200 + s) for m in args.mismatch for s in args.seeds]
    for effect, mismatch, seed in cases:
        tag = case_tag(effect, mismatch, seed, len(args.mismatch) > 1)
        clean = root / f"{tag}_clean"
        if not (args.reuse and (clean / "meta.yaml").is_file()):
            synthesize("sand_walk", clean, speeds=SPEEDS, steps=args.steps, seed=seed,
                       effects=[effect] if effect else [], noise=0.0, format="parquet",
                       overrides=[mismatch] if mismatch else [], overwrite=True)
        for level in args.levels:
            data = root / f"{tag}_n{level:g}"
            if not (args.reuse and (data / "meta.yaml").is_file()):
                noisy_copy(clean, data, level, seed=seed, overwrite=True)
            row = run_case(data, effect, root / f"{tag}_n{level:g}_diag", seed, mismatch,
                           args.replay_segments)
            row.update(effect=effect or (f"mismatch {mismatch}" if mismatch else "none"),
                       seed=seed, noise=level)
            add_signal(row, root)
            rows.append(row)
            print(f"{row['effect']:42s} seed {seed:3d} noise {level:3.1f}  rank {row['rank']}  "
                  f"added {row['added']:20s} coef {row['coef']} (true {row['true']}, err "
                  f"{'-' if row['coef_err'] is None else format(row['coef_err'], '+.1%')})  "
                  f"{row['channel']}: held-out {'-' if row['heldout_red'] is None else format(row['heldout_red'], '.0%')}"
                  f" replay {'-' if row['replay_red'] is None else format(row['replay_red'], '.0%')}"
                  f"  signal {'-' if row['signal'] is None else format(row['signal'], '.1f')}"
                  f"  {row['status']}  [{row['diagnose_s']:.0f} s]", flush=True)
    emit_study(study_figures(rows), rows, args.json)
    tmp.cleanup()


if __name__ == "__main__":
    main()
