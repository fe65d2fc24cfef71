"""examples/gym_rollout.py runs headless, briefly, and prints parseable throughput figures."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("gymnasium")

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "gym_rollout.py"


def test_gym_rollout_example_runs_and_reports_throughput(tmp_path):
    """4 robots × 30 policy steps: the last lines are episodes, mean return and length,
    env_steps_per_s and plant_steps_per_s = 20 × env_steps_per_s (frame skip 20)."""
    env = dict(os.environ)
    env.pop("GRANULAR_MPC_EXAMPLE_SECONDS", None)
    proc = subprocess.run([sys.executable, str(EXAMPLE), "--num-envs", "4", "--steps", "30"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    values = dict(line.split(": ") for line in proc.stdout.strip().splitlines())
    assert set(values) == {"episodes", "mean_return", "mean_length_steps", "env_steps_per_s",
                           "plant_steps_per_s"}
    assert int(values["episodes"]) >= 4
    assert float(values["mean_length_steps"]) > 0
    env_rate, plant_rate = float(values["env_steps_per_s"]), float(values["plant_steps_per_s"])
    assert env_rate > 0 and abs(plant_rate / env_rate - 20.0) < 0.1
    # upright steps earn the alive bonus (0.5) less small tilt and action-rate penalties
    assert float(values["mean_return"]) > 0.3 * float(values["mean_length_steps"])
