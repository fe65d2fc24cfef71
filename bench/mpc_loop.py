"""Where the MPC tick of the closed loop goes: its stages timed inside the running loop.

    python bench/mpc_loop.py [--seconds 10] [--speed 0.2] [--terrain dry_sand] [--json PATH]

``bench/controller.py``'s ``mpc_tick_ms_median`` is the loop's own record of an MPC tick
(``TickRecord.total_ms``: the horizon set-up, ``CentroidalMPC.solve`` and the record). This
script runs the same closed loop (``sim/sand_walk.yaml``, run from the repository root) and
splits every MPC tick into

- ``horizon``: :func:`~granular_mpc.control.horizon.plan_horizon` (the contact plan,
  supports, references and capacities of the N steps);
- ``assembly``: building the QP (``MPCPlan.build_ms``: the compiled condensation);
- ``proxsuite_call``: our wrapper's call (``MPCPlan.solve_ms``: finiteness check,
  ProxSuite's ``update`` and ``solve``, the solution copied out), of which ProxSuite's own
  timers (``compute_timings``) give ``proxsuite_setup`` (its model update and scaling) and
  ``proxsuite_kernel`` (its iterations);
- ``readout``: the rest of ``CentroidalMPC.solve`` — the active (step, foot) pairs, the
  QP's finiteness check, and the plan from the solution (forces, predicted states and
  sinkage);
- ``glue``: the rest of the tick (the state vector, the yaw wrap, the record).

Figures are medians over the run's MPC ticks (the first, a cold start, excluded) [ms];
``mpc_tick_ms_median_without_horizon_readout`` is the tick less its horizon set-up and
read-out — what the tick would be if both cost nothing, a bound on what work outside
ProxSuite and the assembly can give. ProxSuite's timers do not change its numbers: the
run's ``final_x_m`` is ``bench/controller.py``'s. Also the ProxSuite iterations and μ
updates per solve (mean) and the 1-min load before and after (``/proc/loadavg``).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time

import numpy as np
from _report import emit


def loop_stages(seconds: float, speed: float, terrain: str) -> dict:
    """Per MPC tick of one closed-loop run: each stage's time [ms] (lists, first tick
    included), ProxSuite's iterations and μ updates, and the run's final CoM x [m]."""
    import granular_mpc.control.controller as controller_module
    from granular_mpc.control.mpc import CentroidalMPC
    from granular_mpc.control.solvers.proxqp import ProxQPSolver
    from granular_mpc.runner import build_simulation, closed_loop
    from granular_mpc.scenario import load_scenario

    overrides = [f"terrain={terrain}", f"command.speed={speed}", f"sim.duration={seconds}"]
    sim = build_simulation(load_scenario("sim/sand_walk.yaml", overrides))
    state = sim.new_state()
    mpc_data = state.controller.mpc
    if not isinstance(mpc_data.solver, ProxQPSolver):
        raise SystemExit(f"bench/mpc_loop.py profiles the ProxSuite MPC; this scenario's MPC "
                         f"solves with {type(mpc_data.solver).__name__}")
    mpc_data.solver = dataclasses.replace(mpc_data.solver, timings=True)
    horizon_ms, solve_ms, plans, sols = [], [], [], []
    plan_horizon, mpc_solve = controller_module.plan_horizon, CentroidalMPC.solve
    solver_solve = mpc_data.solver.solve

    def timed_horizon(*args, **kwargs):
        t0 = time.perf_counter()
        out = plan_horizon(*args, **kwargs)
        horizon_ms.append((time.perf_counter() - t0) * 1e3)
        return out

    def timed_solve(self, data, **kwargs):
        t0 = time.perf_counter()
        plan = mpc_solve(self, data, **kwargs)
        solve_ms.append((time.perf_counter() - t0) * 1e3)
        plans.append(plan)
        return plan

    def recorded(problem):
        sol = solver_solve(problem)
        sols.append(sol)
        return sol

    controller_module.plan_horizon, CentroidalMPC.solve = timed_horizon, timed_solve
    mpc_data.solver.solve = recorded
    try:
        for _ in closed_loop(sim, state):
            pass
    finally:
        controller_module.plan_horizon, CentroidalMPC.solve = plan_horizon, mpc_solve
    ticks = [r.total_ms for r in state.controller.records if r.kind == "mpc"]
    if not (len(ticks) == len(horizon_ms) == len(solve_ms) == len(sols)):
        raise RuntimeError("the MPC ticks and their stages do not line up "
                           f"({len(ticks)}, {len(horizon_ms)}, {len(solve_ms)}, {len(sols)})")
    build = [p.build_ms for p in plans]
    call = [p.solve_ms for p in plans]
    return {
        "tick": ticks, "horizon": horizon_ms, "assembly": build, "proxsuite_call": call,
        "proxsuite_setup": [s.setup_ms for s in sols],
        "proxsuite_kernel": [s.kernel_ms for s in sols],
        "readout": [s - b - c for s, b, c in zip(solve_ms, build, call)],
        "glue": [t - h - s for t, h, s in zip(ticks, horizon_ms, solve_ms)],
        "iterations": [s.iterations for s in sols], "mu_updates": [s.mu_updates for s in sols],
        "final_x_m": float(state.plant.q[0]),
    }


def stage_figures(stages: dict) -> dict:
    """The medians (first tick excluded) of :func:`loop_stages`' lists."""
    med = {k: float(np.median(stages[k][1:])) for k in
           ("tick", "horizon", "assembly", "proxsuite_call", "proxsuite_setup",
            "proxsuite_kernel", "readout", "glue")}
    bound = np.asarray(stages["tick"][1:]) - np.asarray(stages["horizon"][1:]) \
        - np.asarray(stages["readout"][1:])
    out = {f"mpc_{k}_ms_median": v for k, v in med.items()}
    out["mpc_tick_ms_p99"] = float(np.percentile(stages["tick"][1:], 99))
    out["mpc_tick_ms_median_without_horizon_readout"] = float(np.median(bound))
    out["proxsuite_iterations_mean"] = float(np.mean(stages["iterations"][1:]))
    out["proxsuite_mu_updates_mean"] = float(np.mean(stages["mu_updates"][1:]))
    out["mpc_ticks"] = len(stages["tick"])
    out["final_x_m"] = stages["final_x_m"]
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--speed", type=float, default=0.2)
    ap.add_argument("--terrain", default="dry_sand")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    figs = stage_figures(loop_stages(args.seconds, args.speed, args.terrain))
    figs["load_before"], figs["load_after"] = load0, os.getloadavg()[0]
    emit(figs, args.json, units={"_ms_median": "ms", "_ms_p99": "ms", "_m": "m",
                                "_without_horizon_readout": "ms"})
    return figs


if __name__ == "__main__":
    main()
