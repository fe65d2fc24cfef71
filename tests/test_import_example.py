"""examples/import_lab_log.py as users run it: a subprocess, headless, output parsed."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """One run of the example: (its output folder, the completed process)."""
    tmp_path = tmp_path_factory.mktemp("import_example")
    env = dict(os.environ, MPLBACKEND="Agg", GRANULAR_MPC_EXAMPLE_OUT=str(tmp_path))
    proc = subprocess.run([sys.executable, str(EXAMPLES / "import_lab_log.py")], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=600)
    return tmp_path, proc


def test_import_lab_log_example(example):
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
    tmp_path, proc = example
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


def test_import_lab_log_example_validates_and_diagnoses_on_measured_channels(example):
    """… then validate and diagnose run on the imported data set (no motion capture, no
    intrusion): the reports name the groups that were not measured, score no intrusion,
    start the replays from leg odometry, and the diagnosis names what it cannot assess.
    Joint-angle replay RMSE < 45 mrad: the noise-free log replays on the model that made
    it, so the estimated start states must not cost more than the realistic sensor noise
    does with every channel measured (30–45 mrad, docs/validation.md §6)."""
    tmp_path, proc = example
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    value = {k: v for k, _, v in (line.partition(": ") for line in lines)}
    assert value["not_measured"] == "trunk_position, trunk_linear_velocity, intrusion"
    assert value["not_scored"] == "intrusion_x, intrusion_y, intrusion_z"
    assert "leg odometry" in value["validate"]
    rmse = {k.split()[1]: float(v.split()[0]) for k, v in value.items()
            if k.strip().startswith("RMSE q_")}
    assert len(rmse) == 6 and max(rmse.values()) < 0.045, rmse
    assert not any(k.strip().startswith("RMSE intrusion") for k in value)
    assert value["diagnose"].split()[0] in ("missing_effect", "partially_explained",
                                            "no_significant_missing_effect",
                                            "unexplained_structure")
    assert "not_assessable" in value
    report = (tmp_path / "import_lab_log" / "diagnose" / "report.md").read_text()
    assert "**not measured:** trunk_position, trunk_linear_velocity, intrusion" in report
