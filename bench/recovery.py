"""Recovery study of ``diagnose``: hidden effect × seed × noise level, and the null test.

    python bench/recovery.py [--seeds 1 2 3] [--levels 0.5 1.0] [--effects NAME:k=v …]
                             [--nulls 10] [--mismatch KEY=VALUE …] [--steps 9] [--out DIR [--reuse]] [--json PATH] [--quick]

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
  with the fitted effect).

Null test: data sets with no hidden effect (``--nulls`` seeds × levels); the figure is the
share of them where nothing was added. Parameter mismatch (``--mismatch KEY=VALUE``, by
default ζ = 1.768, +30 % on the model file's 1.36; seeds 200 + ``--seeds``): the plant runs
with the other value, no effect; the figure is the share calibrated within 10 % with
nothing added.

Summary lines (``name: value unit``): rank1_rate, coef_within_15pct_rate,
heldout_reduction_ge_50pct_rate, null_nothing_added_rate, mismatch_calibrated_rate,
cases, null_cases, mismatch_cases. ``--quick``: 2 effects ×
1 seed × 1 level + 1 null (the slow test runs this).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

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
             mismatch: str | None = None) -> dict:
    from granular_mpc.config import parse_effect_string
    from granular_mpc.terrain.effects_library import effect_info
    from granular_mpc.validation.diagnose import diagnose

    t0 = time.perf_counter()
    diag = diagnose(data, out, seed=seed, n_boot=100)
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
    spec = parse_effect_string(effect)
    name = spec["name"]
    info = effect_info(name)
    true_all = info.resolve_params(spec["params"])
    neutral_all = info.neutral_params()
    # the injected magnitude: the parameter furthest from neutral (relative to its range)
    main = max(info.neutral, key=lambda p: abs(true_all[p] - neutral_all[p])
               / (info.params[p].upper - info.params[p].lower))
    true, neutral = true_all[main], neutral_all[main]
    entry = next(e for e in diag.ranking if e.effect == name)
    coef = entry.value_of(main)
    red = {c: d for c, d in diag.heldout_reduction_by_channel.items()
           if c != "touchdown_z" or info.kind == "geometry"}
    sigma = diag.design.sigma
    # the affected channel: largest held-out error reduction in units of its scatter
    channel = (max(red, key=lambda c: (red[c].before - red[c].after) / sigma.get(c, 1.0))
               if red else None)
    rep = diag.replay_rmse_by_channel
    row.update(rank=entry.rank, coef=coef, true=true, param=main,
               coef_err=(coef - true) / (true - neutral), channel=channel,
               heldout_red=red[channel].reduction if channel else None,
               replay_red=rep[channel].reduction if channel in rep else None,
               nothing_added=not diag.added)
    return row


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
    ap.add_argument("--json", type=Path)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--reuse", action="store_true",
                    help="with --out: reuse data sets already there (re-diagnose only)")
    args = ap.parse_args()
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
        kind = effect.split(":")[0] if effect else ("mismatch" if mismatch else "null")
        tag = f"{kind}_s{seed}"
        clean = root / f"{tag}_clean"
        if not (args.reuse and (clean / "meta.yaml").is_file()):
            synthesize("sand_walk", clean, speeds=SPEEDS, steps=args.steps, seed=seed,
                       effects=[effect] if effect else [], noise=0.0, format="parquet",
                       overrides=[mismatch] if mismatch else [], overwrite=True)
        for level in args.levels:
            data = root / f"{tag}_n{level:g}"
            if not (args.reuse and (data / "meta.yaml").is_file()):
                noisy_copy(clean, data, level, seed=seed, overwrite=True)
            row = run_case(data, effect, root / f"{tag}_n{level:g}_diag", seed, mismatch)
            row.update(effect=effect or (f"mismatch {mismatch}" if mismatch else "none"),
                       seed=seed, noise=level)
            rows.append(row)
            print(f"{row['effect']:42s} seed {seed:3d} noise {level:3.1f}  rank {row['rank']}  "
                  f"added {row['added']:20s} coef {row['coef']} (true {row['true']}, err "
                  f"{'-' if row['coef_err'] is None else format(row['coef_err'], '+.1%')})  "
                  f"{row['channel']}: held-out {'-' if row['heldout_red'] is None else format(row['heldout_red'], '.0%')}"
                  f" replay {'-' if row['replay_red'] is None else format(row['replay_red'], '.0%')}"
                  f"  {row['status']}  [{row['diagnose_s']:.0f} s]", flush=True)
    eff = [r for r in rows if r["effect"] != "none" and not r["effect"].startswith("mismatch")]
    nul = [r for r in rows if r["effect"] == "none"]
    mis = [r for r in rows if r["effect"].startswith("mismatch")]

    def rate(rs, f):
        return sum(1 for r in rs if f(r)) / len(rs) if rs else float("nan")

    figures = {
        "rank1_rate": rate(eff, lambda r: r["rank"] == 1),
        "coef_within_15pct_rate": rate(eff, lambda r: r["coef_err"] is not None
                                       and abs(r["coef_err"]) <= 0.15),
        "heldout_reduction_ge_50pct_rate": rate(eff, lambda r: (r["heldout_red"] or 0) >= 0.5),
        "null_nothing_added_rate": rate(nul, lambda r: r["nothing_added"]),
        "mismatch_calibrated_rate": rate(mis, lambda r: r["nothing_added"]
                                         and abs(r["coef_err"]) <= 0.10),
        "cases": len(eff), "null_cases": len(nul), "mismatch_cases": len(mis),
    }
    for k, v in figures.items():
        print(f"{k}: {v:.3g}" if isinstance(v, float) else f"{k}: {v}")
    if args.json:
        args.json.write_text(json.dumps({"figures": figures, "rows": rows}, indent=1,
                                        default=str), encoding="utf-8")
    tmp.cleanup()


if __name__ == "__main__":
    main()
