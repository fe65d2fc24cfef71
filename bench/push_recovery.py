"""Push recovery: the largest trunk impulse the walking robot survives, per terrain and
direction.

    python bench/push_recovery.py [--speed 0.2] [--terrains dry_sand rigid] [--json PATH]

Protocol: walk at ``--speed`` for 4 s (steady gait), then a push of 0.1 s on the trunk at
the next mid-stance of either foot (world frame: forward +x or lateral +y, toward the
swing side is not distinguished), then 4 s more. "Recovered" = no fall (trunk height,
|roll|, |pitch| < 15°) until the end. The largest recovered impulse is found by
bisection on [0, 30] N·s to 0.25 N·s; each row prints ``push_max_impulse_<terrain>_<dir>:
value N·s``. Runs in a process pool (one run per core).
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor

from _report import emit


def survives(terrain: str, direction: str, impulse: float, speed: float) -> bool:
    from granular_mpc.runner import build_simulation, closed_loop
    from granular_mpc.scenario import load_scenario

    vec = [impulse, 0.0, 0.0] if direction == "forward" else [0.0, impulse, 0.0]
    push = f"pushes=[{{at: mid_stance, time: 4.0, impulse: {vec}, duration: 0.1}}]"
    scenario = load_scenario("sim/sand_walk.yaml", [
        f"terrain={terrain}", f"command.speed={speed}", "sim.duration=8.0", push])
    sim = build_simulation(scenario)
    state = sim.new_state()
    for _ in closed_loop(sim, state):
        pass
    return state.fall is None


def bisect(args) -> tuple[str, str, float]:
    terrain, direction, speed, hi, tol = args
    lo = 0.0
    if not survives(terrain, direction, 0.0, speed):
        return terrain, direction, float("nan")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if survives(terrain, direction, mid, speed):
            lo = mid
        else:
            hi = mid
    return terrain, direction, lo


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speed", type=float, default=0.2)
    ap.add_argument("--terrains", nargs="+", default=["dry_sand", "rigid"])
    ap.add_argument("--max", type=float, default=30.0, help="upper bound of the search [N·s]")
    ap.add_argument("--tol", type=float, default=0.25, help="bisection tolerance [N·s]")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    jobs = [(t, d, args.speed, args.max, args.tol) for t in args.terrains
            for d in ("forward", "lateral")]
    figures = {}
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for terrain, direction, value in pool.map(bisect, jobs):
            figures[f"push_max_impulse_{terrain}_{direction}"] = value
    emit(figures, args.json, {"": "N·s"})
    return figures


if __name__ == "__main__":
    main()
