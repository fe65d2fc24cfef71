"""Pairs of library effects: are both found when two are hidden at once?

    python bench/recovery_pairs.py [--pairs A:k=v+B:k=v …] [--seeds 1 2] [--level 1.0]
                                   [--steps 9] [--out DIR [--reuse]] [--json PATH]

The library's recovery study (``bench/recovery.py``) hides one effect per data set, the
out-of-library benchmark (``bench/out_of_library.py``) pairs a library effect with a form
outside the library. Here both hidden effects are library effects, at the recovery study's
default magnitudes: one plant run per pair and seed (``synth``, both effects, 5 speeds ×
``steps`` stances, no noise), one noisy copy at ``level``, one diagnosis with the whole
library as candidates. Per pair and effect: rank, added, main coefficient and its error
(``recovery.effect_figures``).

Figures (``name: value``): ``pair_both_added_rate`` — both effects added (issue 11's "both
effects of a pair found"); ``pair_member_rank_le2_rate`` — each member ranked first or
second; ``pair_member_coef_within_15pct_rate``; ``pair_wrong_added`` — effects added that
are not in the pair; ``pairs``.

The pairs were chosen before any was diagnosed: each joins two mechanisms of different
kinds (terrain force with joint, sensor, geometry; two terrain forces that both act at
unloading), at the magnitudes of ``recovery.DEFAULT_EFFECTS``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the helpers below, when imported

from _report import emit_study  # noqa: E402
from recovery import SPEEDS, effect_figures  # noqa: E402

DEFAULT_PAIRS = [
    "cohesion:suction=3000+joint_friction:coulomb=0.1,viscous=0.02",
    "depth_hardening:n=1.5+force_sensor_bias:bias_z=6",
    "inertial_drag:c_d=4+terrain_slope:slope_y=0.03",
    "elastic_unloading:pressure=4000+cohesion:suction=3000",
]


def split_pair(pair: str) -> list[str]:
    """``"A:k=v+B:k=v"`` → ``["A:k=v", "B:k=v"]`` (a ``+`` inside a number, ``1e+3``, is
    kept)."""
    parts, cur = [], ""
    for i, ch in enumerate(pair):
        if ch == "+" and cur and not cur[-1] in "eE":
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    if len(parts) != 2 or not all(parts):
        raise SystemExit(f"--pairs: {pair!r} is not two effects joined by '+' "
                         "(e.g. cohesion:suction=3000+terrain_slope:slope_y=0.03)")
    return parts


def run_pair(pair: str, seed: int, root: Path, level: float, steps: int,
             reuse: bool) -> dict:
    """Synthesise (or reuse) one pair's data set and diagnose it; the pair's row."""
    from granular_mpc.validation.diagnose import diagnose
    from granular_mpc.validation.synth import noisy_copy, synthesize

    effects = split_pair(pair)
    names = [e.split(":")[0] for e in effects]
    tag = f"{'+'.join(names)}_s{seed}"
    clean = root / f"{tag}_clean"
    if not (reuse and (clean / "meta.yaml").is_file()):
        synthesize("sand_walk", clean, speeds=SPEEDS, steps=steps, seed=seed, effects=effects,
                   noise=0.0, format="parquet", overwrite=True)
    data = root / f"{tag}_n{level:g}"
    if not (reuse and (data / "meta.yaml").is_file()):
        noisy_copy(clean, data, level, seed=seed, overwrite=True)
    t0 = time.perf_counter()
    diag = diagnose(data, root / f"{tag}_n{level:g}_diag", seed=seed, n_boot=100)
    members = [effect_figures(diag, e) | {"effect": e} for e in effects]
    return {"pair": pair, "seed": seed, "noise": level, "status": diag.verdict.status,
            "added": list(diag.added), "members": members,
            "both_added": all(m["added_self"] for m in members),
            "wrong_added": [a for a in diag.added if a not in names],
            "diagnose_s": time.perf_counter() - t0}


def pair_figures(rows: list[dict]) -> dict:
    members = [m for r in rows for m in r["members"]]

    def rate(xs, f):
        return sum(1 for x in xs if f(x)) / len(xs) if xs else float("nan")

    return {"pair_both_added_rate": rate(rows, lambda r: r["both_added"]),
            "pair_member_rank_le2_rate": rate(members, lambda m: m["rank"] <= 2),
            "pair_member_coef_within_15pct_rate":
                rate(members, lambda m: m["coef_err"] is not None and abs(m["coef_err"]) <= 0.15),
            "pair_wrong_added": sum(len(r["wrong_added"]) for r in rows),
            "pairs": len(rows)}


def pair_table(rows: list[dict]) -> str:
    lines = ["| pair | seed | verdict | added | member: rank, added, coefficient (true), error |",
             "|---|---|---|---|---|"]
    for r in rows:
        mem = "; ".join(f"{m['effect'].split(':')[0]}: {m['rank']}, "
                        f"{'yes' if m['added_self'] else 'no'}, {m['param']} = {m['coef']:.4g} "
                        f"({m['true']:g}), {m['coef_err']:+.0%}" for m in r["members"])
        lines.append(f"| `{r['pair']}` | {r['seed']} | {r['status']} | "
                     f"{', '.join(r['added']) or '–'} | {mem} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pairs", nargs="+", default=DEFAULT_PAIRS)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--level", type=float, default=1.0, help="noise level of the data")
    ap.add_argument("--steps", type=int, default=9, help="stances per trial (5 trials)")
    ap.add_argument("--out", type=Path, default=None, help="keep data and reports here")
    ap.add_argument("--reuse", action="store_true",
                    help="with --out: reuse data sets already there (re-diagnose only)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    for p in args.pairs:
        split_pair(p)
    tmp = tempfile.TemporaryDirectory()
    root = args.out or Path(tmp.name)
    root.mkdir(parents=True, exist_ok=True)
    rows = []
    for pair in args.pairs:
        for seed in args.seeds:
            r = run_pair(pair, seed, root, args.level, args.steps, args.reuse)
            rows.append(r)
            print(f"{pair:60s} seed {seed}  {r['status']:24s} added {','.join(r['added']) or '-'}"
                  f"  both {r['both_added']}  " + "  ".join(
                      f"{m['effect'].split(':')[0]} rank {m['rank']} {m['param']} "
                      f"{m['coef']:.4g} ({m['coef_err']:+.0%})" for m in r["members"])
                  + f"  [{r['diagnose_s']:.0f} s]", flush=True)
    print(pair_table(rows))
    emit_study(pair_figures(rows), rows, args.json)
    tmp.cleanup()


if __name__ == "__main__":
    main()
