"""Standing on sand for 10 s: does the sinkage settle, does the robot drift?

    python bench/standing.py [--seconds 10] [--json PATH]

The semi-cylindrical soles roll, so the robot cannot stand still on PD alone (the CoM
over a rolling contact line is an inverted pendulum); "standing" is stepping in place at
a commanded speed of 0 (sim/stand_sand.yaml). Figures: whether it fell, the horizontal
drift of the CoM over the run after the weight shift, the mean per-stance peak sinkage in
the first and last 2 s, and the slope of peak sinkage against time (mm/s) — settled
means a slope near zero (every step lands in fresh sand and sinks to the same depth).
"""

from __future__ import annotations

import argparse

import numpy as np
from _report import emit


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)

    import pandas as pd

    from granular_mpc.analysis import segment_stances
    from granular_mpc.runner import build_simulation, closed_loop
    from granular_mpc.scenario import load_scenario

    sim = build_simulation(load_scenario("sim/stand_sand.yaml", [f"sim.duration={args.seconds}"]))
    state = sim.new_state()
    log = pd.DataFrame.from_records(list(closed_loop(sim, state)))
    start = sim.controller.schedule.start + 0.5
    after = log[log.time >= start]
    drift = float(np.hypot(after.com_x.iloc[-1] - after.com_x.iloc[0],
                           after.com_y.iloc[-1] - after.com_y.iloc[0]))
    peaks = []
    for seg in segment_stances(log).itertuples():
        if seg.t_start < start or not seg.complete:
            continue
        part = log.iloc[seg.row_start:seg.row_stop]
        peaks.append((seg.t_start, float(part.intrusion_z.max()) * 1e3))
    peaks = np.array(peaks)
    t_end = log.time.iloc[-1]
    early = peaks[peaks[:, 0] < start + 2.0, 1]
    late = peaks[peaks[:, 0] > t_end - 2.0, 1]
    slope = float(np.polyfit(peaks[:, 0], peaks[:, 1], 1)[0]) if len(peaks) > 3 else float("nan")
    figures = {
        "standing_fell": float(state.fall is not None),
        "standing_drift_m": drift,
        "standing_sinkage_first_2s_mm": float(early.mean()) if len(early) else float("nan"),
        "standing_sinkage_last_2s_mm": float(late.mean()) if len(late) else float("nan"),
        "standing_sinkage_slope_mm_per_s": slope,
        "standing_stances": float(len(peaks)),
    }
    emit(figures, args.json, {"_m": "m", "_mm": "mm", "_per_s": "mm/s"})
    return figures


if __name__ == "__main__":
    main()
