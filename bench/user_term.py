"""An effect outside the library, found with a user-written term, over data realisations.

    python bench/user_term.py [--seeds 24 25 … 33] [--steps 7] [--out DIR [--reuse]] [--json PATH]

The plant walks with a hidden sideways push F_y = −k·v_x (k = 18 N·s/m, v_x the sole's
forward velocity) that no library effect has; the data sets are the test suite's (3 trials
at 0.15, 0.25, 0.35 m/s × ``steps`` stances, sensor noise level 1), one per seed. Each is
diagnosed with the library plus the user's guess ``oblique_flow`` (F_y = −c·v_x, the term of
docs/validation.md §4) and validated with the fitted term. Per seed it prints whether the
term was added, its fitted c, its held-out error reduction and effect size, and the
``intrusion_y`` / ``grf_y`` RMSE before → after.

Summary lines (``name: value unit``): added_rate, c_within_30pct_rate,
intrusion_y_reduction_min, effect_size_min / _max, heldout_reduction_min, cases.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from _report import emit

TRUE_K = 18.0
SPEEDS = (0.15, 0.25, 0.35)
HIDDEN, USER = "_bench_hidden_skew", "oblique_flow"
LIBRARY = ["inertial_drag", "cohesion", "depth_hardening", "elastic_unloading",
           "joint_friction", "force_sensor_bias", "terrain_slope"]


def _register() -> None:
    from granular_mpc.terrain.effects import Param, register_effect, registered_effects

    if HIDDEN not in registered_effects():
        @register_effect(HIDDEN, params={"k": Param(TRUE_K, 0.0, 200.0, "N·s/m", "")})
        def _hidden(o, s, p):
            """The hidden truth: a sideways push ∝ the sole's forward velocity."""
            return (0.0, -p["k"] * s.v_c[0] * s.in_contact, 0.0)

    if USER not in registered_effects():
        @register_effect(USER, params={"c": Param(10.0, -200.0, 200.0, "N·s/m", "")})
        def _user(o, s, p):
            """The user's guess: lateral force −c·v_x on the sole."""
            return (0.0, -p["c"] * s.v_c[0] * s.in_contact, 0.0)


def run_seed(root: Path, seed: int, steps: int, reuse: bool) -> dict:
    from granular_mpc.validation.diagnose import diagnose
    from granular_mpc.validation.replay import validate
    from granular_mpc.validation.synth import noisy_copy, synthesize

    clean, noisy = root / f"s{seed}_clean", root / f"s{seed}_noisy"
    if not (reuse and (clean / "meta.yaml").is_file()):
        synthesize("sand_walk", clean, speeds=SPEEDS, steps=steps, seed=seed,
                   effects=[f"{HIDDEN}:k={TRUE_K:g}"], noise=0.0, format="parquet",
                   overwrite=True)
    if not (reuse and (noisy / "meta.yaml").is_file()):
        noisy_copy(clean, noisy, 1.0, seed=seed, overwrite=True)
    d = diagnose(noisy, root / f"s{seed}_diag", candidates=LIBRARY + [USER], n_boot=60)
    entry = next(e for e in d.ranking if e.effect == USER)
    c = d.fitted_effects.get(USER, {}).get("c")
    row = {"seed": seed, "added": ",".join(d.added) or "-", "c": c,
           "heldout_red": entry.heldout_error_reduction, "effect_size": entry.effect_size}
    if c is not None:
        v = validate(noisy, root / f"s{seed}_val", effects=[USER], params=root / f"s{seed}_diag",
                     n_boot=100)
        ba = v.report["before_after"]
        for ch in ("intrusion_y", "grf_y"):
            row[f"{ch}_before"], row[f"{ch}_after"] = ba[ch]["before"], ba[ch]["after"]
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(24, 34)))
    ap.add_argument("--steps", type=int, default=7, help="stances per trial (3 trials)")
    ap.add_argument("--out", type=Path, default=None, help="keep data and reports here")
    ap.add_argument("--reuse", action="store_true", help="with --out: reuse data sets there")
    ap.add_argument("--json", default=None, help="also write the figures here")
    args = ap.parse_args()
    _register()
    tmp = None
    if args.out is None:
        tmp = tempfile.TemporaryDirectory(prefix="user_term_")
        root = Path(tmp.name)
    else:
        root = args.out
        root.mkdir(parents=True, exist_ok=True)
    rows = []
    for seed in args.seeds:
        r = run_seed(root, seed, args.steps, args.reuse)
        rows.append(r)
        fit = "-" if r["c"] is None else f"{r['c']:.2f}"
        iy = (f"intrusion_y {1e3 * r['intrusion_y_before']:.2f} → {1e3 * r['intrusion_y_after']:.2f} mm"
              if "intrusion_y_before" in r else "")
        print(f"seed {seed}: added {r['added']:<14s} c {fit} (true {TRUE_K:g})  held-out "
              f"{r['heldout_red']:+.0%}  size {r['effect_size']:.2f} σ  {iy}", flush=True)
    n = len(rows)
    found = [r for r in rows if r["added"].split(",")[0] == USER]
    figures = {
        "added_rate": len(found) / n,
        "c_within_30pct_rate": sum(abs(r["c"] - TRUE_K) <= 0.3 * TRUE_K for r in found) / n,
        "intrusion_y_reduction_min": min((1 - r["intrusion_y_after"] / r["intrusion_y_before"]
                                          for r in found), default=float("nan")),
        "effect_size_min": min(r["effect_size"] for r in rows),
        "effect_size_max": max(r["effect_size"] for r in rows),
        "heldout_reduction_min": min(r["heldout_red"] for r in rows),
        "cases": n,
    }
    emit(figures, None)
    if args.json:
        Path(args.json).write_text(json.dumps({"figures": figures, "rows": rows}, indent=2),
                                   encoding="utf-8")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
