"""Import from CSV / Parquet files: units, quaternion order, foot-frame forces, clocks."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml
from test_dataformat import FS, JOINTS, make_trial
from typer.testing import CliRunner

from granular_mpc.cli import app
from granular_mpc.exceptions import ConfigError
from granular_mpc.importers import Stream, align, import_log
from granular_mpc.importers.frames import foot_rotations
from granular_mpc.robot import load_biped
from granular_mpc.rotations import matrix_from_quat_wxyz
from granular_mpc.validation.dataformat import ChannelGroup, load_dataset

DEG = np.pi / 180.0
LAB = {j: f"J{k}" for k, j in enumerate(JOINTS)}
LAG = 0.01          # s, the force logger's clock runs behind


@pytest.fixture(scope="module")
def biped():
    return load_biped("yobogo10s", with_visuals=False)


def lab_files(folder, df, biped, fmt="csv"):
    """joints (deg, deg/s, ms), imu (w, x, y, z), foot forces in the foot frame at half rate."""
    folder.mkdir(parents=True, exist_ok=True)
    t_ms = df["time"].to_numpy() * 1e3
    joints = pd.DataFrame({"t_ms": t_ms})
    for j in JOINTS:
        joints[f"{LAB[j]}_deg"] = df[f"q_{j}"] / DEG
        joints[f"{LAB[j]}_dps"] = df[f"dq_{j}"] / DEG
        joints[f"{LAB[j]}_Nm"] = df[f"tau_{j}"]
    imu = pd.DataFrame({"t_ms": t_ms, "w": df.base_qw, "x": df.base_qx, "y": df.base_qy,
                        "z": df.base_qz, "gx": df.base_wx, "gy": df.base_wy, "gz": df.base_wz})
    r_wb = np.array([matrix_from_quat_wxyz(q) for q in
                     df[["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy()])
    q_a = df[[f"q_{j}" for j in JOINTS]].to_numpy()
    f_w = df[["grf_x", "grf_y", "grf_z"]].to_numpy()
    force = pd.DataFrame({"t_s": df["time"].to_numpy()[::2] + LAG})
    world = {}
    for side in ("left", "right"):
        f = np.where((df["stance"].to_numpy() == side)[:, None], f_w, 0.0)
        world[side] = f
        f_f = np.einsum("nji,nkj,nk->ni", foot_rotations(biped, side, q_a), r_wb, f)
        for k, ax in enumerate("xyz"):
            force[f"{side}_{ax}_mN"] = f_f[::2, k] * 1e3
    suffix = ".csv" if fmt == "csv" else ".parquet"
    for name, table in (("joints", joints), ("imu", imu), ("force", force)):
        (table.to_csv(folder / f"{name}{suffix}", index=False) if fmt == "csv"
         else table.to_parquet(folder / f"{name}{suffix}", index=False))
    return folder, world


def lab_mapping(tmp_path, suffix=".csv", **changes):
    data = {
        "robot": "yobogo10s", "terrain": "sand", "sample_rate_hz": FS,
        "commanded_speed_mps": 0.2, "joint_names": {v: k for k, v in LAB.items()},
        "streams": [
            {"source": f"joints{suffix}", "time": "t_ms", "time_scale": 0.001,
             "joint_columns": {"q": "{joint}_deg", "dq": "{joint}_dps", "tau": "{joint}_Nm"},
             "joint_scale": {"q": DEG, "dq": DEG}},
            {"source": f"imu{suffix}", "time": "t_ms", "time_scale": 0.001, "channels": [
                {"to": "trunk_orientation", "fields": ["w", "x", "y", "z"], "order": "wxyz"},
                {"to": "trunk_angular_velocity", "fields": ["gx", "gy", "gz"]}]},
            {"source": f"force{suffix}", "time": "t_s", "time_offset_s": -LAG, "channels": [
                {"to": f"{s}_foot_force", "fields": [f"{s}_{a}_mN" for a in "xyz"],
                 "scale": 1e-3, "frame": "foot"} for s in ("left", "right")]}]}
    data.update(changes)
    p = tmp_path / "map.yaml"
    p.write_text(yaml.safe_dump(data), encoding="utf-8")
    return p


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_lab_files_import_to_the_truth(tmp_path, biped, fmt):
    df = make_trial(n=201)
    folder, world = lab_files(tmp_path / "lab", df, biped, fmt)
    suffix = ".csv" if fmt == "csv" else ".parquet"
    res = import_log(folder, lab_mapping(tmp_path, suffix), tmp_path / "ds")
    assert res.resampled and res.stance is not None and res.stance.source == "force"
    ds = load_dataset(res.path)
    got = ds.trials["trial_001"]
    assert set(ds.channels) == {ChannelGroup.JOINT_ANGLES, ChannelGroup.JOINT_VELOCITIES,
                                ChannelGroup.JOINT_TORQUES, ChannelGroup.TRUNK_ORIENTATION,
                                ChannelGroup.TRUNK_ANGULAR_VELOCITY, ChannelGroup.FOOT_FORCE}
    assert "base_x" not in got.columns and "intrusion_z" not in got.columns
    n = len(got)
    assert n == len(df)                  # the force clock shift is undone: full overlap
    for j in JOINTS:
        np.testing.assert_allclose(got[f"q_{j}"], df[f"q_{j}"][:n], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got["base_qw"], df["base_qw"][:n], rtol=0, atol=1e-12)
    # the foot-frame forces are back in the world frame on the force samples (even rows)
    for side in ("left", "right"):
        np.testing.assert_allclose(got[f"{side}_grf_z"].to_numpy()[::2], world[side][::2, 2],
                                   rtol=0, atol=1e-9)
        np.testing.assert_allclose(got[f"{side}_grf_x"].to_numpy()[::2], world[side][::2, 0],
                                   rtol=0, atol=1e-9)
    assert ds.stance_source == "force"
    known = df["stance"].to_numpy()[:n]
    assert float(np.mean(got["stance"].to_numpy() == known)) > 0.97


def test_wrong_quaternion_order_is_caught_by_the_checks(tmp_path, biped):
    from granular_mpc.exceptions import DataFormatError
    folder, _ = lab_files(tmp_path / "lab", make_trial(), biped)
    m = yaml.safe_load(lab_mapping(tmp_path).read_text())
    m["streams"][1]["channels"][0]["order"] = "xyzw"          # the file is w, x, y, z
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(m))
    with pytest.raises(DataFormatError, match="quaternion order"):
        import_log(folder, tmp_path / "map.yaml", tmp_path / "ds")


def test_missing_column_names_file_and_key(tmp_path, biped):
    folder, _ = lab_files(tmp_path / "lab", make_trial(), biped)
    m = yaml.safe_load(lab_mapping(tmp_path).read_text())
    m["streams"][1]["channels"][1]["fields"][2] = "gz_dps"
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(m))
    with pytest.raises(ConfigError) as info:
        import_log(folder, tmp_path / "map.yaml", tmp_path / "ds")
    assert info.value.key == "streams[1].channels[1].field"
    assert "imu.csv" in str(info.value) and "'gz_dps'" in str(info.value)


def test_align_overlap_grid_and_quaternion_hemisphere():
    t1 = np.arange(0, 1.0001, 0.01)
    t2 = np.arange(0.05, 1.2, 0.02)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(t2), 1))
    q[1::2] *= -1.0                                      # same rotation, alternating sign
    a = align([Stream("a", "streams[0]", t1, {"q_x": 2 * t1}, {}),
               Stream("b", "streams[1]", t2, dict(zip(
                   ["base_qw", "base_qx", "base_qy", "base_qz"], q.T)), {})], 100.0)
    assert a.resampled and a.start_s == pytest.approx(0.05)
    assert a.time[0] == 0.0 and a.time[-1] == pytest.approx(0.95)
    np.testing.assert_allclose(a.values["q_x"], 2 * (a.time + 0.05), atol=1e-12)
    assert np.allclose(np.abs(a.values["base_qw"]), 1.0)
    with pytest.raises(ConfigError, match="do not overlap"):
        align([Stream("a", "s0", t1, {"x": t1}, {}), Stream("b", "s1", t1 + 5, {"y": t1}, {})],
              100.0)
    with pytest.raises(ConfigError, match="filled by two streams"):
        align([Stream("a", "s0", t1, {"x": t1}, {}), Stream("b", "s1", t1, {"x": t1}, {})], 100.0)


def test_cli_import_writes_a_loadable_data_set_and_reports_its_channels(tmp_path, biped):
    df = make_trial(n=201)
    folder, _ = lab_files(tmp_path / "lab", df, biped)
    out = tmp_path / "data"
    res = CliRunner().invoke(app, ["import", str(folder), "--mapping",
                                   str(lab_mapping(tmp_path)), "--out", str(out)])
    assert res.exit_code == 0, res.output
    ds = load_dataset(out)
    assert ds.has(ChannelGroup.JOINT_ANGLES) and not ds.has(ChannelGroup.INTRUSION)
    assert str(out) in res.output


def test_cli_import_bad_mapping_exits_2_naming_the_key(tmp_path, biped):
    df = make_trial(n=201)
    folder, _ = lab_files(tmp_path / "lab", df, biped)
    res = CliRunner().invoke(app, ["import", str(folder), "--mapping",
                                   str(lab_mapping(tmp_path, sample_rate_hz=-5)),
                                   "--out", str(tmp_path / "data")])
    assert res.exit_code == 2
    assert "sample_rate_hz" in res.output
    assert not (tmp_path / "data").exists()


def test_a_declared_torque_hold_reaches_meta_yaml_and_a_negative_one_is_refused(tmp_path, biped):
    folder, _ = lab_files(tmp_path / "lab", make_trial(n=201), biped)
    res = import_log(folder, lab_mapping(tmp_path, torque_hold_s=0.002), tmp_path / "ds")
    assert load_dataset(res.path).meta.torque_hold_s == 0.002
    res = import_log(folder, lab_mapping(tmp_path), tmp_path / "plain")
    assert load_dataset(res.path).meta.torque_hold_s is None
    with pytest.raises(ConfigError) as info:
        import_log(folder, lab_mapping(tmp_path, torque_hold_s=-0.002), tmp_path / "bad")
    assert info.value.key == "torque_hold_s"
    assert not (tmp_path / "bad").exists()


def test_an_unknown_channel_target_is_refused_with_the_allowed_ones(tmp_path, biped):
    """A misspelt `to:` used to be accepted and the channel silently dropped (so it read as
    'not measured'); now the mapping is refused, naming the target and the allowed ones."""
    folder, _ = lab_files(tmp_path / "lab", make_trial(), biped)
    m = yaml.safe_load(lab_mapping(tmp_path).read_text())
    m["streams"][1]["channels"][1]["to"] = "trunk_angular_rate"
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(m))
    with pytest.raises(ConfigError, match="trunk_angular_rate.*trunk_angular_velocity"):
        import_log(folder, tmp_path / "map.yaml", tmp_path / "ds")
    m["streams"][1]["channels"][1] = {"to": "base_wx", "field": "gx"}     # one column: fine
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(m))
    with pytest.raises(ConfigError, match="trunk_angular_velocity is incomplete"):
        import_log(folder, tmp_path / "map.yaml", tmp_path / "ds2")


@pytest.mark.parametrize("fault", ["nan", "backwards"])
def test_a_bad_time_cell_is_named_by_its_sample(tmp_path, biped, fault):
    """A NaN in a file's time column was always reported as 'sample 1'."""
    folder, _ = lab_files(tmp_path / "lab", make_trial(), biped)
    imu = pd.read_csv(folder / "imu.csv")
    if fault == "nan":
        imu.loc[100, "t_ms"] = np.nan
        expect = r"not finite at sample 101 \(nan\)"
    else:
        imu.loc[[121, 122], "t_ms"] = imu.loc[[122, 121], "t_ms"].to_numpy()
        expect = "not strictly increasing at sample 123"
    imu.to_csv(folder / "imu.csv", index=False)
    with pytest.raises(ConfigError, match=expect):
        import_log(folder, lab_mapping(tmp_path), tmp_path / "ds")


def test_a_non_numeric_cell_is_named_by_its_row_and_value(tmp_path, biped):
    """'not numeric' used to name only the column: now the first bad row and its text."""
    folder, _ = lab_files(tmp_path / "lab", make_trial(), biped)
    joints = pd.read_csv(folder / "joints.csv")
    col = next(c for c in joints.columns if c.endswith("_Nm"))
    joints[col] = joints[col].astype(object)
    joints.loc[41, col] = "1.2 Nm"
    joints.to_csv(folder / "joints.csv", index=False)
    with pytest.raises(ConfigError, match=rf"'{col}' is not numeric: 1 cell\(s\), the first in "
                                          r"data row 42 \('1.2 Nm'\)"):
        import_log(folder, lab_mapping(tmp_path), tmp_path / "ds")
