"""Examples run as users run them: a subprocess, headless, output parsed."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def test_drop_on_sand_example(tmp_path):
    """The last two lines are `sinkage_sand_mm: X` and `sinkage_rigid_mm: Y`, both parse,
    and the sand sinkage is more than five times the rigid one."""
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(EXAMPLES / "drop_on_sand.py")], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    values = {}
    for line, key in zip(lines[-2:], ("sinkage_sand_mm", "sinkage_rigid_mm")):
        name, _, value = line.partition(":")
        assert name == key, lines[-2:]
        values[key] = float(value)
    assert values["sinkage_rigid_mm"] > 0.0
    assert values["sinkage_sand_mm"] > 5.0 * values["sinkage_rigid_mm"]
    assert 5.0 < values["sinkage_sand_mm"] < 60.0


def test_find_missing_effect_example(tmp_path):
    """The workbench story end to end: the diagnosis names the hidden wet-sand suction and
    adding it at its fitted value cuts the knee-angle replay error by more than half."""
    env = dict(os.environ, MPLBACKEND="Agg", GRANULAR_MPC_EXAMPLE_OUT=str(tmp_path))
    proc = subprocess.run([sys.executable, str(EXAMPLES / "find_missing_effect.py")],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = proc.stdout
    verdict = next(line for line in out.splitlines() if line.startswith("diagnose:"))
    assert "missing effect: cohesion" in verdict, out
    rmse = {}
    for line in out.splitlines():
        if line.startswith(("rmse_before_", "rmse_after_")):
            key, _, value = line.partition(": ")
            rmse[key] = float(value)
    for knee in ("q_left_knee", "q_right_knee"):
        assert rmse[f"rmse_after_{knee}"] < 0.5 * rmse[f"rmse_before_{knee}"], rmse
    assert (tmp_path / "find_missing_effect" / "diagnose" / "diagnosis.json").is_file()
