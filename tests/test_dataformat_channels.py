"""Declared channel groups (meta.yaml ``channels``) and derived stance labels."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from synthetic_log import make_contact_log, make_log
from test_dataformat import make_meta, make_trial, problems_of

from granular_mpc.config import load_robot
from granular_mpc.exceptions import ConfigError, DataFormatError
from granular_mpc.validation.dataformat import (ChannelGroup, ChannelSet, derive_stance,
                                                load_dataset, write_dataset)
from granular_mpc.validation.dataformat.robot_facts import load_robot_facts
from granular_mpc.validation.dataformat.stance_derive import (foot_heights, kinematic_labels,
                                                              leading_foot)

JOINTS = tuple(load_robot("yobogo10s").joints)
ALL = [g.value for g in ChannelGroup]


def without(df: pd.DataFrame, *groups: ChannelGroup, stance: bool = True) -> pd.DataFrame:
    cols = [c for g in groups for c in g.columns(JOINTS)] + ([] if stance else ["stance"])
    return df.drop(columns=cols)


def one_trial_meta(channels) -> dict:
    meta = make_meta(channels=channels)
    meta["trials"] = {"trial_001": {"file": "trial_001.csv", "commanded_speed_mps": 0.2}}
    return meta


def test_channel_set_api():
    cs = ChannelSet.of(["joint_angles", "trunk_orientation"])
    assert cs.has(ChannelGroup.JOINT_ANGLES) and cs.has("trunk_orientation")
    assert not cs.has(ChannelGroup.FOOT_FORCE) and ChannelGroup.FOOT_FORCE in cs.missing
    assert cs.columns(JOINTS)[:2] == [f"q_{JOINTS[0]}", f"q_{JOINTS[1]}"]
    assert cs.columns(JOINTS)[-4:] == ["base_qw", "base_qx", "base_qy", "base_qz"]
    assert ChannelSet.all().declared is False and len(ChannelSet.all()) == 9
    assert str(cs) == "joint_angles, trunk_orientation"


def test_no_channels_key_loads_as_before(tmp_path):
    ds = load_dataset(write_dataset(tmp_path / "ds", make_meta(),
                                    {"trial_001": make_trial(), "trial_002": make_trial()}))
    assert ds.channels == ChannelSet.all() and all(ds.has(g) for g in ChannelGroup)
    assert ds.stance_source == "measured" and dict(ds.stance_derivations) == {}
    assert "channels" not in (tmp_path / "ds" / "meta.yaml").read_text()


def test_all_channels_declared_equals_undeclared(tmp_path):
    a = load_dataset(write_dataset(tmp_path / "a", one_trial_meta(None),
                                   {"trial_001": make_trial()}))
    b = load_dataset(write_dataset(tmp_path / "b", one_trial_meta(ALL),
                                   {"trial_001": make_trial()}))
    pd.testing.assert_frame_equal(a.trials["trial_001"], b.trials["trial_001"])
    assert b.channels.declared and b.channels.groups == a.channels.groups


@pytest.mark.parametrize("group", list(ChannelGroup))
def test_each_group_absent(tmp_path, group):
    """Every group can be left out: its columns are absent after loading, never zeros."""
    declared = [g for g in ALL if g != group.value]
    df = without(make_trial(), group)
    ds = load_dataset(write_dataset(tmp_path / "ds", one_trial_meta(declared), {"trial_001": df}))
    assert not ds.has(group) and ds.channels.missing == (group,)
    loaded = ds.trials["trial_001"]
    assert not set(group.columns(JOINTS)) & set(loaded.columns)
    assert ds.stance_source == "measured"
    assert group.value in ds.channel_report().split("absent:")[1]


def test_undeclared_present_group_is_reported(tmp_path):
    declared = [g for g in ALL if g != "intrusion"]
    meta = one_trial_meta(declared)
    folder = write_dataset(tmp_path / "ds", meta, {"trial_001": make_trial()}, check=False)
    probs = problems_of(folder)
    assert len(probs) == 1, "\n".join(map(str, probs))
    p = probs[0]
    assert (p.file, p.column) == ("trial_001.csv", "intrusion_x,intrusion_y,intrusion_z")
    assert "'intrusion' is not declared in meta.yaml channels" in p.message
    assert "never zero-filled" in p.message


def test_declared_missing_group_and_column(tmp_path):
    df = without(make_trial(), ChannelGroup.JOINT_TORQUES).drop(columns=["base_wy"])
    folder = write_dataset(tmp_path / "ds", one_trial_meta(ALL), {"trial_001": df}, check=False)
    probs = problems_of(folder)
    assert len(probs) == 2, "\n".join(map(str, probs))
    tau = next(p for p in probs if p.column.startswith("tau_"))
    assert tau.column == ",".join(f"tau_{j}" for j in JOINTS)
    assert "'joint_torques' is declared in meta.yaml channels but the file has none" in tau.message
    wy = next(p for p in probs if p.column == "base_wy")
    assert "declared channel group 'trunk_angular_velocity'" in wy.message


def test_bad_channels_key(tmp_path):
    with pytest.raises(ConfigError, match="listed more than once"):
        write_dataset(tmp_path / "a", one_trial_meta(["joint_angles", "joint_angles"]),
                      {"trial_001": make_trial()})
    with pytest.raises(ConfigError, match="channels"):
        write_dataset(tmp_path / "b", one_trial_meta(["joint_angels"]),
                      {"trial_001": make_trial()})


def test_stance_required_without_channels_key(tmp_path):
    df = make_trial().drop(columns=["stance"])
    folder = write_dataset(tmp_path / "ds", one_trial_meta(None), {"trial_001": df}, check=False)
    probs = problems_of(folder)
    assert [(p.column, "required column is missing" in p.message) for p in probs] == \
        [("stance", True)]


def test_stance_underivable_names_what_is_needed(tmp_path):
    df = without(make_trial(), ChannelGroup.JOINT_ANGLES, stance=False)
    declared = [g for g in ALL if g != "joint_angles"]
    folder = write_dataset(tmp_path / "ds", one_trial_meta(declared), {"trial_001": df},
                           check=False)
    probs = problems_of(folder)
    assert len(probs) == 1 and probs[0].column == "stance", "\n".join(map(str, probs))
    assert "cannot be derived" in probs[0].message
    assert "joint_angles and trunk_orientation" in probs[0].message


# ------------------------------------------------------------------ derived stance labels


def _v1(df: pd.DataFrame, drop=()) -> pd.DataFrame:
    cols = ["time"] + [c for c in df.columns if c.startswith(("q_", "dq_", "tau_", "base_"))
                       or c in ("grf_x", "grf_y", "grf_z", "intrusion_x", "intrusion_y",
                                "intrusion_z", "left_grf_z", "right_grf_z")]
    return df[cols].drop(columns=list(drop))


def test_leading_foot_rule():
    left = np.array([1, 1, 1, 1, 0, 0, 0, 1, 1], dtype=bool)
    right = np.array([0, 0, 1, 1, 1, 1, 0, 0, 0], dtype=bool)
    assert list(leading_foot(left, right)) == ["left", "left", "right", "right", "right",
                                               "right", "none", "left", "left"]


def test_stance_from_per_foot_force_matches_true_contact(tmp_path):
    """make_contact_log: per-foot forces on the true contacts (early touchdown, late
    lift-off, one chattering sample). Derived labels = leading foot of the true contacts."""
    log = make_contact_log(4, chatter=[("left", 40)])
    n = len(log.df)
    true = {s: np.zeros(n, dtype=bool) for s in ("left", "right")}
    for side, a, b in log.contact:
        true[side][a:b] = True
    expected = leading_foot(true["left"], true["right"])
    # (the synthetic joints jump between stances: joint velocities are left out)
    declared = [g for g in ALL if g not in ("intrusion", "joint_velocities")]
    df = without(_v1(log.df), ChannelGroup.INTRUSION, ChannelGroup.JOINT_VELOCITIES)
    meta = one_trial_meta(declared) | {"sample_rate_hz": 1.0 / log.dt}
    ds = load_dataset(write_dataset(tmp_path / "ds", meta, {"trial_001": df}))
    assert ds.stance_source == "force"
    got = ds.trials["trial_001"]["stance"].to_numpy()
    assert list(got) == list(expected)
    d = ds.stance_derivations["trial_001"]
    assert d.source == "force" and "left_grf_z / right_grf_z" in d.method
    assert d.rows["left"] == int(np.sum(expected == "left"))
    assert "stance:   force" in ds.channel_report()
    # a copy keeps the labels derived, not measured
    copy = load_dataset(ds.write(tmp_path / "copy", "parquet"))
    assert copy.stance_source == "force"


def test_stance_from_kinematics_matches_known_labels():
    """make_log: the swing knee bends 0.6 rad more than the stance knee, so the swing foot
    is higher. Kinematic labels agree with the known stance in ≥ 95 % of the stance rows."""
    L = make_log(6, stance_rows=101, lead_rows=0)
    facts = load_robot_facts("yobogo10s", None)
    values = {c: L.df[c].to_numpy(dtype=float) for c in L.df.columns
              if c.startswith(("time", "q_", "base_q"))}
    cs = ChannelSet.of(["joint_angles", "trunk_orientation"])
    labels, d = derive_stance(values, facts, cs)
    known = L.df["stance"].to_numpy()
    assert d.source == "kinematics" and d.rows["none"] == 0
    agree = float(np.mean(labels == known))
    assert agree >= 0.95, agree
    # every known change of stance foot is found within 8 samples (16 ms)
    found = [k for k in range(1, len(labels)) if labels[k] != labels[k - 1]]
    for k in (k for k in range(1, len(known)) if known[k] != known[k - 1]):
        assert min(abs(k - f) for f in found) <= 8, (k, found)
    assert d.touchdowns == len(found) and 5 <= len(found) <= 6


def test_kinematic_labels_need_steps():
    z = np.zeros(50)
    assert kinematic_labels({"left": z, "right": z + 1e-4}, np.arange(50) * 0.01) is None


def test_grf_only_timing_with_kinematic_side():
    """With only the stance-foot grf_z: the timing from the force, the side from kinematics."""
    L = make_log(4, stance_rows=101, lead_rows=20, gap_rows=20)   # gaps longer than a bounce
    facts = load_robot_facts("yobogo10s", None)
    values = {c: L.df[c].to_numpy(dtype=float) for c in L.df.columns if c != "stance"}
    del values["left_grf_z"], values["right_grf_z"]
    cs = ChannelSet.of(["joint_angles", "trunk_orientation", "foot_force"])
    labels, d = derive_stance(values, facts, cs)
    known = L.df["stance"].to_numpy()
    assert d.source == "force" and "side from leg kinematics" in d.method
    assert np.all(labels[known == "none"] == "none")
    assert float(np.mean(labels[known != "none"] == known[known != "none"])) >= 0.95


def test_heights_use_trunk_orientation():
    facts = load_robot_facts("yobogo10s", None)
    q = {f"q_{j}": np.full(2, v) for j, v in zip(JOINTS, (0, -0.6, 1.2, 0, -0.6, 1.2))}
    level = dict(q, base_qw=np.ones(2), base_qx=np.zeros(2), base_qy=np.zeros(2),
                 base_qz=np.zeros(2))
    h = foot_heights(level, facts)
    assert np.allclose(h["left"], h["right"]) and np.all(h["left"] < -0.2)
    c, s = np.cos(0.1), np.sin(0.1)                      # roll 0.2 rad about +x
    rolled = dict(level, base_qw=np.full(2, c), base_qx=np.full(2, s))
    h2 = foot_heights(rolled, facts)
    assert h2["left"][0] > h2["right"][0]                # roll about +x lifts the left (+y) foot


def test_mixed_measured_and_derived_is_reported(tmp_path):
    log = make_contact_log(4)
    df = without(_v1(log.df), ChannelGroup.INTRUSION, ChannelGroup.JOINT_VELOCITIES)
    labelled = df.copy()
    labelled.insert(1, "stance", log.df["stance"].to_numpy())
    meta = make_meta(channels=[g for g in ALL if g not in ("intrusion", "joint_velocities")],
                     sample_rate_hz=1 / log.dt)
    with pytest.raises(DataFormatError, match="stance labels come from force here"):
        load_dataset(write_dataset(tmp_path / "ds", meta,
                                   {"trial_001": labelled, "trial_002": df}, check=False))
