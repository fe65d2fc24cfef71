"""Walk on dry sand in closed loop and print the run's key figures.

The plant is the full 3-D augmented model on dry sand (models/terrain/dry_sand.yaml); the
controller (centroidal-plus-sinkage MPC + WBC) uses the same granular model. This is what
``granular-mpc run sim/sand_walk.yaml`` does, from Python.

    python examples/walk_on_sand.py                                # the scenario's 20 s
    GRANULAR_MPC_EXAMPLE_SECONDS=2 python examples/walk_on_sand.py # short (CI)

Writes runs/examples/walk_on_sand/ (summary.json, config.resolved.yaml, log/, plots/);
``GRANULAR_MPC_EXAMPLE_OUT`` changes the parent folder. Prints one ``key: value`` line per
figure of the summary.
"""

import os
from pathlib import Path

from granular_mpc.runner import run_scenario
from granular_mpc.scenario import load_scenario

seconds = os.environ.get("GRANULAR_MPC_EXAMPLE_SECONDS")
overrides = [f"sim.duration={float(seconds)}"] if seconds else []
scenario = load_scenario("sand_walk", overrides)          # sim/sand_walk.yaml
out = Path(os.environ.get("GRANULAR_MPC_EXAMPLE_OUT", "runs/examples")) / "walk_on_sand"

result = run_scenario(scenario, out, progress=False, overwrite=True)

s = result.summary
for key in ("terrain", "controller_terrain_model", "commanded_speed_mps", "mean_speed_mps",
            "sim_time_s", "realtime_factor", "fell", "cot", "sinkage_peak_mm_mean",
            "slip_mm_mean", "max_pitch_deg", "complete"):
    print(f"{key}: {s[key]}")
print(f"plots: {len(result.plots)} in {out / 'plots'}")
