"""A tiny velocity sweep: CoT against speed on sand and on rigid ground (paper Fig. 6d).

Runs sim/velocity_sweep.yaml with two speeds in parallel (local process pool) and prints
one table row per run (mean speed, CoT, mean peak sinkage per stance, fell) and the CoT
ratio sand/rigid per speed (Markdown tables). The full
sweep is ``granular-mpc sweep sim/velocity_sweep.yaml``.

    python examples/velocity_sweep.py
    GRANULAR_MPC_EXAMPLE_SECONDS=1 python examples/velocity_sweep.py   # CI

Writes runs/examples/velocity_sweep/ (sweep.csv, cot_vs_speed.png when a run has a finite
CoT, runs/<run>/).
"""

import os
from pathlib import Path

from granular_mpc.runner import run_sweep
from granular_mpc.scenario import expand_sweep

seconds = float(os.environ.get("GRANULAR_MPC_EXAMPLE_SECONDS", "8"))
out = Path(os.environ.get("GRANULAR_MPC_EXAMPLE_OUT", "runs/examples")) / "velocity_sweep"

if __name__ == "__main__":     # the process pool re-imports this file (spawn)
    base, tasks = expand_sweep("velocity_sweep", ["sweep.speeds=[0.2, 0.4]",
                                                  f"sweep.duration={seconds}"])
    result = run_sweep(tasks, out, workers=2, progress=False, overwrite=True)
    t = result.table
    print(f"{len(t)} runs, {seconds:g} s each; table: {result.csv}")
    print("| terrain | speed [m/s] | mean speed [m/s] | CoT | peak sinkage [mm] | fell |")
    print("|---|---|---|---|---|---|")
    for r in t.itertuples(index=False):
        cot = "-" if r.cot != r.cot else f"{r.cot:.3f}"   # NaN → "-"
        sink = ("-" if r.sinkage_peak_mm_mean != r.sinkage_peak_mm_mean
                else f"{r.sinkage_peak_mm_mean:.2f}")
        print(f"| {r.terrain} | {r.commanded_speed_mps:.2f} | {r.mean_speed_mps:.3f} | {cot} "
              f"| {sink} | {'yes' if r.fell else 'no'} |")
    print()
    print("| series | speed [m/s] | CoT / CoT_rigid |")
    print("|---|---|---|")
    for r in result.ratio.itertuples(index=False):
        print(f"| {r.series} | {r.commanded_speed_mps:.2f} | {r.cot_ratio:.3f} |")
    print(f"plot: {result.plot or 'none'} ({result.plot_note})")
