"""Declared channels in the workbench: data sets with channel groups removed
(``dataformat.drop``), windows and scores on the measured channels only (``prepare``,
``validate``) and what the diagnosis can assess without the missing ones
(``diagnosis.coverage``)."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from granular_mpc.columns import GRF_COLUMNS, INTRUSION_COLUMNS, STANCE
from granular_mpc.exceptions import ConfigError, DataFormatError
from granular_mpc.output import json_safe
from granular_mpc.validation.channel_coverage import Coverage, channel_coverage
from granular_mpc.validation.dataformat import load_dataset
from granular_mpc.validation.dataformat.channels import ChannelGroup, ChannelSet
from granular_mpc.validation.dataformat.drop import drop_channels
from granular_mpc.validation.diagnosis.candidates import build_candidates
from granular_mpc.validation.diagnosis.coverage import (MIN_ASSESSABLE_SIZE, assess_candidates,
                                                        detectable_size,
                                                        drop_unreadable_sensor_candidates)
from granular_mpc.validation.prepare import channel_names, check_replayable, stance_windows
from granular_mpc.validation.replay import validate

PROPRIO_DROP = ("intrusion", "foot_force", "trunk_position", "trunk_linear_velocity")


@pytest.fixture(scope="module")
def full(workbench_data):
    return workbench_data("null")


@pytest.fixture(scope="module")
def proprio(full, tmp_path_factory):
    return drop_channels(full, tmp_path_factory.mktemp("ch") / "proprio", PROPRIO_DROP)


def test_drop_channels_writes_a_valid_data_set_without_the_groups(full, proprio, tmp_path):
    ds = load_dataset(proprio)
    assert set(ds.channels) == {ChannelGroup.JOINT_ANGLES, ChannelGroup.JOINT_VELOCITIES,
                                ChannelGroup.JOINT_TORQUES, ChannelGroup.TRUNK_ORIENTATION,
                                ChannelGroup.TRUNK_ANGULAR_VELOCITY}
    df = ds.trials[ds.trial_names[0]]
    for c in GRF_COLUMNS + INTRUSION_COLUMNS + ("base_x", "base_vz"):
        assert c not in df.columns
    # foot force removed: the contact labels go too, and the loader derives them
    assert ds.stance_source == "kinematics"
    kept = load_dataset(drop_channels(full, tmp_path / "keep", ["intrusion"]))
    assert kept.stance_source == "measured" and "intrusion" not in kept.channels
    assert "grf_z" in kept.trials[kept.trial_names[0]].columns
    with pytest.raises(ConfigError, match="unknown channel group"):
        drop_channels(full, tmp_path / "bad", ["imu"])
    with pytest.raises(ConfigError, match="no channel group would remain"):
        drop_channels(full, tmp_path / "none", [g.value for g in ChannelGroup])


def test_scored_channels_are_those_measured(biped):
    J = list(biped.joint_names)
    only = ChannelSet.of(["joint_angles", "joint_torques", "foot_force"])
    assert channel_names(J, only) == [f"q_{j}" for j in J] + list(GRF_COLUMNS)
    assert channel_names(J) == channel_names(J, ChannelSet.all())
    assert len(channel_names(J)) == len(J) + 6


def test_replay_needs_orientation(full, tmp_path):
    ds = load_dataset(drop_channels(full, tmp_path / "no_imu", ["trunk_orientation"],
                                    stance="keep"))
    with pytest.raises(DataFormatError, match="trunk_orientation"):
        check_replayable(ds)


def test_proprio_windows_score_joint_angles_only(full, proprio, biped):
    """Windows of the proprioceptive copy start within 5 samples (the touchdown budget
    of estimation.touchdown_row) of the contact-labelled ones and carry no absent channel."""
    ref = stance_windows(load_dataset(full), biped)
    wins = stance_windows(load_dataset(proprio), biped)
    assert len(wins) >= len(ref) - 2
    for w in wins:
        assert set(w.meas) == {f"q_{j}" for j in biped.joint_names}
        assert not set(GRF_COLUMNS + INTRUSION_COLUMNS) & set(w.columns)
        near = [r for r in ref if r.trial == w.trial and r.side == w.side]
        assert min(abs(r.row_start - w.row_start) for r in near) <= 5


def test_validate_reports_what_was_not_measured(proprio, tmp_path):
    rep = validate(proprio, tmp_path / "val", workers=1, n_boot=20, figures=False)
    cov = rep.report["coverage"]
    assert set(cov["missing"]) == set(PROPRIO_DROP)
    assert cov["trunk_state"].startswith("leg odometry")
    # touchdowns and the trailing foot's load from an ESTIMATED force, said as such
    assert cov["touchdowns"].startswith("foot force ESTIMATED from the joint torques")
    assert "trailing foot's initial load" in cov["touchdowns"]
    assert rep.report["channels"] == [c for c in rep.report["channels"] if c.startswith("q_")]
    assert set(rep.report["overall_rmse"]["granular"]) == set(rep.report["channels"])
    assert all(np.isfinite(v) for v in rep.report["overall_rmse"]["granular"].values())
    md = (tmp_path / "val" / "report.md").read_text()
    assert "**not measured:** trunk_position, trunk_linear_velocity, foot_force, intrusion" in md
    assert "* touchdowns: foot force ESTIMATED" in md
    on_disk = json.loads((tmp_path / "val" / "report.json").read_text())
    assert "grf_z" in on_disk["coverage"]["not_scored_channels"]


def test_sensor_candidate_reading_an_absent_column_cannot_be_assessed(proprio, biped):
    ds = load_dataset(proprio)
    w = stance_windows(ds, biped)[0]
    cands = build_candidates(["force_sensor_bias", "cohesion"])
    kept, out = drop_unreadable_sensor_candidates(cands, w, ds.joint_names, ds)
    assert list(kept.infos) == ["cohesion"]
    assert [e.name for e in out] == ["force_sensor_bias"] and not out[0].assessable
    assert "foot_force" in out[0].reason


def _fake(channels, groups):
    """A problem / data set / residuals triple with hand-made sensitivities."""
    J = ["a", "b"]
    cs = ChannelSet.of(groups)
    ds = SimpleNamespace(joint_names=J, channels=cs, has=cs.has, stance_source="measured")
    W, B = 6, 4
    windows = [SimpleNamespace(trial="t1", side=("left", "right")[i % 2]) for i in range(W)]
    problem = SimpleNamespace(channels=tuple(channels), windows=windows)
    S_big = np.zeros((W, len(channels), B))
    S_big[:, 0, 1] = 3.0                      # per unit parameter
    S_small = np.full((W, len(channels), B), 0.01)
    return problem, ds, S_big, S_small


def test_assessable_rule_uses_the_sensitivity_on_measured_channels():
    """cohesion's column moves q_a's mean by 3 × step / σ; terrain_slope's by
    0.01 × step / σ: with missing groups the small one is not assessable, with every
    group measured nothing is taken out."""
    cands = build_candidates(["cohesion", "terrain_slope"])
    ch = ["q_a", "q_b"]
    sig = {"q_a": 2.0, "q_b": 2.0}
    step = {c.key: c.step for cols in cands.columns.values() for c in cols}
    for groups, expect_out in [(["joint_angles", "joint_torques", "trunk_orientation",
                                 "trunk_angular_velocity"], {"terrain_slope"}),
                               ([g.value for g in ChannelGroup], set())]:
        problem, ds, S_big, S_small = _fake(ch, groups)
        sens = {k: (S_big if k.startswith("cohesion") else S_small) / step[k] * 1.0
                for k in step}
        res = SimpleNamespace(sens=sens, sigma=sig,
                              geometry=SimpleNamespace(sens={}, sigma=1e-3))
        kept, cov = assess_candidates(problem, ds, cands, res)
        assert set(cov.not_assessable) == expect_out
        assert set(kept.infos) == {"cohesion", "terrain_slope"} - expect_out
        size = {e.name: e.size for e in cov.effects}
        assert size["cohesion"] == pytest.approx(3.0 / 2.0)
        assert size["terrain_slope"] == pytest.approx(0.01 / 2.0)
        assert size["terrain_slope"] < MIN_ASSESSABLE_SIZE <= size["cohesion"]
    assert channel_coverage(ds).missing == ()


def test_collinear_candidates_are_indistinguishable_with_the_measured_channels():
    """cohesion's and elastic_unloading's columns move q_a's phase bin 1 in the same
    proportion (collinear signatures, 1.5 σ each): with missing groups neither can be
    assessed and each is reported indistinguishable from the other; joint_friction moves
    q_b (orthogonal to them): assessable. With every group measured nothing is taken out
    and nothing is reported indistinguishable."""
    cands = build_candidates(["cohesion", "elastic_unloading", "joint_friction"])
    ch = ["q_a", "q_b"]
    sig = {"q_a": 2.0, "q_b": 2.0}
    step = {c.key: c.step for cols in cands.columns.values() for c in cols}
    for groups, expect_out in [(["joint_angles", "joint_torques", "trunk_orientation",
                                 "trunk_angular_velocity"], {"cohesion", "elastic_unloading"}),
                               ([g.value for g in ChannelGroup], set())]:
        problem, ds, S_big, _ = _fake(ch, groups)
        S_orth = np.zeros_like(S_big)
        S_orth[:, 1, 2] = 3.0
        sens = {k: (S_orth if k.startswith("joint_friction") else S_big) / step[k]
                for k in step}
        res = SimpleNamespace(sens=sens, sigma=sig,
                              geometry=SimpleNamespace(sens={}, sigma=1e-3))
        kept, cov = assess_candidates(problem, ds, cands, res)
        assert set(cov.not_assessable) == expect_out
        assert set(kept.infos) == {"cohesion", "elastic_unloading", "joint_friction"} - expect_out
        by = {e.name: e for e in cov.effects}
        assert by["cohesion"].size == pytest.approx(1.5)
        assert by["cohesion"].identifiable_size == pytest.approx(0.0, abs=1e-9)
        assert by["joint_friction"].identifiable_size == pytest.approx(1.5)
        if expect_out:
            assert set(cov.indistinguishable) == {("cohesion", "elastic_unloading"),
                                                  ("elastic_unloading", "cohesion")}
            assert "indistinguishable with the measured channels from elastic_unloading" \
                in by["cohesion"].reason
            assert any("indistinguishable with the measured channels: cohesion, "
                       "elastic_unloading" in line for line in cov.markdown())
        else:
            assert cov.indistinguishable == ()
        assert Coverage.from_dict(json.loads(json.dumps(json_safe(cov.to_dict())))) == cov


def test_detectable_size_is_the_largest_stance_mean_cell_in_sigma():
    S = np.zeros((4, 2, 3))
    S[:, 1, 2] = [1.0, 3.0, 1.0, 3.0]          # mean 2 per unit
    size, ch = detectable_size(S, 0.5, ["x", "y"], {"x": 1.0, "y": 0.25})
    assert size == pytest.approx(2.0 * 0.5 / 0.25) and ch == "y"


def test_cli_drop_channels(full, tmp_path):
    from typer.testing import CliRunner

    from granular_mpc.cli import app

    res = CliRunner().invoke(app, ["drop-channels", str(full), "intrusion", "--out",
                                   str(tmp_path / "cli")])
    assert res.exit_code == 0, res.output
    assert "absent:   intrusion" in res.output
    bad = CliRunner().invoke(app, ["drop-channels", str(full), "imu", "--out",
                                   str(tmp_path / "bad")])
    assert bad.exit_code == 2 and "unknown channel group" in bad.output


def test_diagnosis_without_foot_force_says_so_instead_of_printing_nan(proprio, tmp_path):
    """Joints and IMU only: the calibration has no sinking samples with a measured force;
    the report says there was no equation-error fit (it printed "force residual nan N")."""
    from granular_mpc.validation.diagnose import diagnose

    d = diagnose(proprio, tmp_path / "diag", candidates=["joint_friction"], workers=1)
    assert d.calibration.equation_error.n_samples == 0
    md = (tmp_path / "diag" / "report.md").read_text()
    assert "No equation-error fit: not calibrated by equation error" in md
    assert "nan" not in md.lower().replace("nanosecond", "")
