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
    """4 robots × 30 policy steps (0.3 s): the last lines are episodes, mean return and
    length, env_steps_per_s and plant_steps_per_s = 20 × env_steps_per_s (frame skip 20).

    No robot falls in 0.3 s, so there are exactly 4 episodes of 30 steps: even with no
    control at all, the standing robot is an inverted pendulum (l ≈ 0.45 m,
    ω = √(g/l) ≈ 4.7 1/s) started within the reset noise of upright (θ0 ≲ 0.02 rad,
    θ̇0 ≲ 0.02 rad/s), θ(t) = θ0 cosh ωt + (θ̇0/ω) sinh ωt: ≈ 0.9 s to reach the
    termination tilt of 0.8 rad, 0.05 rad at 0.3 s.
    Reward per step (envs/task.py): at most w_speed + w_alive = 1.5; at least the alive
    bonus 0.5 less the tilt penalty (0.5 · tilt² < 2e-3) and the action-rate penalty
    (0.01 · Σ Δa²; the PD's actions are a few hundredths of the range at these tilts:
    < 0.01) — bound 0.4 per step (measured 0.51).
    The throughput figures depend on wall-clock time and are only checked for sign and
    their ratio (which is exact up to the printed 4 significant digits)."""
    env = dict(os.environ)
    env.pop("GRANULAR_MPC_EXAMPLE_SECONDS", None)
    proc = subprocess.run([sys.executable, str(EXAMPLE), "--num-envs", "4", "--steps", "30"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    values = dict(line.split(": ") for line in proc.stdout.strip().splitlines())
    assert set(values) == {"episodes", "mean_return", "mean_length_steps", "env_steps_per_s",
                           "plant_steps_per_s"}
    assert int(values["episodes"]) == 4
    length = float(values["mean_length_steps"])
    assert length == 30.0
    env_rate, plant_rate = float(values["env_steps_per_s"]), float(values["plant_steps_per_s"])
    # 4 significant digits each: the printed ratio is 20 within 20 · 2 · 5e-4 = 0.02
    assert env_rate > 0 and abs(plant_rate / env_rate - 20.0) < 0.05
    assert 0.4 * length < float(values["mean_return"]) <= 1.5 * length
