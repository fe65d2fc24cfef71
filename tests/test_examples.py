"""Examples run as users run them: a subprocess, headless, output parsed.

The subprocesses inherit ``GRANULAR_MPC_PROXSUITE=generic`` from ``conftest.py`` (the
drop has no controller; the workbench's synthetic walks are the same realisation on
every machine).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from granular_mpc.config import load_terrain

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def test_drop_on_sand_example(tmp_path, biped, sand):
    """The last two lines are `sinkage_sand_mm: X` and `sinkage_rigid_mm: Y`, both parse,
    and each lies within bounds derived from the two contact models.

    At rest on the guide rig (which holds x, y and the attitude, never z) each foot bears
    W/2. Sand: at least the quasi-static depth under W/2 (12.6 mm; the drop's impact and
    the hysteresis of the granular law only add depth, docs/model.md §5), and above the
    floor of the layer (``layer_depth``). Rigid ground: penalty springs of stiffness k per
    contact patch, so at most W/(2k) (all of a foot's load on one patch: 0.52 mm).
    Measured 31.7 mm and 0.26 mm (= W/(4k): two patches per foot share the load)."""
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
    sand_min = 1e3 * sand.quasi_static_depth(biped.weight / 2)
    sand_max = 1e3 * load_terrain("dry_sand").layer_depth
    rigid_max = 1e3 * biped.weight / (2 * load_terrain("rigid").contact_stiffness)
    assert 0.0 < values["sinkage_rigid_mm"] <= rigid_max, (values, rigid_max)
    assert sand_min <= values["sinkage_sand_mm"] < sand_max, (values, sand_min)
    assert values["sinkage_sand_mm"] > 5.0 * values["sinkage_rigid_mm"]


def test_find_missing_effect_example(tmp_path):
    """The workbench story end to end: the diagnosis names the hidden wet-sand suction and
    adding it at its fitted value cuts the knee-angle replay error by more than half.

    "More than half" is the example's stated promise (examples/README.md), not a measured
    figure; measured 0.27 → 0.04 rad (a factor ≈ 7)."""
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
