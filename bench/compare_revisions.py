"""Controller figures of two package trees side by side: interleaved runs, medians.

    python bench/compare_revisions.py --old /tmp/C_base --new . [--seconds 5] [--reps 3]
        [--speed 0.2] [--terrain dry_sand] [--proxsuite generic] [--json PATH]

Each repetition runs the same closed loop (``sim/sand_walk.yaml``, plant at 2 kHz, WBC at
500 Hz, MPC at 40 Hz) once on the old tree and once on the new one, each in a fresh
subprocess with that tree first on ``PYTHONPATH`` and as working directory (two versions of
one package, and two ProxSuite builds, cannot share a process). The order alternates
between repetitions (old-new, new-old, ...), so a load change on a shared machine hits both
alike. The measuring code is this file's, the same for both trees, and uses public names
only: ``granular_mpc.scenario.load_scenario``, ``granular_mpc.runner.build_simulation``,
``granular_mpc.runner.closed_loop`` and the controller's tick records.

Prints, per figure, the old and new medians over the repetitions and new/old, plus the load
average (``os.getloadavg``: 1, 5, 15 min) before and after; ``--json`` writes them too.
Figures are those of ``bench/controller.py`` (``mpc_solve_ms_median`` … ``realtime_factor``)
plus the simulated speed, peak sinkage and CoT-relevant sums so behaviour can be compared.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))

#: runs inside the subprocess: argv = bench folder, seconds, speed, terrain; prints one
#: JSON line with :func:`bench/controller.py:closed_loop_figures` (one measuring code)
_MEASURE = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
from controller import closed_loop_figures
out = closed_loop_figures(float(sys.argv[2]), float(sys.argv[3]), sys.argv[4])
print("RESULT " + json.dumps(out))
"""


def measure(tree: str, seconds: float, speed: float, terrain: str, env: dict) -> dict:
    """One closed-loop run on ``tree`` in a fresh subprocess; its figures."""
    tree = os.path.abspath(tree)
    e = dict(env, PYTHONPATH=tree + os.pathsep + env.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-c", _MEASURE, BENCH_DIR, str(seconds), str(speed),
                           terrain],
                          cwd=tree, env=e, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"run on {tree} failed:\n{proc.stderr[-3000:]}")
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT "))
    return json.loads(line[len("RESULT "):])


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=True, help="package tree of the reference revision")
    ap.add_argument("--new", default=".", help="package tree of the revision under test")
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated time per run [s]")
    ap.add_argument("--reps", type=int, default=3, help="runs per tree (interleaved)")
    ap.add_argument("--speed", type=float, default=0.2, help="commanded speed [m/s]")
    ap.add_argument("--terrain", default="dry_sand", help="plant terrain (models/terrain)")
    ap.add_argument("--proxsuite", default=None, choices=("native", "generic"),
                    help="GRANULAR_MPC_PROXSUITE for both trees (default: inherited)")
    ap.add_argument("--json", default=None, help="also write the medians to this JSON file")
    args = ap.parse_args(argv)

    env = dict(os.environ, MPLBACKEND="Agg")
    if args.proxsuite:
        env["GRANULAR_MPC_PROXSUITE"] = args.proxsuite
    load_before = os.getloadavg()
    print(f"load before: {load_before[0]:.2f} {load_before[1]:.2f} {load_before[2]:.2f}",
          flush=True)
    runs: dict[str, list[dict]] = {"old": [], "new": []}
    t0 = time.perf_counter()
    for rep in range(args.reps):
        order = ("old", "new") if rep % 2 == 0 else ("new", "old")
        for which in order:
            tree = args.old if which == "old" else args.new
            runs[which].append(measure(tree, args.seconds, args.speed, args.terrain, env))
            print(f"  rep {rep + 1}/{args.reps} {which}: "
                  f"mpc_tick {runs[which][-1]['mpc_tick_ms_median']:.3f} ms, "
                  f"wbc_tick {runs[which][-1]['wbc_tick_ms_median']:.3f} ms, "
                  f"rtf {runs[which][-1]['realtime_factor']:.3f}", flush=True)
    load_after = os.getloadavg()
    keys = [k for k, v in runs["old"][0].items() if isinstance(v, float)]
    result: dict = {"reps": args.reps, "seconds": args.seconds,
                    "load_before": list(load_before), "load_after": list(load_after),
                    "proxsuite_build": runs["new"][0]["proxsuite_build"],
                    "wall_s": time.perf_counter() - t0, "old": {}, "new": {}}
    print(f"{'figure':24s} {'old':>10s} {'new':>10s} {'new/old':>8s}")
    for k in keys:
        o = float(np.median([r[k] for r in runs["old"]]))
        n = float(np.median([r[k] for r in runs["new"]]))
        result["old"][k], result["new"][k] = o, n
        ratio = n / o if o else float("nan")
        print(f"{k:24s} {o:10.4g} {n:10.4g} {ratio:8.3f}")
    print(f"proxsuite_build: {result['proxsuite_build']}")
    print(f"load after: {load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=2)
    return result


if __name__ == "__main__":
    main()
