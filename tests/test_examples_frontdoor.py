"""The front-door examples run headless at reduced duration and print what they promise.

Each runs as a subprocess with ``GRANULAR_MPC_EXAMPLE_SECONDS`` (short) and
``GRANULAR_MPC_EXAMPLE_OUT`` (a temporary folder); its printed output is parsed.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
slow = pytest.mark.slow   # a few seconds each (they still run in CI: no marker filter there)


def run_example(name: str, tmp_path: Path, seconds: float = 1.0) -> str:
    env = dict(os.environ, GRANULAR_MPC_EXAMPLE_SECONDS=str(seconds),
               GRANULAR_MPC_EXAMPLE_OUT=str(tmp_path), MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(EXAMPLES / name)], capture_output=True,
                          text=True, timeout=600, cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr
    return proc.stdout


def markdown_rows(text: str) -> list[list[str]]:
    """Cells of every Markdown table line in ``text`` (rule lines ``|---|`` dropped)."""
    rows = []
    for line in text.splitlines():
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if not set("".join(cells)) <= set("-:"):
                rows.append(cells)
    return rows


def number_or_dash(cell: str) -> float | None:
    return None if cell == "-" else float(cell)


def test_examples_readme_lists_the_front_door_examples_in_order():
    text = (EXAMPLES / "README.md").read_text()
    names = ["walk_on_sand.py", "rigid_vs_granular_controller.py", "velocity_sweep.py"]
    pos = [text.find(n) for n in names]
    assert all(p >= 0 for p in pos) and pos == sorted(pos)
    if "drop_on_sand.py" in text:
        assert text.find("drop_on_sand.py") < pos[0]


@slow
def test_walk_on_sand(tmp_path):
    out = run_example("walk_on_sand.py", tmp_path)
    values = dict(line.split(": ", 1) for line in out.splitlines() if ": " in line)
    assert values["terrain"] == "dry_sand" and values["controller_terrain_model"] == "dry_sand"
    assert float(values["sim_time_s"]) == pytest.approx(1.0, abs=1e-6) or values["fell"] == "True"
    assert values["fell"] in ("True", "False") and values["complete"] == "True"
    for key in ("commanded_speed_mps", "realtime_factor", "max_pitch_deg"):
        assert float(values[key]) >= 0.0
    for key in ("mean_speed_mps", "sinkage_peak_mm_mean", "slip_mm_mean", "cot"):
        assert values[key] == "None" or float(values[key]) == float(values[key])
    assert values["plots"].startswith("5 in ")
    assert (tmp_path / "walk_on_sand" / "summary.json").is_file()


@slow
def test_rigid_vs_granular_controller(tmp_path):
    out = run_example("rigid_vs_granular_controller.py", tmp_path)
    rows = [r for r in markdown_rows(out) if r[0] != "controller terrain"]
    assert [r[0] for r in rows] == ["dry_sand (granular)", "rigid (rigid)"]
    for r in rows:
        assert len(r) == 8 and r[1] in ("yes", "no")
        for cell in r[2:7]:
            number_or_dash(cell)
        int(r[7])
    assert out.startswith("plant: dry_sand")


@slow
def test_velocity_sweep(tmp_path):
    out = run_example("velocity_sweep.py", tmp_path, seconds=0.5)
    assert out.startswith("4 runs, 0.5 s each")
    rows = [r for r in markdown_rows(out) if r[0] not in ("terrain", "series")]
    runs = [r for r in rows if len(r) == 5]
    assert sorted((r[0], float(r[1])) for r in runs) == [
        ("dry_sand", 0.2), ("dry_sand", 0.4), ("rigid", 0.2), ("rigid", 0.4)]
    for r in runs:
        float(r[2])
        number_or_dash(r[3])
        assert r[4] in ("yes", "no")
    assert "plot: " in out
    assert (tmp_path / "velocity_sweep" / "sweep.csv").is_file()
