"""Find a missing physical effect: synth → validate → diagnose → add it → validate again.

    .venv/bin/python examples/find_missing_effect.py [SECONDS]

1. ``synth``: closed-loop walking of the plant at three speeds with a *hidden* effect —
   wet-sand suction (``cohesion``) that the model does not have — and realistic sensor
   noise; written in measurement format v1.
2. ``validate``: every stance replayed from its measured touchdown state with the
   measured torques; the RMSE is high, and the report says where (channel × stance phase).
3. ``diagnose``: calibrate ζ, replay the candidate effects, rank them by held-out error
   reduction; the verdict names what is missing, with its fitted parameters.
4. ``validate --effect NAME --params diagnosis.json``: the same replay with the effect
   added at its fitted values; the RMSE before and after is printed.

Headless; everything is written under ``$GRANULAR_MPC_EXAMPLE_OUT`` (default
``runs/examples``)/find_missing_effect. SECONDS (argument or
``GRANULAR_MPC_EXAMPLE_SECONDS``, default 1.2) is the recorded walking time per trial.
The last lines printed are ``rmse_before_<channel>`` / ``rmse_after_<channel>`` pairs.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from granular_mpc.validation.diagnose import diagnose
from granular_mpc.validation.replay import validate
from granular_mpc.validation.synth import synthesize

seconds = float(sys.argv[1]) if len(sys.argv) > 1 else float(
    os.environ.get("GRANULAR_MPC_EXAMPLE_SECONDS", "1.2"))
seconds = max(seconds, 0.8)                      # at least a few stances per trial
out = Path(os.environ.get("GRANULAR_MPC_EXAMPLE_OUT", "runs/examples")) / "find_missing_effect"
data = out / "data"

# 1. measurement data with an effect the model does not have
res = synthesize("sand_walk", data, speeds=[0.15, 0.25, 0.35], duration=seconds, seed=3,
                 effects=["cohesion:suction=3000"], noise=1.0, format="parquet",
                 overwrite=True)
print(f"synth: {sum(res.n_stances.values())} stances in {len(res.trials)} trials -> {data}")

# 2. how wrong is the model, and where?
before = validate(data, out / "validate_before", n_boot=200)
rmse = before.report["overall_rmse"]["granular"]
print("validate: RMSE knee {:.3f} rad, grf_z {:.1f} N, intrusion_z {:.1f} mm".format(
    rmse["q_left_knee"], rmse["grf_z"], 1e3 * rmse["intrusion_z"]))

# 3. what is missing?
diag = diagnose(data, out / "diagnose", n_boot=100)
print("diagnose:", diag.verdict.text)
for e in diag.ranking[:3]:
    print(f"  {e.rank}. {e.effect:18s} held-out error reduction "
          f"{100 * e.heldout_error_reduction:5.1f} %  ΔAICc {e.delta_aicc:8.1f}  "
          f"inclusion {e.inclusion_probability}")

# 4. add it with its fitted parameters and replay again
added = diag.added or [diag.ranking[0].effect]
after = validate(data, out / "validate_after", effects=added, params=out / "diagnose", n_boot=200)
for ch, d in after.report["before_after"].items():
    if ch in ("q_left_knee", "q_right_knee", "grf_z", "intrusion_z"):
        print(f"rmse_before_{ch}: {d['before']:.4g}")
        print(f"rmse_after_{ch}: {d['after']:.4g}")
