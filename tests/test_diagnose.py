"""granular_mpc.validation.diagnosis (diagnose) / calibrate: the statistics on synthetic designs, then
the whole pipeline on small synthetic data sets (session fixtures in conftest.py): null
data, a hidden library effect, a mis-set ζ, and an effect outside the library that a
user-written term explains."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from granular_mpc.effects import Param, effect_info, register_effect, registered_effects
from granular_mpc.validation.diagnosis import (LARGE_HELDOUT_REDUCTION, MAX_DELTA_AICC,
                                               MIN_EFFECT_SIZE, Column, Design, Diagnosis,
                                               Regression, aicc, candidate_columns,
                                               candidate_stats, guard_jumps, load_diagnosis,
                                               localize)

ROOT = Path(__file__).resolve().parent.parent


# ----------------------------------------------------------------------------- statistics
def _design(n_groups=6, n_rows=300, beta=0.5, seed=0, noise=1.0):
    rng = np.random.default_rng(seed)
    n = n_groups * n_rows
    groups = np.repeat([f"t{k}" for k in range(n_groups)], n_rows)
    bins = np.arange(n) % 10
    nuis = rng.normal(size=n)
    real = np.linspace(-2.0, 2.0, 10)[bins] + 0.3 * rng.normal(size=n)   # a phase profile
    null = rng.normal(size=n)
    y = 0.8 * nuis + beta * real + noise * rng.normal(size=n)   # σ_c = 1 (the unit)
    X = {"calibration.zeta": nuis, "cohesion.suction": real, "inertial_drag.c_d": null}
    d = Design(y, X, groups, np.zeros(n, int), np.full(n, "grf_z"), bins,
               {"grf_z": 1.0}, 1.0)
    bounds = {k: (-10.0, 10.0) for k in X}
    return Regression(d, bounds, ["calibration.zeta"], stance_design=d)


def _cols(name, key):
    return [Column(name, key.split(".")[1], 0.0, 1.0, -10.0, 10.0)]


def _two_candidate_stats(reg):
    """Candidate statistics of cohesion (the design's real column) and inertial drag."""
    cand_keys = {"cohesion": ["cohesion.suction"], "inertial_drag": ["inertial_drag.c_d"]}
    cand_cols = {"cohesion": _cols("cohesion", "cohesion.suction"),
                 "inertial_drag": _cols("inertial_drag", "inertial_drag.c_d")}
    infos = {n: effect_info(n) for n in cand_keys}
    return candidate_stats(reg, ["calibration.zeta"], cand_keys, cand_cols, infos,
                            n_boot=50, seed=0, max_effects=1)


def test_regression_ranks_a_real_column_and_rejects_a_null_one():
    top, other = _two_candidate_stats(_design())
    assert top.effect == "cohesion" and top.significant and top.rank == 1
    assert top.params["suction"].value == pytest.approx(0.5, abs=0.05)
    lo, hi = top.params["suction"].boot_ci_lo, top.params["suction"].boot_ci_hi
    assert lo < 0.5 < hi
    assert top.inclusion_probability > 0.9 and top.delta_aicc < -10
    assert not other.significant and other.heldout_error_reduction < 0.01
    assert other.inclusion_probability < 0.2


def test_a_thin_effect_passes_by_its_heldout_reduction():
    """A term that moves no cell by 1 σ_c but removes most of the held-out error (the
    stance-averaged rows are less noisy than the stance-to-stance scatter) is practical;
    the same term in scatter-level noise is not."""
    top, _ = _two_candidate_stats(_design(beta=0.3, noise=0.3))
    assert top.effect == "cohesion"
    assert top.effect_size < MIN_EFFECT_SIZE
    assert top.heldout_error_reduction >= LARGE_HELDOUT_REDUCTION and top.significant
    top, _ = _two_candidate_stats(_design(beta=0.3, noise=1.0))
    assert top.effect_size < MIN_EFFECT_SIZE
    assert top.heldout_error_reduction < LARGE_HELDOUT_REDUCTION
    assert not top.significant and top.delta_aicc < MAX_DELTA_AICC


def test_null_design_adds_nothing():
    rows = _two_candidate_stats(_design(beta=0.0, seed=3))
    assert not any(r.significant for r in rows)


def test_guard_jumps_replaces_an_isolated_finite_difference_jump():
    """One stance whose perturbed replay crossed a contact event (a 50× response) takes
    its group's mean response; a response that is large on many stances is physics and
    stays."""
    rng = np.random.default_rng(0)
    W, C, B = 24, 3, 10
    groups = np.array([f"t{i % 3}|{'left' if i % 2 else 'right'}" for i in range(W)])
    S = 0.03 * (1.0 + 0.2 * rng.normal(size=(W, C, B)))
    S[9, 1] *= 50.0
    out, rep = guard_jumps(S, groups)
    assert rep == [(9, 1)]
    peers = [i for i in range(W) if groups[i] == groups[9] and i != 9]
    np.testing.assert_allclose(out[9, 1], S[peers, 1].mean(axis=0))
    np.testing.assert_array_equal(np.delete(out, 9, axis=0), np.delete(S, 9, axis=0))
    np.testing.assert_array_equal(out[9, [0, 2]], S[9, [0, 2]])
    S2 = S.copy()
    S2[:6, 2] *= 50.0                      # 25 % of the stances: not isolated
    assert all(c != 2 for _, c in guard_jumps(S2, groups)[1])


def test_aicc_and_candidate_columns():
    assert aicc(100.0, 50, 2) == pytest.approx(50 * math.log(2.0) + 4 + 12 / 47)
    cols = candidate_columns(effect_info("joint_friction"))
    assert {c.param for c in cols} == {"viscous", "coulomb"}
    assert all(c.neutral == 0.0 and c.step > 0 for c in cols)
    (c,) = candidate_columns(effect_info("depth_hardening"))
    assert c.param == "n" and c.neutral == 1.0 and c.step == pytest.approx(0.5)


def test_localize_finds_the_biased_cell():
    rng = np.random.default_rng(0)
    from granular_mpc.validation.prepare import StanceWindow

    W, C, B = 40, 2, 10
    R = rng.normal(0.0, 1.0, (W, C, B))
    R[:, 1, 3] += 2.0                               # channel 1, 30–40 %: systematic
    ws = []
    for i in range(W):
        t = np.linspace(0, 0.2, 50)
        feats = {f: rng.normal(size=50) for f in ("depth", "sink_velocity", "rise_from_deepest",
                                                   "sink_acceleration", "slip_velocity", "v_h",
                                                   "v_l", "vc_z", "time_in_stance",
                                                   "joint_speed", "trunk_speed", "grf_z",
                                                   "x_position")}
        ws.append(StanceWindow(i, f"t{i % 4}", 0.2, "left", 0, 10 * i, 10 * i + 50, t,
                               100 * t / 0.2, np.zeros(13), np.zeros(12), np.zeros((50, 6)),
                               (), np.zeros(3), np.zeros(3), {}, feats))
    loc = localize(ws, R, ["a", "b"], np.linspace(0, 100, B + 1), {"a": 1.0, "b": 1.0})
    sig = loc.significant_cells
    assert sig and sig[0].channel == "b" and sig[0].phase_lo == 30.0
    assert sig[0].major and {c.side for c in sig if c.major} == {"all", "left"}
    assert set(loc.whiteness_stance_sequence) == {"a", "b"}


# ----------------------------------------------------------------------------- pipeline
def test_null_data_adds_nothing(workbench_diagnosis):
    d = workbench_diagnosis("null")
    assert d.added == []
    assert d.verdict.status in ("no_significant_missing_effect", "unexplained_structure")
    assert d.calibration.values["zeta"] == pytest.approx(1.36, rel=0.08)


def test_hidden_library_effect_is_found_and_fitted(workbench_diagnosis):
    d = workbench_diagnosis("cohesion")
    assert d.added[:1] == ["cohesion"] and d.ranking[0].effect == "cohesion"
    top = d.ranking[0]
    assert top.heldout_error_reduction > 0.3 and top.inclusion_probability > 0.8
    assert top.added and top.refined_params["suction"] == pytest.approx(3000.0, rel=0.2)
    # the affected channels' held-out error falls
    red = d.heldout_reduction_by_channel
    assert max(v.reduction for k, v in red.items() if k.startswith("q_")) > 0.5
    assert d.replay_rmse_by_channel["q_right_knee"].reduction > 0.3


def test_a_mis_set_parameter_is_calibrated_not_reported(workbench_diagnosis):
    """The data were made with ζ = 1.768 (+30 %); the model file says 1.36."""
    d = workbench_diagnosis("zeta_off")
    cal = d.calibration
    assert cal.equation_error.initial["zeta"] == 1.36
    assert cal.equation_error.values["zeta"] == pytest.approx(1.768, rel=0.1)
    assert cal.values["zeta"] == pytest.approx(1.768, rel=0.08)
    lo, hi = cal.equation_error.ci_boot["zeta"]
    assert lo < cal.equation_error.values["zeta"] < hi
    assert d.added == []


def test_effect_outside_the_library_is_localised(workbench_diagnosis):
    """A sideways push ∝ the forward sole speed: no library term has it. The diagnosis
    must say where (lateral channels) and with what it correlates."""
    d = workbench_diagnosis("unknown")
    loc = d.localization.before
    lateral = {"grf_y", "intrusion_y", "q_left_hip_abd", "q_right_hip_abd"}
    top_channels = [c.channel for c in loc.significant_cells[:8]]
    assert lateral & set(top_channels), top_channels
    share = loc.by_channel
    assert max(share[c].systematic_share for c in lateral) > 0.15
    assert any(e.p_value < 1e-3 for c in lateral for e in loc.correlates[c][:3])
    assert d.localization.where


def test_a_user_written_term_closes_the_gap(workbench_data, library_candidates, tmp_path):
    from granular_mpc.validation.diagnose import diagnose      # the compatibility module
    from granular_mpc.validation.replay import validate

    name = "_test_user_oblique"
    if name not in registered_effects():
        @register_effect(name, params={"c": Param(10.0, -200.0, 200.0, "N·s/m", "")})
        def _oblique(o, s, p):
            """The user's guess: lateral force −c·v_x on the sole."""
            return (0.0, -p["c"] * s.v_c[0] * s.in_contact, 0.0)
    data = workbench_data("unknown")
    d = diagnose(data, tmp_path / "diag", candidates=library_candidates + [name], n_boot=60)
    assert d.added[:1] == [name]
    assert d.fitted_effects[name]["c"] == pytest.approx(18.0, rel=0.3)
    v = validate(data, tmp_path / "val", effects=[name], params=tmp_path / "diag", n_boot=100)
    ba = v.report["before_after"]
    assert ba["intrusion_y"]["after"] < 0.8 * ba["intrusion_y"]["before"]
    assert ba["grf_y"]["after"] < ba["grf_y"]["before"]


def test_outputs_on_disk(workbench_diagnosis):
    d = workbench_diagnosis("cohesion")
    j = json.loads((d.out_dir / "diagnosis.json").read_text())
    for key in ("verdict", "calibration", "ranking", "localization", "fitted_effects",
                "indistinguishable", "recommended"):
        assert key in j
    for e in j["ranking"]:
        for key in ("effect", "heldout_error_reduction", "delta_aicc", "inclusion_probability",
                    "params"):
            assert key in e
        for p in e["params"].values():
            assert {"value", "ci_lo", "ci_hi", "boot_ci_lo", "boot_ci_hi"} <= set(p)
    # the file reads back into the same typed diagnosis
    back = load_diagnosis(d.out_dir)
    assert isinstance(back, Diagnosis) and back.out_dir == d.out_dir
    assert back.to_json() == d.to_json() == (d.out_dir / "diagnosis.json").read_text()
    assert back.ranking[0].effect == "cohesion" and back.ranking[0].params == d.ranking[0].params
    assert back.verdict == d.verdict and back.added == d.added
    md = (d.out_dir / "report.md").read_text()
    assert "Verdict" in md and "cohesion" in md
    for f in j["figures"]:
        assert (d.out_dir / f).stat().st_size > 5_000
    assert "--effect cohesion" in j["recommended"]["validate_command"]


def test_cli_commands(workbench_data, tmp_path):
    from typer.testing import CliRunner

    from granular_mpc.cli import app

    runner = CliRunner()
    data = workbench_data("cohesion")
    res = runner.invoke(app, ["validate", str(data), "--out", str(tmp_path / "v"), "--model",
                              "rigid", "--workers", "1"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "v" / "report.json").is_file()
    res = runner.invoke(app, ["diagnose", str(data), "--out", str(tmp_path / "d"),
                              "--candidate", "force_sensor_bias"])
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "d" / "diagnosis.json").read_text())["ranking"]
    res = runner.invoke(app, ["validate", str(data), "--out", str(tmp_path / "x"),
                              "--effect", "cohesoin"])
    assert res.exit_code == 2 and "did you mean 'cohesion'" in res.output


@pytest.mark.slow
def test_recovery_study_quick():
    """bench/recovery.py --quick: two library effects and one null data set."""
    proc = subprocess.run([sys.executable, str(ROOT / "bench" / "recovery.py"), "--quick"],
                          capture_output=True, text=True, timeout=3600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    figs = dict(ln.split(": ", 1) for ln in proc.stdout.splitlines() if ": " in ln
                and not ln.startswith(" ") and ln.split(":")[0].isidentifier())
    assert float(figs["rank1_rate"]) >= 0.99
    assert float(figs["coef_within_15pct_rate"]) >= 0.99
    assert float(figs["null_nothing_added_rate"]) >= 0.99
