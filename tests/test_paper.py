"""The paper comparison (granular_mpc.paper): the quick form writes every claim row, and
each "ours" number is recomputed here from the run or report the row names."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from granular_mpc.analysis import contact_segments, plateau_by_stance, rolling_from_log
from granular_mpc.exceptions import OutputError
from granular_mpc.paper import paper_comparison
from granular_mpc.runlog import read_log

KEYS = ("cot_sand", "cot_rigid", "cot_ratio_02", "cot_ratio_range", "u_shape_sand",
        "u_shape_rigid", "cost_opening", "pullout_jump", "plateau_sand", "plateau_fades",
        "plateau_rigid", "r_eff_rigid", "rigid_model_grf", "hip_knee_better",
        "planar_model", "rigid_controller_on_sand")


@pytest.fixture(scope="module")
def comparison(tmp_path_factory):
    return paper_comparison(tmp_path_factory.mktemp("paper"), quick=True, workers=2)


def summary(comparison, rel: str) -> dict:
    return json.loads((comparison.out_dir / rel / "summary.json").read_text())


def test_table_has_every_claim_and_no_empty_cell(comparison):
    assert tuple(r.key for r in comparison.rows) == KEYS
    text = comparison.table.read_text()
    rows = [ln for ln in text.splitlines() if ln.startswith("| ") and not ln.startswith("| claim")]
    assert len(rows) == len(KEYS)
    for ln in rows:
        cells = [c.strip() for c in ln.strip().strip("|").split(" | ")]
        assert len(cells) == 7 and all(cells), ln
        assert "quick" in cells[4]
    for fig in comparison.figures:
        assert fig.is_file() and fig.stat().st_size > 1000


def test_cot_rows_are_the_runs_summaries(comparison):
    for key in ("cot_sand", "cot_rigid"):
        row = comparison.row(key)
        s = summary(comparison, row.source)
        assert row.value == pytest.approx(s["cot_abs_per_joint"], rel=1e-12)
        assert f"{s['cot_abs_net']:.2f}" in row.ours and f"{s['cot_positive']:.2f}" in row.ours
    sand, rigid = comparison.row("cot_sand").value, comparison.row("cot_rigid").value
    assert comparison.row("cot_ratio_02").value == pytest.approx(sand / rigid)


def test_ratio_range_from_every_speed(comparison):
    runs = comparison.runs
    ratios = []
    for v in runs.plan.speeds:
        s = json.loads((runs.sweep_run("dry_sand", v) / "summary.json").read_text())
        r = json.loads((runs.sweep_run("rigid", v) / "summary.json").read_text())
        ratios.append(s["cot_abs_per_joint"] / r["cot_abs_per_joint"])
    assert comparison.row("cot_ratio_range").value == pytest.approx(min(ratios))
    a = np.polyfit(runs.plan.speeds, [json.loads((runs.sweep_run("rigid", v) / "summary.json")
                                                 .read_text())["cot_abs_per_joint"]
                                      for v in runs.plan.speeds], 2)[0]
    assert comparison.row("u_shape_rigid").value == pytest.approx(a)


def test_plateau_row_recomputed_from_the_log(comparison):
    row = comparison.row("plateau_sand")
    run = comparison.out_dir / row.source
    s = json.loads((run / "summary.json").read_text())
    log = read_log(run)
    seg = contact_segments(log)
    seg = seg[seg["t_start"] >= s["window_s"][0]].reset_index(drop=True)
    assert (seg["duration_s"] > 0.1).all()      # no landing bounce left as a "stance"
    plat = plateau_by_stance(rolling_from_log(log, segments=seg))
    onsets = plat.loc[plat["n_plateaus"] > 0, "onset_pct"]
    expected = float(onsets.median()) if len(onsets) else math.nan
    assert row.value == pytest.approx(expected, nan_ok=True)


def test_model_rows_from_the_reports(comparison):
    rep = {m: json.loads((comparison.out_dir / f"validate_{m}" / "report.json").read_text())
           for m in ("granular", "rigid")}
    joints = ("q_left_hip_pitch", "q_left_knee", "q_right_hip_pitch", "q_right_knee")
    better = sum(rep["granular"]["overall_rmse"]["granular"][c]
                 < rep["rigid"]["overall_rmse"]["rigid"][c] for c in joints)
    assert comparison.row("hip_knee_better").value == better


def test_planar_row_from_its_report(comparison):
    rep = {m: json.loads((comparison.out_dir / f"validate_{m}" / "report.json").read_text())
           for m in ("granular", "planar")}
    channels = ("q_left_hip_pitch", "q_left_knee", "q_right_hip_pitch", "q_right_knee",
                "grf_x", "grf_z", "intrusion_z")
    ratios = [rep["planar"]["overall_rmse"]["planar"][c]
              / rep["granular"]["overall_rmse"]["granular"][c] for c in channels]
    assert comparison.row("planar_model").value == pytest.approx(max(ratios))


def test_track_row_from_the_exact_protocol_run(comparison):
    row = comparison.row("rigid_controller_on_sand")
    s = summary(comparison, "track/runs/exact")
    if s["fell"]:
        assert f"fall at {s['fall_time_s']:.2f} s" in row.ours
        assert 0.0 < row.value < s["fall_time_s"]
    else:
        assert row.value == pytest.approx(s["sim_time_s"])


def test_a_second_comparison_into_the_same_folder_needs_overwrite(comparison):
    table = comparison.table.read_text()
    with pytest.raises(OutputError, match="overwrite"):
        paper_comparison(comparison.out_dir, quick=True, workers=1)
    assert comparison.table.read_text() == table          # nothing was replaced
