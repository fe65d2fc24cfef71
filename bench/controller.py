"""Controller benchmark: solve times and real-time factor of the closed loop on sand.

    python bench/controller.py [--seconds 10] [--speed 0.2] [--terrain dry_sand] [--json PATH]
    python bench/controller.py --plant both --repeat 3     # reference vs compiled plant

``--plant`` chooses the plant of the closed loop (``sim.plant``: ``compiled``, the
default, or ``reference``); ``both`` runs the two alternately in this process ``--repeat``
times and prints each figure's median with the plant as a suffix (``realtime_factor_reference``,
``realtime_factor_compiled`` …), plus the machine load before and after.

Prints one ``name: value unit`` line per figure. The closed loop is the runner's own
(:func:`granular_mpc.runner.closed_loop`: plant at 2 kHz, WBC at 500 Hz, MPC at 40 Hz, a
log row per WBC tick kept in memory), so the real-time factor is what ``granular-mpc run``
achieves before plots and HTML. ``*_solve_ms`` is the ProxSuite solve alone; ``*_tick_ms``
adds building the QP in Python (the MPC's condensation, the WBC's Pinocchio terms).

Where the time goes (cProfile, sand, 0.2 m/s; before the lean tick of issue 12): the WBC
tick ≈ 45 % (Pinocchio terms and QP assembly in NumPy, ~0.7 ms), the plant ≈ 25 % (2000
steps of ~65 µs), logging ≈ 15 % (one PlantRecorder row per WBC tick), the MPC ≈ 10 % (40
ticks of ~2.5 ms). The lean tick builds both QPs in preallocated buffers without per-point
Python loops (one ``computeAllTerms`` per WBC tick, the MPC's condensed matrices from
broadcast blocks) and solves the MPC's QP with ProxSuite's primal-dual LDLT backend (half
the warm-started iterations of the automatic choice); what is left is ProxSuite's solve
(MPC) and NumPy's per-call overhead on 24×24 arrays (WBC). One BLAS thread: the matrices
are tiny and threading costs more than it saves (MPC tick 16 → 2.4 ms). Since then the
WBC's assembly is generated C (``control/wbc_qp.py``) and the plant compiled: of a 4 s walk
the WBC's ProxSuite solves ≈ 16 %, the controller's remaining Python ≈ 18 %, the compiled
assembly with Pinocchio ≈ 10 %, the plant ≈ 11 %, the log rows ≈ 10 % (docs/speed.md).
``mpc_solve_ms_mean`` and ``realtime_factor_without_mpc_solve`` separate the code's speed
from the realisation's rare slow MPC solves (≈ 50–100 ms each, where the loop meets them).
``realtime_factor_cpu`` divides the simulated time by the process's CPU time instead of the
wall time: on a machine shared with other jobs it moves far less with their load (the wall
clock also counts the time the process waits for a core). Since the chunked plant steps
and leaner rows (docs/speed.md, "Second pass"), the plant steps between two controller ticks
are one call and the log row is built from whole arrays.
``proxsuite_build`` names the ProxSuite binding in use: ``GRANULAR_MPC_PROXSUITE=generic``
selects the bit-reproducible build (≈ 30 % slower MPC solves, docs/user-guide.md).
Two revisions side by side: ``bench/compare_revisions.py``.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _report import emit


def closed_loop_figures(seconds: float, speed: float, terrain: str, plant: str | None = None) -> dict:
    """Solver times and real-time factor of one closed-loop run of ``sim/sand_walk.yaml``
    (run from the repository root). Also used by ``bench/compare_revisions.py``, whose
    subprocesses import this file so that old and new trees are measured by one code."""
    from granular_mpc.control.solvers.proxqp import proxsuite_build
    from granular_mpc.runner import build_simulation, closed_loop
    from granular_mpc.scenario import load_scenario

    overrides = [f"terrain={terrain}", f"command.speed={speed}", f"sim.duration={seconds}"]
    if plant is not None:
        overrides.append(f"sim.plant={plant}")
    scenario = load_scenario("sim/sand_walk.yaml", overrides)
    sim = build_simulation(scenario)
    state = sim.new_state()
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in closed_loop(sim, state):
        pass
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    records = state.controller.records
    mpc = [r for r in records if r.kind == "mpc"]
    wbc = [r for r in records if r.kind == "wbc"]
    sim_time = state.plant.t
    return {
        "mpc_solve_ms_median": float(np.median([r.solve_ms for r in mpc])),
        "mpc_solve_ms_p99": float(np.percentile([r.solve_ms for r in mpc], 99)),
        "mpc_tick_ms_median": float(np.median([r.total_ms for r in mpc])),
        "mpc_tick_ms_p99": float(np.percentile([r.total_ms for r in mpc], 99)),
        "wbc_solve_ms_median": float(np.median([r.solve_ms for r in wbc])),
        "wbc_solve_ms_p99": float(np.percentile([r.solve_ms for r in wbc], 99)),
        "wbc_tick_ms_median": float(np.median([r.total_ms for r in wbc])),
        "wbc_tick_ms_p99": float(np.percentile([r.total_ms for r in wbc], 99)),
        "mpc_rate_hz": len(mpc) / max(sim_time - sim.controller.schedule.start, 1e-9),
        "wbc_rate_hz": len(wbc) / sim_time,
        "realtime_factor": sim_time / wall,
        # the MPC's rare slow solves (warm-started ProxSuite running into thousands of inner
        # iterations, ≈ 50–100 ms each) depend on the realisation of the closed loop, which
        # rounding-level changes anywhere alter: the mean solve and the real-time factor
        # without the MPC's solve time separate the code's speed from that luck
        "mpc_solve_ms_mean": float(np.mean([r.solve_ms for r in mpc])),
        "realtime_factor_without_mpc_solve":
            sim_time / max(wall - 1e-3 * sum(r.solve_ms for r in mpc), 1e-9),
        # simulated time per second of this process's CPU time (one BLAS thread, so about
        # one core): on a machine shared with other jobs far steadier than the wall-clock
        # real-time factor, which counts the time the process waits for a core
        "realtime_factor_cpu": sim_time / max(cpu, 1e-9),
        "qp_failures": float(state.controller.qp_failures),
        "fell": float(state.fall is not None),
        "final_x_m": float(state.plant.q[0]),
        "proxsuite_build": proxsuite_build(),
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated time [s]")
    ap.add_argument("--speed", type=float, default=0.2, help="commanded speed [m/s]")
    ap.add_argument("--terrain", default="dry_sand", help="plant terrain (models/terrain)")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    ap.add_argument("--plant", choices=("compiled", "reference", "both"), default=None,
                    help="plant of the closed loop (default: sim.plant's default, compiled)")
    ap.add_argument("--repeat", type=int, default=1, help="runs per plant with --plant both")
    args = ap.parse_args(argv)

    if args.plant != "both":
        figures = closed_loop_figures(args.seconds, args.speed, args.terrain, args.plant)
    else:
        figures = {"load_before": os.getloadavg()[0]}
        runs: dict = {"reference": [], "compiled": []}
        for _ in range(max(1, args.repeat)):
            for plant in runs:
                runs[plant].append(closed_loop_figures(args.seconds, args.speed, args.terrain,
                                                       plant))
        for plant, rows in runs.items():
            for key, value in rows[0].items():
                if isinstance(value, float):
                    figures[f"{key}_{plant}"] = float(np.median([r[key] for r in rows]))
                else:
                    figures[f"{key}_{plant}"] = value
        figures["load_after"] = os.getloadavg()[0]
    emit(figures, args.json, {"_median": "ms", "_p99": "ms", "_hz": "Hz"})
    return figures


if __name__ == "__main__":
    main()
