"""MPC tick benchmark: assembly and ProxSuite solve of the centroidal MPC, timed apart.

    python bench/mpc.py [--seconds 4] [--speed 0.2] [--terrain dry_sand] [--reps 5] [--json PATH]
                        [--old-tree DIR]

Records the MPC's inputs (``CentroidalMPC.solve``'s arguments) over a closed-loop run of
``sim/sand_walk.yaml`` (run from the repository root), then replays them ``--reps`` times
through two MPC settings in this process, interleaved: ``old`` (forces in newtons,
ProxSuite's ``automatic`` backend, ``mu_in`` kept from solve to solve — the settings before
issue 12's MPC pass, still the default: ``controller.mpc.qp: newton``) and ``new``
(``controller.mpc.qp: scaled``, :data:`~granular_mpc.control.mpc.QP_SETTINGS`). Each
replay starts from a fresh :class:`MPCData` and warm-starts along the recorded ticks, as the
closed loop does; the assembly is identical in both (``QPNumerics.scaled`` only rescales it).
With ``--old-tree DIR`` (another checkout, e.g. ``git archive HEAD | tar -x -C DIR``) its
``granular_mpc/control/mpc.py`` and ``control/solvers/proxqp.py`` are loaded as modules of
this package (its own assembly, tick and ProxSuite wrapper; this tree's config and ground
model) and replayed too, interleaved,
with both settings: suffixes ``_oldtree`` (``scaled``) and ``_oldtree_newton``. Suffix
``_daqp``: ``controller.mpc.qp: daqp`` (the ``scaled`` QP solved by DAQP; its iterations are
active-set changes, not ProxSuite's). Suffix ``_rows``: ``controller.mpc.qp: scaled_rows``
(``scaled`` without the polytope rows the others imply: the same optimum, fewer rows).

Prints per setting (suffix ``_old``; no suffix = new): ``mpc_assembly_ms_median`` (building
the QP, ``MPCPlan.build_ms``), ``mpc_solve_ms_median`` / ``_p99`` (ProxSuite's update and
solve with our wrapper, ``MPCPlan.solve_ms``), ``mpc_tick_ms_median`` / ``_p99`` (the whole
``CentroidalMPC.solve``, read-out included: the figure the targets are judged on),
``mpc_assembly_solve_ms_median`` / ``_p99`` (per tick, assembly + ProxSuite call, the
issue's words; without the finiteness check and the plan's read-out),
``mpc_tick_cpu_ms_mean`` (process CPU time per tick, steadier on a shared machine), the
ProxSuite iterations per solve (median, max) and the distance of the planned forces from
the QP's optimum (a tight cold ProxSuite solve of the same QP,
``‖F − F*‖∞`` [N], median and max), plus the 1-min load before and after. Times are
medians over reps × ticks (the first tick of each replay, a cold start, excluded). With
``--old-tree``: ``mpc_plans_differing_oldtree`` (``_oldtree_newton``), the number of ticks
whose plan (forces, predicted states, predicted sinkage) differs in any bit between this
tree and the old one (first replay, same settings), and ``mpc_plan_force_diff_n_max_…``,
their largest force difference [N].
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time
from pathlib import Path

import numpy as np
from _report import emit
from threadpoolctl import threadpool_limits


def record_ticks(seconds: float, speed: float, terrain: str):
    """The MPC model of a sand-walk closed loop and the inputs of each of its MPC ticks."""
    from granular_mpc.control.mpc import CentroidalMPC
    from granular_mpc.runner import build_simulation, closed_loop
    from granular_mpc.scenario import load_scenario

    overrides = [f"terrain={terrain}", f"command.speed={speed}", f"sim.duration={seconds}"]
    sim = build_simulation(load_scenario("sim/sand_walk.yaml", overrides))
    state = sim.new_state()
    ticks = []
    solve = CentroidalMPC.solve

    def recording(self, data, **kw):
        ticks.append({k: np.array(v, copy=True) if isinstance(v, np.ndarray) else v
                      for k, v in kw.items()})
        return solve(self, data, **kw)

    CentroidalMPC.solve = recording
    try:
        for _ in closed_loop(sim, state):
            pass
    finally:
        CentroidalMPC.solve = solve
    return sim.controller.mpc, ticks


def old_settings(mpc):
    """The MPC with the QP settings before issue 12's MPC pass (same assembly)."""
    return mpc.with_qp("newton")


def new_settings(mpc):
    """The MPC with ``controller.mpc.qp: scaled`` (same assembly, rescaled)."""
    return mpc.with_qp("scaled")


def load_old_module(tree: str, relpath: str, name: str):
    """The file ``relpath`` of the checkout ``tree`` loaded as the module ``name`` (of this
    package, so its relative imports resolve to this tree)."""
    spec = importlib.util.spec_from_file_location(name, Path(tree) / relpath)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def old_tree_mpc(mpc, tree: str):
    """``mpc``'s model (same numbers) built by the ``CentroidalMPC`` of the checkout
    ``tree``: its ``control/mpc.py`` loaded as ``granular_mpc.control.mpc_oldtree``, with
    the ProxSuite wrapper of that checkout (``control/solvers/proxqp.py``, as
    ``granular_mpc.control.solvers.proxqp_oldtree``) in place of this tree's."""
    old_qp = load_old_module(tree, "granular_mpc/control/solvers/proxqp.py",
                             "granular_mpc.control.solvers.proxqp_oldtree")
    module = load_old_module(tree, "granular_mpc/control/mpc.py",
                             "granular_mpc.control.mpc_oldtree")
    for name in ("ProxQPSolver", "QPProblem", "QPStatus"):
        setattr(module, name, getattr(old_qp, name))
    return module.CentroidalMPC(mpc.config, mpc.mass, mpc.inertia_B, mpc.gravity, mpc.ground,
                                mpc.n_points, mpc.max_pairs)


def replay(mpc, ticks, keep_qps: bool = False) -> dict:
    """One warm-started pass over ``ticks``: per-tick times, iterations, forces (and QPs)."""
    data = mpc.new_data()
    solver_solve = data.solver.solve
    iters, qps, xs = [], [], []

    def counting(p):
        sol = solver_solve(p)
        iters.append(sol.iterations)
        if keep_qps:
            xs.append(sol.x)
            qps.append(tuple(None if a is None else np.array(a, copy=True)
                             for a in (p.H, p.g, p.C, p.l, p.u, p.lb, p.ub)))
        return sol

    data.solver.solve = counting
    build, solve, tick, forces, plans = [], [], [], [], []
    c0 = time.process_time()
    for kw in ticks:
        t0 = time.perf_counter()
        plan = mpc.solve(data, **kw)
        tick.append((time.perf_counter() - t0) * 1e3)
        build.append(plan.build_ms)
        solve.append(plan.solve_ms)
        forces.append(plan.forces)
        plans.append((plan.forces, plan.states, plan.sinkage))
    cpu = (time.process_time() - c0) * 1e3 / len(ticks)
    return {"build": build[1:], "solve": solve[1:], "tick": tick[1:], "cpu": cpu,
            "iters": iters[1:], "forces": forces, "plans": plans, "qps": qps, "xs": xs,
            "failures": data.failures}


def optimum_forces(mpc, qps) -> list:
    """The optimum of each recorded QP (cold ProxSuite solve, eps_abs = 1e-11) as forces [N]."""
    from granular_mpc.control.solvers.proxqp import ProxQPSolver, QPProblem

    out = []
    for H, g, C, l, u, lb, ub in qps:
        solver = ProxQPSolver(mpc.nu, 0, mpc.n_in, box=True, eps_abs=1e-11, max_iter=100000,
                              backend="primal_dual_ldlt")
        sol = solver.solve(QPProblem(H, g, None, None, C, l, u, lb, ub))
        out.append(sol.x * mpc.force_unit)
    return out


def figures(runs: dict, dist: dict, load: tuple) -> dict:
    out: dict = {"load_before": load[0]}
    for name, rows in runs.items():
        sfx = "" if name == "new" else f"_{name}"
        cat = {k: np.concatenate([r[k] for r in rows]) for k in ("build", "solve", "tick", "iters")}
        out[f"mpc_assembly_ms_median{sfx}"] = float(np.median(cat["build"]))
        out[f"mpc_solve_ms_median{sfx}"] = float(np.median(cat["solve"]))
        out[f"mpc_solve_ms_p99{sfx}"] = float(np.percentile(cat["solve"], 99))
        both = cat["build"] + cat["solve"]      # per tick: the "assembly + solve"
        out[f"mpc_assembly_solve_ms_median{sfx}"] = float(np.median(both))
        out[f"mpc_assembly_solve_ms_p99{sfx}"] = float(np.percentile(both, 99))
        out[f"mpc_tick_ms_median{sfx}"] = float(np.median(cat["tick"]))
        out[f"mpc_tick_ms_p99{sfx}"] = float(np.percentile(cat["tick"], 99))
        out[f"mpc_tick_cpu_ms_mean{sfx}"] = float(np.median([r["cpu"] for r in rows]))
        out[f"mpc_iterations_median{sfx}"] = float(np.median(cat["iters"]))
        out[f"mpc_iterations_max{sfx}"] = float(np.max(cat["iters"]))
        out[f"mpc_failures{sfx}"] = float(sum(r["failures"] for r in rows))
        out[f"mpc_force_error_n_median{sfx}"] = float(np.median(dist[name]))
        out[f"mpc_force_error_n_max{sfx}"] = float(np.max(dist[name]))
    out["load_after"] = os.getloadavg()[0]
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=4.0, help="simulated time recorded [s]")
    ap.add_argument("--speed", type=float, default=0.2, help="commanded speed [m/s]")
    ap.add_argument("--terrain", default="dry_sand", help="plant terrain (models/terrain)")
    ap.add_argument("--reps", type=int, default=5, help="replays per setting, interleaved")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    ap.add_argument("--old-tree", default=None,
                    help="another checkout whose control/mpc.py is replayed too")
    args = ap.parse_args(argv)

    with threadpool_limits(limits=1, user_api="blas"):   # as the closed loop runs
        mpc, ticks = record_ticks(args.seconds, args.speed, args.terrain)
        load0 = os.getloadavg()[0]
        models = {"new": new_settings(mpc), "old": old_settings(mpc),
                  "daqp": mpc.with_qp("daqp"), "rows": mpc.with_qp("scaled_rows")}
        if args.old_tree:
            old = old_tree_mpc(mpc, args.old_tree)
            models.update(oldtree=new_settings(old), oldtree_newton=old_settings(old))
        runs: dict = {name: [] for name in models}
        dist: dict = {}
        for rep in range(max(1, args.reps)):
            for name, model in models.items():
                r = replay(model, ticks, keep_qps=rep == 0)
                runs[name].append(r)
                if rep == 0:
                    dist[name] = force_errors(model, r)
    figs = figures(runs, dist, (load0,))
    figs["mpc_ticks"] = float(len(ticks))
    if args.old_tree:
        figs.update(plan_differences(runs["new"][0], runs["oldtree"][0], "_oldtree"))
        figs.update(plan_differences(runs["old"][0], runs["oldtree_newton"][0],
                                     "_oldtree_newton"))
    units = {}
    for sfx in ("_old", "", "_daqp", "_rows", "_oldtree", "_oldtree_newton"):
        units.update({f"_ms_median{sfx}": "ms", f"_ms_p99{sfx}": "ms", f"_ms_mean{sfx}": "ms",
                      f"_n_median{sfx}": "N", f"_n_max{sfx}": "N"})
    emit(figs, args.json, units)
    return figs


def plan_differences(run: dict, other: dict, suffix: str) -> dict:
    """How the plans of two replays of the same ticks differ: the number of ticks whose
    forces, predicted states or predicted sinkage are not bit for bit the same
    (``mpc_plans_differing``; signed zeros count as differing) and the largest force
    difference [N] (``mpc_plan_force_diff_n_max``)."""
    differing, worst = 0, 0.0
    for a, b in zip(run["plans"], other["plans"]):
        same = all(x.shape == y.shape and x.tobytes() == y.tobytes() for x, y in zip(a, b))
        differing += not same
        worst = max(worst, float(np.abs(a[0] - b[0]).max()))
    return {f"mpc_plans_differing{suffix}": float(differing),
            f"mpc_plan_force_diff_n_max{suffix}": worst}


def force_errors(mpc, run: dict) -> np.ndarray:
    """‖x − x*‖∞ · force unit [N] of each replayed solve (the first, cold, excluded): the
    solver's forces against a tight solve of the same QP."""
    best = optimum_forces(mpc, run["qps"])
    fu = mpc.force_unit
    return np.array([float(np.abs(x * fu - xb).max())
                     for x, xb in zip(run["xs"], best)])[1:]


if __name__ == "__main__":
    main()
