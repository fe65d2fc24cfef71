"""examples/import_lab_log.py as users run it: a subprocess, headless, output parsed."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def test_import_lab_log_example(tmp_path):
    """The made-up lab log (degrees, ms, xyzw, foot-frame forces on their own clock) imports
    to the truth: joint angles within 1e-9 rad, stance labels derived from the foot forces
    agreeing with the plant's on ≥ 97 % of the rows, absent groups reported as absent.

    1e-9 rad: the truth's own samples go through degrees and ms / ns time stamps and come
    back on the same 500 Hz grid, so only round-off remains (measured 5.9e-12 rad); a unit
    slip or a one-sample time shift (≈ 1e-2 rad at 500 Hz) is 1e7 times larger.
    97 %: the force stream has every other sample (250 Hz) and its own clock, so each
    stance change can be placed only to ±1 force sample (2 rows) plus one row of
    debounce: ≤ 3 disagreeing rows per touchdown, 6 touchdowns in 651 rows → ≥ 97.2 %
    (measured 99.4 %)."""
    env = dict(os.environ, MPLBACKEND="Agg", GRANULAR_MPC_EXAMPLE_OUT=str(tmp_path))
    proc = subprocess.run([sys.executable, str(EXAMPLES / "import_lab_log.py")], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    values = dict(line.split(": ", 1) for line in lines
                  if line.startswith(("max_joint_angle_error_rad", "stance_agreement")))
    assert float(values["max_joint_angle_error_rad"]) < 1e-9, proc.stdout
    assert float(values["stance_agreement"]) >= 0.97, proc.stdout
    absent = next(line for line in lines if line.strip().startswith("absent:"))
    assert "trunk_position" in absent and "intrusion" in absent and "foot_force" not in absent
    assert any(line.strip() == "stance:   force" for line in lines), proc.stdout
    assert (tmp_path / "import_lab_log" / "imported" / "meta.yaml").is_file()
