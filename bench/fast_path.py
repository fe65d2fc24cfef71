"""The workbench on the reference and on the compiled plant, side by side in one process.

    python bench/fast_path.py [--data DIR] [--repeat 1] [--workers N] [--json PATH]

Runs ``validate`` and ``diagnose`` (the figures of ``bench/diagnose.py``) on one data set
with the ``granular`` replays stepping the reference plant (``GRANULAR_MPC_PLANT=reference``)
and the compiled plant (``compiled``, the default), alternately ``--repeat`` times, and
prints the medians: ``validate_s_<plant>``, ``diagnose_s_<plant>``, ``diagnose_speedup``,
the selected effect and the calibrated θ of both (the physics must not change), and the
machine load (1-min average) before and after. Without ``--data`` the data set of
``bench/diagnose.py`` is synthesised first (5 speeds × 10 stances, hidden ``cohesion``,
realistic noise; not timed). The closed loop side by side: ``bench/controller.py --plant both``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from _report import emit
from diagnose import benchmark_data

PLANTS = ("reference", "compiled")


def workbench_figures(data: Path, out: Path, plant: str, workers: int | None) -> dict:
    """validate + diagnose of ``data`` with the replays on ``plant``."""
    from granular_mpc.dynamics.select import PLANT_ENV
    from granular_mpc.validation.diagnose import diagnose
    from granular_mpc.validation.replay import validate

    os.environ[PLANT_ENV] = plant
    t0 = time.perf_counter()
    rep = validate(data, out / "validate", workers=workers)
    t_val = time.perf_counter() - t0
    t0 = time.perf_counter()
    diag = diagnose(data, out / "diagnose", workers=workers)
    t_diag = time.perf_counter() - t0
    theta = dict(diag.calibration.values)
    fitted = {f"{e}.{k}": float(v) for e, p in diag.fitted_effects.items() for k, v in p.items()}
    return {"validate_s": t_val, "diagnose_s": t_diag, "n_stances": rep.report["n_stances"],
            "replays": diag.design.replays, "verdict": diag.verdict.status,
            "added": ",".join(diag.verdict.added),
            "zeta": float(theta.get("zeta", float("nan"))),
            "phi_s": float(theta.get("phi_s", float("nan"))),
            "fitted": ", ".join(f"{k}={v:.5g}" for k, v in sorted(fitted.items()))}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, help="an existing data set (default: synthesise one)")
    ap.add_argument("--json", type=Path, help="write the figures as JSON here")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        data = args.data
        if data is None:
            data = benchmark_data(Path(tmp) / "data")
        figures: dict = {"load_before": os.getloadavg()[0]}
        runs: dict = {p: [] for p in PLANTS}
        for r in range(max(1, args.repeat)):
            for plant in PLANTS:
                runs[plant].append(workbench_figures(data, Path(tmp) / f"{plant}{r}", plant,
                                                     args.workers))
        figures["load_after"] = os.getloadavg()[0]
    for plant, rows in runs.items():
        for key, value in rows[0].items():
            if isinstance(value, float):
                figures[f"{key}_{plant}"] = float(np.median([row[key] for row in rows]))
            else:
                figures[f"{key}_{plant}"] = value
    figures["diagnose_speedup"] = figures["diagnose_s_reference"] / figures["diagnose_s_compiled"]
    figures["validate_speedup"] = figures["validate_s_reference"] / figures["validate_s_compiled"]
    emit(figures, str(args.json) if args.json else None, {"_s_reference": "s", "_s_compiled": "s"})
    return figures


if __name__ == "__main__":
    main()
