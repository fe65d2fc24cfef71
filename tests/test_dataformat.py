"""Measurement data format v1: round trips, and one failing data set per loader check.

Every bad data set is a clean one (``make_trial``) with one defect injected, so each test
can assert the exact problem (file, column, first row, wording) and that nothing else is
reported.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from granular_mpc.config import load_robot
from granular_mpc.exceptions import ConfigError, DataFormatError, DataProblem, OutputError
from granular_mpc.validation import (Dataset, DatasetMeta, FormatTolerances, StancePhase,
                                     check_dataset, check_trials, format_columns, load_dataset,
                                     stance_phases, write_dataset)

JOINTS = tuple(load_robot("yobogo10s").joints)
STAND = (0.0, -0.6, 1.2, 0.0, -0.6, 1.2)          # rad, standing pose of models/yobogo10s.yaml
AMP = (0.05, 0.3, 0.3, 0.05, 0.3, 0.3)            # rad
FS = 200.0                                         # Hz
WEIGHT = 104.4                                     # N, about m g of yobogo10s
QUAT = ["base_qw", "base_qx", "base_qy", "base_qz"]
QCOLS = ",".join(QUAT)


def make_trial(n: int = 200, *, speed: float = 0.2, phase: float = 0.0) -> pd.DataFrame:
    """A kinematically consistent walking trial: every velocity is the exact derivative.

    Joints oscillate at the gait frequency (2.5 Hz) about the standing pose; the trunk
    moves along +x at ``speed`` with a lateral sway, a vertical bob, and yaw ψ and roll φ
    oscillations (R = Rz(ψ) Rx(φ), so ω_B = (φ̇, ψ̇ sin φ, ψ̇ cos φ)). Stance alternates
    left/right every 0.2 s; the stance foot carries about the robot's weight and sinks
    2 cm during each stance.
    """
    t = np.arange(n) / FS
    w = 2 * np.pi * 2.5
    d: dict[str, object] = {"time": t}
    d["stance"] = np.where(np.floor(t / 0.2 + 1e-9).astype(int) % 2 == 0, "left", "right")
    for k, j in enumerate(JOINTS):
        d[f"q_{j}"] = STAND[k] + AMP[k] * np.sin(w * t + k + phase)
    for k, j in enumerate(JOINTS):
        d[f"dq_{j}"] = AMP[k] * w * np.cos(w * t + k + phase)
    for k, j in enumerate(JOINTS):
        d[f"tau_{j}"] = 5.0 * np.sin(w * t + 2 * k)
    d["base_x"] = speed * t
    d["base_y"] = 0.02 * np.sin(w / 2 * t)
    d["base_z"] = 0.47 + 0.005 * np.sin(2 * w * t)
    yaw, dyaw = 0.05 * np.sin(w / 2 * t), 0.05 * w / 2 * np.cos(w / 2 * t)
    roll, droll = 0.03 * np.sin(w / 2 * t + 1), 0.03 * w / 2 * np.cos(w / 2 * t + 1)
    a, b, c, s = np.cos(yaw / 2), np.sin(yaw / 2), np.cos(roll / 2), np.sin(roll / 2)
    d["base_qw"], d["base_qx"], d["base_qy"], d["base_qz"] = a * c, a * s, b * s, b * c
    d["base_vx"] = np.full(n, speed)
    d["base_vy"] = 0.02 * w / 2 * np.cos(w / 2 * t)
    d["base_vz"] = 0.005 * 2 * w * np.cos(2 * w * t)
    d["base_wx"], d["base_wy"], d["base_wz"] = droll, dyaw * np.sin(roll), dyaw * np.cos(roll)
    ph = (t % 0.2) / 0.2
    d["grf_x"] = 5 * np.sin(2 * np.pi * ph)
    d["grf_y"] = 2 * np.sin(2 * np.pi * ph)
    d["grf_z"] = WEIGHT * (1 + 0.3 * np.sin(np.pi * ph))
    d["intrusion_x"] = 0.003 * ph
    d["intrusion_y"] = np.zeros(n)
    d["intrusion_z"] = 0.02 * ph
    return pd.DataFrame(d)


def make_meta(**top) -> dict:
    meta = {"schema_version": 1, "robot": "yobogo10s", "terrain": "dry play sand, 12 cm layer",
            "sample_rate_hz": FS,
            "trials": {"trial_001": {"file": "trial_001.csv", "commanded_speed_mps": 0.2},
                       "trial_002": {"file": "trial_002.csv", "commanded_speed_mps": 0.3}}}
    meta.update(top)
    return meta


def clean_trials() -> dict[str, pd.DataFrame]:
    return {"trial_001": make_trial(), "trial_002": make_trial(speed=0.3, phase=0.5)}


def write(tmp_path: Path, trials: dict | None = None, fmt: str = "csv",
          meta: dict | None = None) -> Path:
    """Write a (possibly broken) data set without the writer's checks."""
    return write_dataset(tmp_path / "ds", meta or make_meta(), trials or clean_trials(), fmt,
                         check=False)


def problems_of(path: Path) -> list[DataProblem]:
    """The problems of the DataFormatError that load_dataset must raise."""
    with pytest.raises(DataFormatError) as info:
        load_dataset(path)
    assert info.value.root == str(path)
    return info.value.problems


def only(problems: list[DataProblem], *, file: str, column: str = "", row: int | None = None,
         text: str = "") -> DataProblem:
    """Assert ``problems`` is exactly one problem with these fields; return it."""
    assert len(problems) == 1, "\n".join(map(str, problems))
    p = problems[0]
    assert (p.file, p.column, p.row) == (file, column, row), str(p)
    assert text in p.message, str(p)
    return p


def has(problems: list[DataProblem], *, file: str, column: str = "", row: int | None = None,
        text: str = "") -> DataProblem:
    """Assert one of ``problems`` has these fields; return it."""
    for p in problems:
        if (p.file, p.column, p.row) == (file, column, row) and text in p.message:
            return p
    raise AssertionError(f"no problem {file}/{column}/{row}/{text!r} in:\n"
                         + "\n".join(map(str, problems)))


def rewrite_csv(path: Path, edit) -> None:
    """Apply ``edit(list of text lines) -> list`` to a CSV file."""
    lines = path.read_text(encoding="utf-8").splitlines()
    path.write_text("\n".join(edit(lines)) + "\n", encoding="utf-8")


# ------------------------------------------------------------------------ round trips


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_round_trip_equals_input(tmp_path, fmt):
    trials = clean_trials()
    trials["trial_002"]["left_contact"] = np.arange(200) % 2           # extra int column
    trials["trial_002"]["note"] = "ok"                                 # extra text column
    meta = make_meta(generator={"seed": 3, "effects": ["inertial_drag:c_d=1.2"],
                                "noise": {"grf_": 0.5}})
    before = copy.deepcopy(trials)
    folder = write_dataset(tmp_path / "ds", meta, trials, fmt)
    for df, orig in zip(trials.values(), before.values()):
        pd.testing.assert_frame_equal(df, orig)                        # input untouched
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        ["meta.yaml", f"trial_001.{fmt}", f"trial_002.{fmt}"])
    ds = load_dataset(folder)
    assert isinstance(ds, Dataset)
    assert ds.path == folder.resolve()
    assert ds.joint_names == JOINTS
    assert ds.trial_names == ("trial_001", "trial_002")
    assert ds.meta.trials["trial_002"].file == f"trial_002.{fmt}"
    assert ds.meta.generator.effects[0].name == "inertial_drag"
    assert ds.meta.generator.effects[0].params == {"c_d": 1.2}
    assert ds.commanded_speed("trial_002") == 0.3
    for name in trials:
        pd.testing.assert_frame_equal(ds.trials[name], trials[name], check_exact=True)
    # extra columns are kept with their values
    assert ds.trials["trial_002"]["left_contact"].tolist() == (np.arange(200) % 2).tolist()
    assert set(ds.trials["trial_002"]["note"]) == {"ok"}
    assert check_dataset(folder) == []
    with pytest.raises(TypeError):
        ds.trials["trial_003"] = make_trial()                          # read-only mapping


def test_meta_round_trip_and_written_yaml(tmp_path):
    folder = write_dataset(tmp_path / "ds", make_meta(description="pilot"), clean_trials())
    raw = yaml.safe_load((folder / "meta.yaml").read_text())
    assert list(raw)[:5] == ["schema_version", "robot", "terrain", "sample_rate_hz", "trials"]
    assert raw["trials"]["trial_001"] == {"file": "trial_001.csv", "commanded_speed_mps": 0.2}
    assert load_dataset(folder).meta == DatasetMeta.model_validate(make_meta(description="pilot"))


def test_csv_to_parquet_conversion_and_frame_helpers(tmp_path):
    ds = load_dataset(write(tmp_path))
    pq = load_dataset(ds.write(tmp_path / "pq", "parquet"))
    assert (tmp_path / "pq" / "trial_001.parquet").is_file()
    for name in ds.trials:
        pd.testing.assert_frame_equal(pq.trials[name], ds.trials[name], check_exact=True)
    frame = ds.to_frame()
    assert list(frame.columns[:4]) == ["trial", "row", "commanded_speed_mps", "time"]
    assert len(frame) == 400
    assert frame.loc[200, ["trial", "row", "commanded_speed_mps"]].tolist() == ["trial_002", 1, 0.3]
    assert ds.joint_columns("tau") == [f"tau_{j}" for j in JOINTS]
    assert format_columns(JOINTS)[:3] == ["time", "stance", f"q_{JOINTS[0]}"]


def test_stance_phases_are_maximal_runs():
    df = pd.DataFrame({"stance": ["left"] * 3 + ["none"] * 2 + ["right"] * 4 + ["left"]})
    phases = stance_phases(df, trial="t")
    assert phases == [StancePhase("t", 0, 3, "left", False), StancePhase("t", 3, 5, "none", True),
                      StancePhase("t", 5, 9, "right", True), StancePhase("t", 9, 10, "left", False)]
    right = phases[2]
    assert (right.first_row, right.last_row, right.n_rows) == (6, 9, 4)
    assert df.iloc[right.row_start:right.row_stop]["stance"].eq("right").all()
    assert [p.side for p in stance_phases(df, sides=("left", "right"))] == ["left", "right", "left"]
    with pytest.raises(DataFormatError) as info:
        stance_phases(pd.DataFrame({"stance": ["left", "Right"]}))
    assert info.value.problems[0].row == 2


def test_dataset_stance_phases_cover_every_row(tmp_path):
    ds = load_dataset(write(tmp_path))
    phases = ds.stance_phases()
    for name, df in ds.trials.items():
        mine = [p for p in phases if p.trial == name]
        assert mine[0].row_start == 0 and mine[-1].row_stop == len(df)
        assert all(a.row_stop == b.row_start and a.side != b.side for a, b in zip(mine, mine[1:]))
        assert [p.complete for p in mine] == [False] + [True] * (len(mine) - 2) + [False]


def test_noisy_but_correct_data_loads(tmp_path):
    """Sensor noise of realistic size must not trigger any unit or consistency heuristic."""
    rng = np.random.default_rng(1)
    trials = clean_trials()
    for df in trials.values():
        n = len(df)
        for col, sd in [("q_", 2e-3), ("dq_", 0.05), ("tau_", 0.2), ("base_x", 1e-3),
                        ("base_y", 1e-3), ("base_z", 1e-3), ("base_v", 0.02), ("base_w", 0.02),
                        ("grf_", 3.0), ("intrusion_", 1e-3)]:
            for c in [c for c in df.columns if c.startswith(col)]:
                df[c] = df[c] + rng.normal(0.0, sd, n)
        q = df[QUAT].to_numpy() + rng.normal(0.0, 1e-3, (n, 4))
        df[QUAT] = q / np.linalg.norm(q, axis=1, keepdims=True)
        df["time"] = df["time"] + rng.uniform(-2e-4, 2e-4, n)           # timestamp jitter
    assert check_dataset(write(tmp_path, trials)) == []


# ------------------------------------------------------------------------ meta.yaml


def test_missing_folder_and_missing_meta(tmp_path):
    only(problems_of(tmp_path / "nope"), file=str(tmp_path / "nope"), text="folder not found")
    folder = write(tmp_path)
    (folder / "meta.yaml").unlink()
    only(problems_of(folder), file="meta.yaml", text="meta.yaml is missing")


def test_malformed_yaml_names_the_line(tmp_path):
    folder = write(tmp_path)
    (folder / "meta.yaml").write_text("schema_version: 1\nrobot: [yobogo10s\n")
    only(problems_of(folder), file="meta.yaml", text="malformed YAML at line 3")
    (folder / "meta.yaml").write_text("- schema_version: 1\n")
    only(problems_of(folder), file="meta.yaml", text="top level must be a mapping")


@pytest.mark.parametrize("version, text", [(2, "2 is not supported"), ("1", "'1' is not supported"),
                                           (None, "required key is missing")])
def test_schema_version(tmp_path, version, text):
    meta = make_meta(schema_version=version)
    if version is None:
        del meta["schema_version"]
    folder = write(tmp_path)
    (folder / "meta.yaml").write_text(yaml.safe_dump(meta))
    only(problems_of(folder), file="meta.yaml", text=f"schema_version: {text}" if version
         else "schema_version: required key is missing")


def test_meta_missing_unknown_and_wrong_keys_all_reported(tmp_path):
    meta = make_meta()
    del meta["sample_rate_hz"]
    meta["sample_rate"] = 200                                          # typo of sample_rate_hz
    meta["trials"]["trial_002"]["commanded_speed_mps"] = "fast"
    meta["trials"]["trial_001"]["file"] = "trial_001.txt"
    meta["torque_hold_s"] = -0.002                                     # a hold is ≥ 0
    folder = write(tmp_path, meta={**make_meta()})
    (folder / "meta.yaml").write_text(yaml.safe_dump(meta))
    probs = problems_of(folder)
    has(probs, file="meta.yaml", text="sample_rate_hz: required key is missing")
    has(probs, file="meta.yaml", text="unknown key 'sample_rate'; did you mean 'sample_rate_hz'?")
    has(probs, file="meta.yaml", text="trials.trial_002.commanded_speed_mps: Input should be a valid number")
    has(probs, file="meta.yaml", text="trials.trial_001.file: 'trial_001.txt' must end in .csv or .parquet")
    # trial_001.csv is now not listed (the meta names trial_001.txt)
    has(probs, file="trial_001.csv", text="not listed under trials")
    has(probs, file="meta.yaml", text="torque_hold_s: Input should be greater than or equal to 0")
    assert len(probs) == 6, "\n".join(map(str, probs))


def test_meta_problems_do_not_hide_trial_problems(tmp_path):
    trials = clean_trials()
    trials["trial_002"].loc[4, "grf_x"] = np.nan
    meta = make_meta(operator="me")
    folder = write(tmp_path, trials)
    (folder / "meta.yaml").write_text(yaml.safe_dump(meta))
    probs = problems_of(folder)
    assert len(probs) == 2
    has(probs, file="meta.yaml", text="unknown key 'operator'")
    has(probs, file="trial_002.csv", column="grf_x", row=5, text="empty or NaN values in row 5")


def test_bad_trial_names_and_shared_files(tmp_path):
    meta = make_meta()
    meta["trials"]["bad name"] = {"file": "trial_001.csv", "commanded_speed_mps": 0.1}
    folder = write(tmp_path)
    (folder / "meta.yaml").write_text(yaml.safe_dump(meta))
    probs = problems_of(folder)
    has(probs, file="meta.yaml", text="trial name 'bad name' is not valid")
    has(probs, file="meta.yaml", text="use the same file 'trial_001.csv'")


def test_unknown_robot(tmp_path):
    folder = write(tmp_path, meta=make_meta(robot="no_such_robot"))
    p = only(problems_of(folder), file="meta.yaml", text="robot")
    assert "no_such_robot" in p.message and "yobogo10s" in p.message   # lists the known robots


def test_robot_file_next_to_the_data_and_reloaded_when_changed(tmp_path):
    """A robot YAML in the data set folder is found; editing its URDF is seen at once."""
    import shutil

    from granular_mpc.paths import resolve_file

    folder = write(tmp_path, meta=make_meta(robot="myrobot.yaml"))
    src = resolve_file("robot", "yobogo10s")
    shutil.copy(src, folder / "myrobot.yaml")
    shutil.copy(src.with_suffix(".urdf"), folder / "yobogo10s.urdf")
    assert check_dataset(folder) == []
    urdf = folder / "yobogo10s.urdf"
    text = urdf.read_text()
    assert text.count('lower="0.1" upper="2.6"') == 2
    urdf.write_text(text.replace('lower="0.1" upper="2.6"', 'lower="0.1" upper="1.25"'))
    probs = problems_of(folder)
    has(probs, file="trial_001.csv", column="q_left_knee", row=1,
        text="outside the joint limits [0.1, 1.25] rad")
    # slightly beyond the limits is not "degrees", even though the values converted to
    # radians would fit: only an excursion larger than the joint's range suggests degrees
    assert not any("degree" in p.message for p in probs), "\n".join(map(str, probs))


def test_implausible_commanded_speed(tmp_path):
    meta = make_meta()
    meta["trials"]["trial_002"]["commanded_speed_mps"] = 30.0        # cm/s
    folder = write(tmp_path, meta=meta)
    has(problems_of(folder), file="meta.yaml",
        text="trials.trial_002.commanded_speed_mps: 30 is implausible for m/s")


# ------------------------------------------------------------------------ trial files


def test_missing_and_unlisted_trial_files(tmp_path):
    folder = write(tmp_path)
    (folder / "trial_002.csv").rename(folder / "trial_002_old.csv")
    probs = problems_of(folder)
    assert len(probs) == 2
    has(probs, file="trial_002.csv", text="trial file of trial 'trial_002' not found")
    has(probs, file="trial_002_old.csv", text="not listed under trials in meta.yaml")


def test_ragged_csv_lines_are_reported_with_their_rows(tmp_path):
    folder = write(tmp_path)

    def edit(lines):
        lines[5] = lines[5] + ",7"                        # data row 5: one field too many
        lines[9] = ",".join(lines[9].split(",")[:10])     # data row 9: truncated
        lines[12] = ""                                    # data row 12: blank line
        return lines

    rewrite_csv(folder / "trial_001.csv", edit)
    probs = problems_of(folder)
    n_fields = len(format_columns(JOINTS))
    has(probs, file="trial_001.csv", row=5, text=f"{n_fields + 1} field(s) where the header has {n_fields}")
    has(probs, file="trial_001.csv", row=9, text=f"10 field(s) where the header has {n_fields}")
    has(probs, file="trial_001.csv", row=12, text="blank line in row 12")
    assert len(probs) == 3, "\n".join(map(str, probs))


def test_unreadable_files(tmp_path):
    meta = make_meta()
    meta["trials"]["trial_001"]["file"] = "trial_001.parquet"
    folder = write(tmp_path)
    (folder / "meta.yaml").write_text(yaml.safe_dump(meta))
    (folder / "trial_001.csv").unlink()
    (folder / "trial_001.parquet").write_bytes(b"PAR1 this is not parquet")
    (folder / "trial_002.csv").write_text("")
    probs = problems_of(folder)
    assert len(probs) == 2
    has(probs, file="trial_001.parquet", text="cannot read as Parquet")
    has(probs, file="trial_002.csv", text="file is empty")


def test_semicolon_separated_csv(tmp_path):
    folder = write(tmp_path)
    rewrite_csv(folder / "trial_001.csv", lambda lines: [ln.replace(",", ";") for ln in lines])
    only(problems_of(folder), file="trial_001.csv", text="separated by commas")


def test_missing_columns_with_hints(tmp_path):
    trials = clean_trials()
    df = trials["trial_001"]
    trials["trial_001"] = df.drop(columns=["grf_y"]).rename(
        columns={"time": "Time", "q_left_knee": "q_left_knee_deg"})
    probs = problems_of(write(tmp_path, trials))
    assert len(probs) == 4, "\n".join(map(str, probs))
    has(probs, file="trial_001.csv", column="time", text="column 'Time' differs only in case")
    has(probs, file="trial_001.csv", column="q_left_knee", text="did you mean 'q_left_knee_deg'?")
    has(probs, file="trial_001.csv", column="grf_y", text="required column is missing")
    has(probs, file="trial_001.csv", column="q_left_knee_deg",
        text="'left_knee_deg' is not an actuated joint")


def test_joint_not_in_robot(tmp_path):
    trials = clean_trials()
    trials["trial_002"]["tau_left_ankle"] = 0.0
    p = only(problems_of(write(tmp_path, trials)), file="trial_002.csv", column="tau_left_ankle",
             text="'left_ankle' is not an actuated joint of robot 'yobogo10s'")
    assert "left_knee" in p.message                                       # lists the real joints


def test_duplicate_column_names(tmp_path):
    folder = write(tmp_path)
    rewrite_csv(folder / "trial_001.csv",
                lambda ls: [ls[0] + ",grf_x"] + [ln + ",0" for ln in ls[1:]])
    only(problems_of(folder), file="trial_001.csv", column="grf_x", text="appears 2 times")


def test_too_few_rows(tmp_path):
    trials = clean_trials()
    trials["trial_001"] = trials["trial_001"].iloc[:1]
    only(problems_of(write(tmp_path, trials)), file="trial_001.csv",
         text="has 1 data row(s); a trial needs at least 2")


# ------------------------------------------------------------------------ values


def test_non_numeric_cells(tmp_path):
    folder = write(tmp_path)

    def edit(lines):
        header = lines[0].split(",")
        k = header.index("q_left_knee")
        for row in (5, 6, 9):
            fields = lines[row].split(",")
            fields[k] = "1,5" if row == 9 else "abc"
            lines[row] = ",".join(fields) if row != 9 else ",".join(fields[:k] + ['"1,5"'] + fields[k + 1:])
        return lines

    rewrite_csv(folder / "trial_002.csv", edit)
    only(problems_of(folder), file="trial_002.csv", column="q_left_knee", row=5,
         text="non-numeric values (e.g. 'abc', '1,5') in rows 5–6, 9 (3 rows)")


def test_non_finite_values_are_grouped_by_runs(tmp_path):
    trials = clean_trials()
    df = trials["trial_001"]
    df.loc[11:39, "q_left_knee"] = np.nan                      # data rows 12–40
    df.loc[2, "tau_left_knee"] = np.inf
    df.loc[[3, 4, 5, 7], "tau_left_knee"] = -np.inf
    probs = problems_of(write(tmp_path, trials))
    assert len(probs) == 2
    has(probs, file="trial_001.csv", column="q_left_knee", row=12,
        text="empty or NaN values in rows 12–40 (29 rows)")
    has(probs, file="trial_001.csv", column="tau_left_knee", row=3,
        text="infinite values in rows 3–6, 8 (5 rows)")


@pytest.mark.timing
def test_ten_thousand_bad_rows_make_one_bounded_problem(tmp_path):
    n = 10_000
    trials = {"trial_001": make_trial(n), "trial_002": make_trial(speed=0.3)}
    trials["trial_001"].loc[::2, "grf_x"] = np.nan              # every other row
    meta = make_meta()
    for entry in meta["trials"].values():
        entry["file"] = entry["file"].replace(".csv", ".parquet")
    folder = write(tmp_path, trials, "parquet", meta)
    t0 = time.perf_counter()
    p = only(problems_of(folder), file="trial_001.parquet", column="grf_x", row=1)
    # measured 0.2–0.4 s idle; 3 s holds at load 2 with a wide margin (a check that walked
    # the rows one by one in Python would take > 10 s)
    assert time.perf_counter() - t0 < 3.0
    assert "(5000 rows)" in p.message and "… and 4990 more runs" in p.message
    assert len(p.message) < 200


def test_time_not_strictly_increasing(tmp_path):
    trials = clean_trials()
    df = trials["trial_001"]
    df.loc[9, "time"] = df.loc[8, "time"]                        # data row 10 repeats row 9
    df.loc[19, "time"] = 0.0                                     # data row 20 goes back
    probs = problems_of(write(tmp_path, trials))
    assert len(probs) == 2, "\n".join(map(str, probs))
    has(probs, file="trial_001.csv", column="time", row=10, text="repeats the value of the previous row")
    has(probs, file="trial_001.csv", column="time", row=20, text="goes backwards")


def test_bad_stance_labels(tmp_path):
    trials = clean_trials()
    df = trials["trial_001"]
    df.loc[0:9, "stance"] = "Left"
    df.loc[50, "stance"] = ""
    df.loc[60:61, "stance"] = "both"
    probs = problems_of(write(tmp_path, trials))
    assert len(probs) == 3
    has(probs, file="trial_001.csv", column="stance", row=1,
        text="stance label 'Left' is not left, right or none (labels are lower case) in rows 1–10 (10 rows)")
    has(probs, file="trial_001.csv", column="stance", row=51, text="empty stance label in row 51")
    has(probs, file="trial_001.csv", column="stance", row=61, text="'both'")


def test_all_none_stance(tmp_path):
    trials = clean_trials()
    trials["trial_002"]["stance"] = "none"
    only(problems_of(write(tmp_path, trials)), file="trial_002.csv", column="stance",
         text="no stance phase")


def test_quaternion_not_unit(tmp_path):
    trials = clean_trials()
    trials["trial_002"].loc[100:110, "base_qw"] *= 1.1
    only(problems_of(write(tmp_path, trials)), file="trial_002.csv", column=QCOLS, row=101,
         text="is not unit (|‖q‖ − 1| > 0.001) in rows 101–111 (11 rows)")


def test_quaternion_tolerance_is_adjustable(tmp_path):
    trials = clean_trials()
    trials["trial_002"]["base_qw"] *= 1.002
    folder = write(tmp_path, trials)
    assert len(check_dataset(folder)) == 1
    assert check_dataset(folder, tolerances=FormatTolerances(quaternion_norm=5e-3)) == []


def test_quaternion_in_xyzw_order(tmp_path):
    trials = clean_trials()
    df = trials["trial_001"]
    df[QUAT] = df[QUAT].to_numpy()[:, [1, 2, 3, 0]]              # (x, y, z, w) under w, x, y, z
    only(problems_of(write(tmp_path, trials)), file="trial_001.csv", column=QCOLS,
         text="written as (x, y, z, w)?")


def test_trunk_lying_on_its_side(tmp_path):
    trials = clean_trials()
    df = trials["trial_002"]
    df[QUAT] = np.tile([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0], (len(df), 1))  # roll 90°
    df[["base_wx", "base_wy", "base_wz"]] = 0.0
    only(problems_of(write(tmp_path, trials)), file="trial_002.csv", column=QCOLS,
         text="tilted by more than 60° from upright")


def test_parquet_column_types_are_checked(tmp_path):
    trials = clean_trials()
    trials["trial_001"]["grf_z"] = trials["trial_001"]["grf_z"].map(str)   # numbers as text
    trials["trial_002"]["grf_y"] = trials["trial_002"]["grf_y"] > 0         # booleans
    meta = make_meta(trials={"trial_001": {"file": "trial_001.parquet", "commanded_speed_mps": 0.2},
                             "trial_002": {"file": "trial_002.parquet", "commanded_speed_mps": 0.3}})
    probs = problems_of(write(tmp_path, trials, "parquet", meta))
    assert len(probs) == 2
    has(probs, file="trial_001.parquet", column="grf_z", row=1, text="wants a floating-point column")
    has(probs, file="trial_002.parquet", column="grf_y", row=1, text="true/false values")


# ------------------------------------------------------------------------ sampling


def test_sample_rate_inconsistent_with_meta(tmp_path):
    folder = write(tmp_path, meta=make_meta(sample_rate_hz=100.0))
    probs = problems_of(folder)
    assert len(probs) == 2
    for file in ("trial_001.csv", "trial_002.csv"):
        has(probs, file=file, column="time", text="(200 Hz) does not match sample_rate_hz = 100")


def test_time_in_milliseconds(tmp_path):
    trials = clean_trials()
    trials["trial_001"]["time"] *= 1000.0
    only(problems_of(write(tmp_path, trials)), file="trial_001.csv", column="time",
         text="is time in milliseconds?")


def test_irregular_short_steps(tmp_path):
    trials = clean_trials()
    trials["trial_001"].loc[70, "time"] = trials["trial_001"].loc[69, "time"] + 0.001
    probs = problems_of(write(tmp_path, trials))      # row 71 stamped 4 ms early
    assert len(probs) == 2
    has(probs, file="trial_001.csv", column="time", row=71,
        text="time step shorter than 0.0025 s = 0.5/sample_rate_hz (irregular sampling?) in row 71")
    has(probs, file="trial_001.csv", column="time", row=72, text="time step longer than 0.0075 s")


def test_missing_samples(tmp_path):
    trials = clean_trials()
    trials["trial_002"] = trials["trial_002"].drop(index=range(50, 60)).reset_index(drop=True)
    only(problems_of(write(tmp_path, trials)), file="trial_002.csv", column="time", row=51,
         text="(samples missing?) in row 51; largest step 0.055 s")


# ------------------------------------------------------------------------ units


def test_joint_angles_in_degrees(tmp_path):
    trials = clean_trials()
    df = trials["trial_001"]
    for j in JOINTS:
        df[f"q_{j}"] = np.rad2deg(df[f"q_{j}"])
    probs = problems_of(write(tmp_path, trials))
    assert len(probs) == len(JOINTS), "\n".join(map(str, probs))
    for j in JOINTS:
        has(probs, file="trial_001.csv", column=f"q_{j}",
            row=next(p.row for p in probs if p.column == f"q_{j}"),
            text="fit them after a degree→radian conversion: degrees?")
    # the knee (limits [0.1, 2.6] rad) is out of range from the first row
    assert next(p for p in probs if p.column == "q_left_knee").row == 1


def test_joint_velocities_in_degrees_per_second(tmp_path):
    trials = clean_trials()
    df = trials["trial_002"]
    df["dq_left_hip_abd"] = np.rad2deg(df["dq_left_hip_abd"])     # small: within the limit
    df["dq_left_knee"] = np.rad2deg(df["dq_left_knee"])           # large: beyond the limit
    probs = problems_of(write(tmp_path, trials))
    assert len(probs) == 2, "\n".join(map(str, probs))
    has(probs, file="trial_002.csv", column="dq_left_hip_abd",
        text="a factor of 57.3: velocity in degrees per second?")
    p = next(p for p in probs if p.column == "dq_left_knee")
    assert "velocity limit 20 rad/s" in p.message and "degrees per second?" in p.message
    assert p.row is not None


def test_small_joint_angles_in_degrees_found_from_velocity(tmp_path):
    """±0.5° read as rad stays within the limits; the velocity in rad/s gives it away."""
    trials = clean_trials()
    df = trials["trial_001"]
    w = 2 * np.pi * 2.5
    df["q_left_hip_abd"] = 0.5 * np.sin(w * df["time"])                  # degrees
    df["dq_left_hip_abd"] = np.deg2rad(0.5 * w * np.cos(w * df["time"]))   # rad/s
    only(problems_of(write(tmp_path, trials)), file="trial_001.csv", column="dq_left_hip_abd",
         text="a factor of 0.01745: angle in degrees?")


def test_joint_velocity_sign_flipped(tmp_path):
    trials = clean_trials()
    trials["trial_001"]["dq_right_knee"] *= -1
    only(problems_of(write(tmp_path, trials)), file="trial_001.csv", column="dq_right_knee",
         text="opposite sign of the time derivative of q_right_knee")


def test_joint_angle_outside_limits(tmp_path):
    trials = clean_trials()
    trials["trial_001"].loc[30:34, "q_left_knee"] = -1.0            # below 0.1 rad
    only(problems_of(write(tmp_path, trials)), file="trial_001.csv", column="q_left_knee", row=31,
         text="angle outside the joint limits [0.1, 2.6] rad (± 0.1 rad) of robot 'yobogo10s' in "
              "rows 31–35 (5 rows)")


def test_torque_in_newton_millimetres(tmp_path):
    trials = clean_trials()
    trials["trial_002"]["tau_right_hip_pitch"] *= 1000.0
    p = only(problems_of(write(tmp_path, trials)), file="trial_002.csv",
             column="tau_right_hip_pitch", row=1, text="N·mm?")
    assert "effort limit 18 N·m in rows 1–200 (200 rows)" in p.message


def test_millimetres_detected(tmp_path):
    trials = clean_trials()
    df = trials["trial_001"]
    df["intrusion_z"] *= 1000.0
    df["base_z"] *= 1000.0
    df["base_x"] *= 1000.0
    df["base_vx"] *= 1000.0
    probs = problems_of(write(tmp_path, trials))
    assert len(probs) == 4, "\n".join(map(str, probs))
    has(probs, file="trial_001.csv", column="intrusion_z", row=3,
        text="millimetres or centimetres instead of metres?")
    has(probs, file="trial_001.csv", column="base_z", row=1, text="millimetres instead of metres?")
    has(probs, file="trial_001.csv", column="base_x", row=2, text="millimetres instead of metres?")
    has(probs, file="trial_001.csv", column="base_vx", row=1, text="mm/s instead of m/s?")


def test_velocity_in_mm_per_s_found_from_position(tmp_path):
    trials = clean_trials()
    trials["trial_002"]["base_vz"] *= 100.0       # cm/s: below the speed bound, wrong scale
    only(problems_of(write(tmp_path, trials)), file="trial_002.csv", column="base_vz",
         text="a factor of 100: velocity in cm/s?")


def test_trunk_rate_in_degrees_per_second(tmp_path):
    trials = clean_trials()
    trials["trial_001"]["base_wz"] = np.rad2deg(trials["trial_001"]["base_wz"])
    only(problems_of(write(tmp_path, trials)), file="trial_001.csv", column="base_wz",
         text="velocity in degrees per second?")


def test_grf_sign_and_unit(tmp_path):
    trials = clean_trials()
    trials["trial_001"]["grf_z"] *= -1.0                          # foot on ground
    trials["trial_002"]["grf_z"] /= 9.81                          # kgf
    probs = problems_of(write(tmp_path, trials))
    assert len(probs) == 2
    has(probs, file="trial_001.csv", column="grf_z", text="force OF the ground ON the foot")
    has(probs, file="trial_002.csv", column="grf_z", text="in kgf instead of N?")


def test_intrusion_sign_flipped(tmp_path):
    trials = clean_trials()
    trials["trial_002"]["intrusion_z"] *= -1.0
    only(problems_of(write(tmp_path, trials)), file="trial_002.csv", column="intrusion_z",
         text="z positive DEEPER")


def test_walking_along_world_y(tmp_path):
    trials = clean_trials()
    df = trials["trial_002"]
    df["base_x"], df["base_y"] = df["base_y"].copy(), df["base_x"].copy()
    df["base_vx"], df["base_vy"] = df["base_vy"].copy(), df["base_vx"].copy()
    only(problems_of(write(tmp_path, trials)), file="trial_002.csv", column="base_x,base_y",
         text="world x must be the walking direction")


# ------------------------------------------------------------------------ all at once


def test_many_problems_in_many_files_reported_together(tmp_path):
    trials = clean_trials()
    trials["trial_001"].loc[4, "base_vy"] = np.nan
    trials["trial_001"]["q_left_knee"] = np.rad2deg(trials["trial_001"]["q_left_knee"])
    trials["trial_002"].loc[7, "stance"] = "flight"
    trials["trial_002"] = trials["trial_002"].drop(columns=["intrusion_y"])
    meta = make_meta(trials={"trial_001": {"file": "trial_001.csv", "commanded_speed_mps": 0.2},
                             "trial_002": {"file": "trial_002.csv", "commanded_speed_mps": 0.3},
                             "trial_003": {"file": "trial_003.csv", "commanded_speed_mps": 0.4}})
    folder = write_dataset(tmp_path / "ds", meta, {**trials, "trial_003": make_trial()},
                           check=False)
    (folder / "trial_003.csv").unlink()
    (folder / "notes.csv").write_text("a,b\n1,2\n")
    probs = problems_of(folder)
    assert [str(p) for p in check_dataset(folder)] == [str(p) for p in probs]
    assert len(probs) == 6, "\n".join(map(str, probs))
    has(probs, file="notes.csv", text="not listed")
    has(probs, file="trial_001.csv", column="base_vy", row=5, text="empty or NaN")
    has(probs, file="trial_001.csv", column="q_left_knee", row=1, text="degrees?")
    has(probs, file="trial_002.csv", column="stance", row=8, text="'flight'")
    has(probs, file="trial_002.csv", column="intrusion_y", text="required column is missing")
    has(probs, file="trial_003.csv", text="not found")
    text = str(DataFormatError(probs, root=str(folder)))
    assert text.startswith(f"6 problem(s) in data set {folder}")


# ------------------------------------------------------------------------ writer


def test_writer_refuses_bad_data_and_writes_nothing(tmp_path):
    trials = clean_trials()
    trials["trial_002"].loc[3, "time"] = np.nan
    with pytest.raises(DataFormatError) as info:
        write_dataset(tmp_path / "ds", make_meta(), trials)
    only(info.value.problems, file="trial_002.csv", column="time", row=4, text="empty or NaN")
    assert not (tmp_path / "ds").exists()


def test_writer_checks_trial_names_format_and_overwrite(tmp_path):
    with pytest.raises(DataFormatError) as info:
        write_dataset(tmp_path / "a", make_meta(), {"trial_001": make_trial()})
    only(info.value.problems, file="trial_002.csv", text="has no data")
    with pytest.raises(ConfigError) as cfg:
        write_dataset(tmp_path / "b", make_meta(), clean_trials(), "xlsx")
    assert cfg.value.key == "format"
    with pytest.raises(ConfigError):
        write_dataset(tmp_path / "c", make_meta(sample_rate_hz=-1), clean_trials())
    folder = write_dataset(tmp_path / "d", make_meta(), clean_trials())
    with pytest.raises(OutputError):
        write_dataset(folder, make_meta(), clean_trials())
    write_dataset(folder, make_meta(terrain="wet sand"), clean_trials(), overwrite=True)
    assert load_dataset(folder).meta.terrain == "wet sand"


def test_check_trials_in_memory_requires_numeric_dtypes():
    trials = clean_trials()
    trials["trial_001"]["base_z"] = trials["trial_001"]["base_z"].astype(str)
    assert check_trials(make_meta(), clean_trials()) == []
    only(check_trials(make_meta(), trials), file="trial_001.csv", column="base_z", row=1,
         text="wants a floating-point column")
