"""Validation-workbench speed on a 50-stance data set: `name: value unit` lines.

    python bench/diagnose.py [--data DIR] [--json PATH] [--workers N]

Figures:

* validate_s — ``granular-mpc validate`` (granular model: replay of every stance, RMSE
  tables with 1000 trial-bootstrap replicates, figures, report.json).
* diagnose_s — ``granular-mpc diagnose`` (calibration, ≈ 12 replays of all stances, ranking
  with 200 bootstrap refits, replay refinement of the added effect, localisation, report).
* n_stances — complete stance phases in the data set; replays — stance replays run.
* diagnose_<stage>_s — ``diagnosis.timing_s`` of the diagnose run, per stage (prepare,
  calibrate, replays, design, rank, refine, localize; ``total`` excludes the figures and
  the report, which ``diagnose_s`` includes).

Without ``--data`` a data set is synthesised first (5 speeds × 10 stances, hidden effect
``cohesion``, realistic noise; not timed) in a temporary folder. Budget (issue 5): both
below 60 s on the 2-core development machine.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path


def benchmark_data(folder: Path) -> Path:
    """The benchmark's data set (5 speeds × 9 steps, hidden cohesion, noise level 1,
    seed 11), synthesised into ``folder``."""
    from granular_mpc.validation.synth import synthesize

    synthesize("sand_walk", folder, speeds=[0.1, 0.2, 0.3, 0.4, 0.5], steps=9, seed=11,
               effects=["cohesion:suction=3000"], noise=1.0, format="parquet")
    return folder


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, help="an existing data set (default: synthesise one)")
    ap.add_argument("--json", type=Path, help="write the figures as JSON here")
    ap.add_argument("--workers", type=int, default=None)
    args = ap.parse_args()

    from granular_mpc.validation.diagnose import diagnose
    from granular_mpc.validation.replay import validate
    with tempfile.TemporaryDirectory() as tmp:
        data = args.data
        if data is None:
            data = benchmark_data(Path(tmp) / "data")
        t0 = time.perf_counter()
        rep = validate(data, Path(tmp) / "validate", workers=args.workers)
        t_val = time.perf_counter() - t0
        t0 = time.perf_counter()
        diag = diagnose(data, Path(tmp) / "diagnose", workers=args.workers)
        t_diag = time.perf_counter() - t0
    figures = {"validate_s": t_val, "diagnose_s": t_diag,
               "n_stances": rep.report["n_stances"],
               "replays": diag.design.replays}
    units = {"validate_s": "s", "diagnose_s": "s", "n_stances": "", "replays": ""}
    for stage, sec in diag.timing_s.items():
        figures[f"diagnose_{stage}_s"] = float(sec)
        units[f"diagnose_{stage}_s"] = "s"
    for k, v in figures.items():
        print(f"{k}: {v:.3g} {units[k]}".rstrip() if isinstance(v, float) else f"{k}: {v}")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1), encoding="utf-8")


if __name__ == "__main__":
    main()
