"""ProxSuite's settings on the MPC's own QPs: does any of them solve the tick faster?

    python bench/proxsuite_settings.py [--seconds 4] [--reps 3] [--variants NAME …] [--json PATH]

Records the MPC's QPs of a closed-loop sand walk (``bench/mpc.py``'s ``record_ticks`` and
``replay``, ``controller.mpc.qp: scaled``), then solves the sequence again, warm-started as
the loop does, with each variant of :data:`VARIANTS` (our :class:`ProxQPSolver` with the
MPC's sizes; a variant changes the tolerance, the μ_in restart, ProxSuite's backend or
one of its settings). Variants run interleaved, ``--reps`` times. Per variant: the ProxSuite
call's median and p99 time [ms] (first solve, a cold start, excluded; medians over reps ×
QPs), the mean iterations, the planned forces' distance from the QP's optimum (a tight
cold solve) as median and max ``‖F − F*‖∞`` [N], and the solves that did not end
``solved``. ``scaled`` is the default's own settings. The 1-min load before and after.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _report import emit
from mpc import new_settings, optimum_forces, record_ticks, replay
from threadpoolctl import threadpool_limits

#: variant name -> ProxQPSolver keyword arguments over the ``scaled`` default's
VARIANTS: dict[str, dict] = {
    "scaled": {},
    "eps_3e-5": {"eps_abs": 3e-5},
    "eps_1e-4": {"eps_abs": 1e-4},
    "eps_3e-4": {"eps_abs": 3e-4},
    "mu_in_reset_1": {"mu_in_reset": 1.0},
    "mu_in_reset_0.03": {"mu_in_reset": 0.03},
    "mu_in_reset_1e-3": {"mu_in_reset": 1e-3},
    "mu_in_kept": {"mu_in_reset": None},
    "mu_in_kept_min_1e-5": {"mu_in_reset": None, "settings": {"mu_min_in": 1e-5}},
    "rho_1e-7": {"settings": {"default_rho": 1e-7}},
    "rho_1e-5": {"settings": {"default_rho": 1e-5}},
    "infeasibility_check_100": {"settings": {"frequence_infeasibility_check": 100}},
    "refinement_1": {"settings": {"nb_iterative_refinement": 1}},
    "primal_ldlt": {"backend": "primal_ldlt"},
}


def solve_sequence(mpc, qps, optimum, **variant) -> dict:
    """Solve ``qps`` in order with one warm-started solver of the ``scaled`` settings
    changed by ``variant``: per QP its time [ms], iterations, status and force distance
    from ``optimum`` [N]."""
    from granular_mpc.control.mpc import QP_SETTINGS
    from granular_mpc.control.solvers.proxqp import ProxQPSolver, QPProblem

    base = QP_SETTINGS["scaled"]
    kwargs = {"eps_abs": base.eps_abs, "backend": base.backend,
              "mu_in_reset": base.mu_in_reset, "eps_primal_inf": base.eps_primal_inf}
    kwargs.update(variant)
    solver = ProxQPSolver(mpc.nu, 0, mpc.n_in, box=True, max_iter=100, multipliers=False,
                          **kwargs)
    times, iters, failed, dist = [], [], 0, []
    for (H, g, C, l, u, lb, ub), f_opt in zip(qps, optimum):
        sol = solver.solve(QPProblem(H, g, None, None, C, l, u, lb, ub))
        times.append(sol.solve_ms)
        iters.append(sol.iterations)
        failed += not sol.status.ok
        dist.append(float(np.abs(sol.x * mpc.force_unit - f_opt).max()))
    return {"times": times[1:], "iters": iters[1:], "failed": failed, "dist": dist}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("--speed", type=float, default=0.2)
    ap.add_argument("--terrain", default="dry_sand")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--variants", nargs="+", choices=list(VARIANTS), default=list(VARIANTS))
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    with threadpool_limits(1):
        mpc, ticks = record_ticks(args.seconds, args.speed, args.terrain)
        mpc = new_settings(mpc)
        qps = replay(mpc, ticks, keep_qps=True)["qps"]
        optimum = optimum_forces(mpc, qps)
        runs: dict[str, list] = {name: [] for name in args.variants}
        for _ in range(args.reps):
            for name in args.variants:
                runs[name].append(solve_sequence(mpc, qps, optimum, **VARIANTS[name]))
    figs: dict = {}
    for name, reps in runs.items():
        times = np.concatenate([r["times"] for r in reps])
        first = reps[0]
        figs[f"{name}_solve_ms_median"] = float(np.median(times))
        figs[f"{name}_solve_ms_p99"] = float(np.percentile(times, 99))
        figs[f"{name}_iterations_mean"] = float(np.mean(first["iters"]))
        figs[f"{name}_force_from_optimum_n_median"] = float(np.median(first["dist"]))
        figs[f"{name}_force_from_optimum_n_max"] = float(np.max(first["dist"]))
        figs[f"{name}_not_solved"] = first["failed"]
    figs["qps"] = len(qps)
    figs["load_before"], figs["load_after"] = load0, os.getloadavg()[0]
    emit(figs, args.json, units={"_ms_median": "ms", "_ms_p99": "ms", "_n_median": "N",
                                "_n_max": "N"})
    return figs


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"# {time.perf_counter() - t0:.0f} s")
