"""The paper protocol's fallback, measured: the paper's gait recorded on rigid ground and
replayed by joint PD (``mode: playback``) on rigid ground, on the paper's track and on sand.

    python bench/playback.py [--speeds 0.2] [--out runs/playback] [--json PATH]

For each speed: (1) record ``sim/paper_protocol.yaml`` on rigid ground (the paper's gait,
the rigid-ground MPC-WBC, 20 s); (2) replay its joint references with
``sim/paper_playback.yaml`` — pure joint PD at three stiffnesses, and PD plus the recorded
torques — on rigid ground, on the paper's track and on dry sand; (3) the same torque replay
on rigid ground on the other plant (reference instead of compiled: the same physics, a
last-bit difference), to measure how fast an open-loop replay leaves its recording.
Prints, per case and speed, ``fall_<case>_<v>_s`` (the fall time; the run's duration when it
walked the whole run), ``mean_speed_<case>_<v>_mps``, ``peak_sinkage_<case>_<v>_mm`` and,
for (3), ``torque_replay_leaves_recording_<v>_s``: when the replay's joint angles or trunk
position first differ from the recording's by more than 1 mm / 1 mrad.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from _report import emit

CASES = {
    # name: (terrain, kp, kd, feedforward, plant)
    "rigid_pd150": ("rigid", 150.0, 3.0, False, None),
    "rigid_pd400": ("rigid", 400.0, 5.0, False, None),
    "rigid_pd1000": ("rigid", 1000.0, 10.0, False, None),
    "rigid_pd150_ff": ("rigid", 150.0, 3.0, True, None),
    "rigid_pd150_ff_reference_plant": ("rigid", 150.0, 3.0, True, "reference"),
    "track_pd150": ("paper_track", 150.0, 3.0, False, None),
    "track_pd150_ff": ("paper_track", 150.0, 3.0, True, None),
    "sand_pd150_ff": ("dry_sand", 150.0, 3.0, True, None),
}


def run(config: str, out: Path, overrides: list[str]) -> dict:
    from granular_mpc.runner import run_scenario
    from granular_mpc.scenario import load_scenario

    return run_scenario(load_scenario(config, overrides), out, progress=False,
                        overwrite=True).summary


def divergence_s(a_dir: Path, b_dir: Path, tol: float = 1e-3) -> float:
    """First time [s] the joint angles or trunk position of two runs differ by > ``tol``."""
    from granular_mpc.runlog import read_log

    a, b = read_log(a_dir), read_log(b_dir)
    n = min(len(a), len(b))
    cols = [c for c in a.columns if c.startswith("q_") or c in ("base_x", "base_y", "base_z")]
    d = np.abs(a[cols].to_numpy()[:n] - b[cols].to_numpy()[:n]).max(axis=1)
    over = np.flatnonzero(d > tol)
    return float(a["time"].iloc[over[0]]) if over.size else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--speeds", type=float, nargs="+", default=[0.2])
    ap.add_argument("--out", type=Path, default=Path("runs/playback"))
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    figures: dict = {}
    units: dict = {"_s": "s", "_mps": "m/s", "_mm": "mm"}
    for v in args.speeds:
        rec = args.out / f"record_{v:g}"
        s = run("sim/paper_protocol.yaml", rec, ["terrain=rigid", f"command.speed={v}"])
        figures[f"fall_record_{v:g}_s"] = s["fall_time_s"] if s["fell"] else s["sim_time_s"]
        figures[f"mean_speed_record_{v:g}_mps"] = s["mean_speed_mps"]
        for name, (terrain, kp, kd, ff, plant) in CASES.items():
            over = [f"playback.reference={rec}", f"terrain={terrain}", f"playback.kp={kp}",
                    f"playback.kd={kd}", f"playback.feedforward={str(ff).lower()}"]
            if terrain == "dry_sand":
                over.append("initial_clearance=-0.005")
            if plant:
                over.append(f"sim.plant={plant}")
            s = run("sim/paper_playback.yaml", args.out / f"{name}_{v:g}", over)
            figures[f"fall_{name}_{v:g}_s"] = s["fall_time_s"] if s["fell"] else s["sim_time_s"]
            figures[f"mean_speed_{name}_{v:g}_mps"] = s["mean_speed_mps"]
            figures[f"peak_sinkage_{name}_{v:g}_mm"] = s["sinkage_peak_mm_mean"]
            print(f"# {v:g} m/s {name}: {'falls at %.3f s' % s['fall_time_s'] if s['fell'] else 'walks'}",
                  flush=True)
        figures[f"torque_replay_leaves_recording_{v:g}_s"] = divergence_s(
            args.out / f"rigid_pd150_ff_{v:g}", args.out / f"rigid_pd150_ff_reference_plant_{v:g}")
    emit(figures, args.json, units)


if __name__ == "__main__":
    main()
