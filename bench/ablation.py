"""Which granular-aware parts of the controller matter on sand: an ablation.

    python bench/ablation.py [--speeds 0.2 0.4] [--seconds 20] [--json PATH]

Runs the sand plant with controller variants and prints, per variant and speed, whether it
fell (and when), the mean speed and the mean peak sinkage:

* ``granular``             the granular-aware controller (defaults);
* ``granular_no_transfer`` the same without the load-transfer double support;
* ``granular_no_rate``     the same without the load-rate limit (max_sink_rate = 100 m/s);
* ``rigid``                the rigid-assumption controller (controller.terrain: rigid);
* ``rigid_with_transfer``  the rigid-assumption controller plus the sand's double support.

Lines ``ablation_<variant>_v<speed>_{fell_at_s,mean_speed_mps,sinkage_peak_mm}: value``
(``fell_at_s`` = −1 when the robot did not fall).
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

from _report import emit

VARIANTS = {
    "granular": [],
    "granular_no_transfer": ["controller.gait.load_transfer=0.0"],
    "granular_no_rate": ["controller.mpc.max_sink_rate=100.0"],
    "rigid": ["controller.terrain=rigid"],
    "rigid_with_transfer": ["controller.terrain=rigid", "controller.gait.load_transfer=0.039"],
}


def run(job):
    variant, speed, seconds = job
    from granular_mpc.runner import build_simulation, closed_loop, stance_metrics
    from granular_mpc.scenario import load_scenario

    overrides = [f"command.speed={speed}", f"sim.duration={seconds}"] + VARIANTS[variant]
    sim = build_simulation(load_scenario("sim/sand_walk.yaml", overrides))
    state = sim.new_state()
    rows = list(closed_loop(sim, state))
    import pandas as pd

    df = pd.DataFrame.from_records(rows)
    t_after = sim.scenario.command.start_delay + 2.0
    tail = df[df.time > t_after]
    mean_speed = float((tail.com_x.iloc[-1] - tail.com_x.iloc[0]) /
                       (tail.time.iloc[-1] - tail.time.iloc[0])) if len(tail) > 10 else math.nan
    metrics = stance_metrics(df)
    fell_at = state.fall.time if state.fall is not None else None
    return variant, speed, fell_at, mean_speed, metrics.get("sinkage_peak_mm_mean", math.nan)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=float, nargs="+", default=[0.2, 0.4])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS))
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    jobs = [(v, s, args.seconds) for v in args.variants for s in args.speeds]
    out = {}
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for variant, speed, fell_at, vmean, sink in pool.map(run, jobs):
            key = f"ablation_{variant}_v{speed}"
            out[f"{key}_fell_at_s"] = fell_at if fell_at is not None else -1.0
            out[f"{key}_mean_speed_mps"] = vmean
            out[f"{key}_sinkage_peak_mm"] = sink
    emit(out, args.json, {"_s": "s", "_mps": "m/s", "_mm": "mm"})
    return out


if __name__ == "__main__":
    main()
