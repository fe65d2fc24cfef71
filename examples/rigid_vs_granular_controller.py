"""Same sand plant, two controllers: one that knows the ground is sand, one that thinks
it is rigid.

The plant is always dry sand (``terrain: dry_sand``). Only the controller's ground model
changes (``controller.terrain``): ``plant`` → the granular model (sinkage-aware force
limits, CoM lowered by the expected sinkage, footholds narrowed to the lateral capacity);
``rigid`` → rigid ground with Coulomb friction. Prints a small comparison table
(Markdown).

    python examples/rigid_vs_granular_controller.py
    GRANULAR_MPC_EXAMPLE_SECONDS=2 python examples/rigid_vs_granular_controller.py   # CI

The command-line equivalent of the second run:
``granular-mpc run sim/sand_walk.yaml --set controller.terrain=rigid``.
"""

import os
from pathlib import Path

from granular_mpc.runner import run_scenario
from granular_mpc.scenario import load_scenario

seconds = float(os.environ.get("GRANULAR_MPC_EXAMPLE_SECONDS", "8"))
root = Path(os.environ.get("GRANULAR_MPC_EXAMPLE_OUT", "runs/examples")) / "rigid_vs_granular"

rows = []
for controller_terrain in ("plant", "rigid"):
    scenario = load_scenario("sand_walk", [f"controller.terrain={controller_terrain}",
                                           f"sim.duration={seconds}", "output.plots=false"])
    s = run_scenario(scenario, root / controller_terrain, progress=False,
                     overwrite=True).summary
    rows.append(s)


def fmt(x, spec=".3f"):
    return "-" if x is None else (("yes" if x else "no") if isinstance(x, bool) else format(x, spec))


print(f"plant: {rows[0]['terrain']}, commanded speed {rows[0]['commanded_speed_mps']} m/s, "
      f"{seconds:g} s")
print("| controller terrain | fell | mean speed [m/s] | CoT | peak sinkage [mm] | slip [mm] | max pitch [deg] | QP failures |")
print("|---|---|---|---|---|---|---|---|")
for s in rows:
    print(f"| {s['controller_terrain_model']} ({s['controller_terrain_kind']}) | {fmt(s['fell'])} "
          f"| {fmt(s['mean_speed_mps'])} | {fmt(s['cot'])} | {fmt(s['sinkage_peak_mm_mean'], '.1f')} "
          f"| {fmt(s['slip_mm_mean'], '.1f')} | {fmt(s['max_pitch_deg'], '.1f')} | {s['qp_failures']} |")
