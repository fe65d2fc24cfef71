"""Run logs (granular_mpc/runlog.py): the recorder's rows against the plant's own state and
independent Pinocchio computations; the chunked writer's parts, their round trip through
``read_log`` and its reading after an interruption; write and read errors naming the path.

Tolerances: the recorder copies or rotates plant quantities, so copies are compared
exactly and rotated ones to 1e-12 (a few ulps of a 3×3 product); the centre of mass is
recomputed as the mass-weighted sum of the bodies' centres (1e-12 m) and its velocity by a
central difference along v with step ε = 1e-6 s (truncation O(ε²) ≈ 1e-12, round-off
≈ 1e-16 / ε = 1e-10 m/s; bound 1e-8 m/s).
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import pinocchio as pin
import pytest

from granular_mpc.columns import (BASE_ANGULAR_VELOCITY, BASE_COLUMNS, BASE_LINEAR_VELOCITY,
                                  BASE_POSITION, BASE_QUATERNION, COM_POSITION, COM_VELOCITY,
                                  FOOT_SIDES,
                                  GRF_COLUMNS, INTRUSION_COLUMNS, LOG_DIR, STANCE, TIME,
                                  foot_column, format_columns, joint_columns, log_part_name)
from granular_mpc.config import SimConfig
from granular_mpc.dynamics import FastPlant, Plant
from granular_mpc.exceptions import OutputError
from granular_mpc.rotations import matrix_from_quat_wxyz
from granular_mpc.runlog import LOG_PART_GLOB, PlantRecorder, RunLog, read_log

ROT_TOL = 1e-12
VCOM_TOL = 1e-8
FD_EPS = 1e-6


# --------------------------------------------------------------------------------------
# plant states
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sand_plant(biped, sand):
    return Plant(biped, sand, SimConfig())


@pytest.fixture(scope="module", params=["reference", "compiled"])
def any_sand_plant(request, sand_plant):
    """The reference plant and the compiled one (FastPlant): the recorder reads both."""
    return sand_plant if request.param == "reference" else FastPlant(sand_plant)


def _joint_q_index(biped, name):
    return biped.model.idx_qs[biped.model.getJointId(name)]


def _joint_v_index(biped, name):
    return biped.model.idx_vs[biped.model.getJointId(name)]


def _moving_state(plant, biped, *, lift_right: bool, steps: int = 5):
    """Plant data a few steps after a start in the sand with a moving, tilted trunk;
    ``lift_right`` bends the right leg so that only the left foot touches."""
    q = biped.standing_configuration(clearance=-0.005)
    if lift_right:
        q[_joint_q_index(biped, "right_knee")] += 0.5
        q[_joint_q_index(biped, "right_hip_pitch")] -= 0.25
    rot = pin.Quaternion(pin.rpy.rpyToMatrix(0.03, -0.05, 0.2))
    q[3:7] = rot.coeffs()                                     # x, y, z, w
    v = np.zeros(biped.model.nv)
    v[0:6] = [0.05, -0.01, -0.02, 0.1, -0.2, 0.05]
    v[6:] = np.linspace(-0.3, 0.3, biped.model.nv - 6)
    d = plant.new_data(q, v)
    tau = np.linspace(0.5, -0.4, len(biped.joint_names))
    for _ in range(steps):
        plant.step(d, tau)
    return d


def _com_reference(biped, q):
    """Mass-weighted sum of the bodies' centres of mass in W (no pin.centerOfMass)."""
    model, data = biped.model, biped.create_data()
    pin.forwardKinematics(model, data, q)
    m = np.array([model.inertias[i].mass for i in range(1, model.njoints)])
    c = np.array([data.oMi[i].act(model.inertias[i].lever) for i in range(1, model.njoints)])
    return m @ c / m.sum()


# --------------------------------------------------------------------------------------
# PlantRecorder
# --------------------------------------------------------------------------------------


def test_recorder_row_matches_the_plant_state(biped, any_sand_plant):
    d = _moving_state(any_sand_plant, biped, lift_right=True)
    row = PlantRecorder(biped).row(d)
    q, v = d.q, d.v
    assert row[TIME] == d.t and d.t == pytest.approx(5 * any_sand_plant.dt)
    # the columns in the documented order, Python floats (ints for contact), then extra
    jcols = [c for cols in zip(*(joint_columns(biped.joint_names, k) for k in ("q", "dq", "tau")))
             for c in cols]
    feet = [foot_column(side, c) for side in FOOT_SIDES
            for c in ([n for ax in "xyz" for n in (f"grf_{ax}", f"intrusion_{ax}", f"p{ax}")]
                      + ["contact", "depth", "pitch", "cap_z"])]
    stance_copies = [c for pair in zip(GRF_COLUMNS, INTRUSION_COLUMNS) for c in pair]
    assert list(row) == ([TIME] + jcols + list(BASE_COLUMNS) + feet + [STANCE] + stance_copies
                         + list(COM_POSITION) + list(COM_VELOCITY))
    for c, value in row.items():
        want = str if c == STANCE else int if c.endswith("_contact") else float
        assert type(value) is want, c
    # joints, by name through Pinocchio's own joint indices
    for name, cq, cdq, ctau in zip(biped.joint_names, joint_columns(biped.joint_names, "q"),
                                   joint_columns(biped.joint_names, "dq"),
                                   joint_columns(biped.joint_names, "tau")):
        iq, iv = _joint_q_index(biped, name), _joint_v_index(biped, name)
        assert (row[cq], row[cdq], row[ctau]) == (q[iq], v[iv], d.tau[iv])
    # trunk pose and twist: Pinocchio's placement and velocity of the root joint
    data = biped.create_data()
    pin.forwardKinematics(biped.model, data, q, v)
    assert [row[c] for c in BASE_POSITION] == list(q[0:3])
    quat_wxyz = np.array([row[c] for c in BASE_QUATERNION])
    np.testing.assert_allclose(matrix_from_quat_wxyz(quat_wxyz), data.oMi[1].rotation,
                               atol=ROT_TOL)
    v_world = pin.getVelocity(biped.model, data, 1, pin.LOCAL_WORLD_ALIGNED).linear
    np.testing.assert_allclose([row[c] for c in BASE_LINEAR_VELOCITY], v_world, atol=ROT_TOL)
    w_body = pin.getVelocity(biped.model, data, 1, pin.LOCAL).angular
    np.testing.assert_allclose([row[c] for c in BASE_ANGULAR_VELOCITY], w_body, atol=ROT_TOL)
    # per foot: the plant's contact read-outs; intrusion and depth zero off the ground
    assert [d.foot_in_contact(i) for i in (0, 1)] == [True, False]
    for i, side in enumerate(FOOT_SIDES):
        diag, contact = d.foot_diag(i), d.foot_in_contact(i)
        assert row[foot_column(side, "contact")] == int(contact)
        for k, ax in enumerate("xyz"):
            assert row[foot_column(side, f"grf_{ax}")] == d.foot_force(i)[k]
            assert row[foot_column(side, f"p{ax}")] == d.foot_point(i)[k]
            assert row[foot_column(side, f"intrusion_{ax}")] == (diag[2 + k] if contact else 0.0)
        assert row[foot_column(side, "depth")] == (diag[0] if contact else 0.0)
        assert row[foot_column(side, "pitch")] == diag[5]
        assert row[foot_column(side, "cap_z")] == diag[1]
    assert row[foot_column("right", "grf_z")] == 0.0            # off the ground: no force
    # only the left foot touches: it is the stance foot, its force the v1 grf
    assert row[STANCE] == "left"
    for c_grf, c_intr in zip(GRF_COLUMNS, INTRUSION_COLUMNS):
        assert row[c_grf] == row[foot_column("left", c_grf)]
        assert row[c_intr] == row[foot_column("left", c_intr)]
    # centre of mass and its velocity, recomputed without pin.centerOfMass
    np.testing.assert_allclose([row[c] for c in COM_POSITION], _com_reference(biped, q),
                               atol=1e-12)
    vcom = (_com_reference(biped, pin.integrate(biped.model, q, FD_EPS * v))
            - _com_reference(biped, pin.integrate(biped.model, q, -FD_EPS * v))) / (2 * FD_EPS)
    np.testing.assert_allclose([row[c] for c in COM_VELOCITY], vcom, atol=VCOM_TOL)
    # a run log is a data set of format v1: every required column is there
    assert set(format_columns(biped.joint_names)) <= set(row)


def test_recorder_stance_is_the_foot_carrying_more_and_can_be_given(biped, any_sand_plant):
    d = _moving_state(any_sand_plant, biped, lift_right=False, steps=20)
    assert d.foot_in_contact(0) and d.foot_in_contact(1)
    rec = PlantRecorder(biped)
    row = rec.row(d)
    heavier = "left" if d.foot_force(0)[2] > d.foot_force(1)[2] else "right"
    assert row[STANCE] == heavier
    for c in GRF_COLUMNS + INTRUSION_COLUMNS:
        assert row[c] == row[foot_column(heavier, c)]
    other = "right" if heavier == "left" else "left"
    given = rec.row(d, stance=other, extra={"cmd_vx": 0.2, "mpc_status": "solved"})
    assert given[STANCE] == other
    assert given["grf_z"] == given[foot_column(other, "grf_z")] != row["grf_z"]
    assert given["cmd_vx"] == 0.2 and given["mpc_status"] == "solved"
    none = rec.row(d, stance="none")
    assert all(none[c] == 0.0 for c in GRF_COLUMNS + INTRUSION_COLUMNS)
    with pytest.raises(ValueError, match="stance"):
        rec.row(d, stance="both")


def test_recorder_row_in_the_air_has_stance_none(biped, rigid):
    plant = Plant(biped, rigid, SimConfig())
    d = plant.new_data(biped.standing_configuration(clearance=0.05))
    plant.step(d, np.zeros(len(biped.joint_names)))
    row = PlantRecorder(biped).row(d)
    assert row[STANCE] == "none"
    for side in FOOT_SIDES:
        assert row[foot_column(side, "contact")] == 0 and row[foot_column(side, "depth")] == 0.0
    assert all(row[c] == 0.0 for c in GRF_COLUMNS + INTRUSION_COLUMNS)


# --------------------------------------------------------------------------------------
# RunLog and read_log
# --------------------------------------------------------------------------------------


def _rows(n, start=0):
    return [{TIME: 0.002 * k, "x": float(k) ** 0.5, STANCE: ("left", "right", "none")[k % 3],
             "n": k} for k in range(start, start + n)]


def test_runlog_writes_parts_of_flush_every_rows_and_reads_them_back(tmp_path):
    rows = _rows(7)
    folder = tmp_path / "run" / LOG_DIR
    with RunLog(folder, flush_every=3) as rl:
        for r in rows[:6]:
            rl.append(r)
        # two full chunks on disk, nothing pending yet
        assert sorted(p.name for p in folder.glob(LOG_PART_GLOB)) == [log_part_name(0),
                                                                       log_part_name(1)]
        rl.append(rows[6])
        assert rl.n_rows == 7
    parts = sorted(folder.glob(LOG_PART_GLOB))
    assert [p.name for p in parts] == [log_part_name(i) for i in range(3)]
    assert [len(pd.read_parquet(p)) for p in parts] == [3, 3, 1]
    assert not list(folder.glob("*.tmp")) and not list(folder.glob(".*"))
    want = pd.DataFrame.from_records(rows)
    pd.testing.assert_frame_equal(read_log(folder), want)
    pd.testing.assert_frame_equal(read_log(tmp_path / "run"), want)   # the run folder


def test_recorder_rows_round_trip_through_the_log(biped, sand_plant, tmp_path):
    d = _moving_state(sand_plant, biped, lift_right=False, steps=1)
    rec = PlantRecorder(biped)
    rows = []
    with RunLog(tmp_path / LOG_DIR, flush_every=4) as rl:
        for k in range(10):
            sand_plant.step(d, np.zeros(len(biped.joint_names)))
            rows.append(rec.row(d, extra={"cmd_vx": 0.1 * k}))
            rl.append(rows[-1])
    got = read_log(tmp_path)
    pd.testing.assert_frame_equal(got, pd.DataFrame.from_records(rows))
    assert got[TIME].is_monotonic_increasing


def test_log_is_readable_after_an_interruption(tmp_path):
    rl = RunLog(tmp_path / LOG_DIR, flush_every=4)
    for r in _rows(6):
        rl.append(r)
    # the process dies here: the 2 unflushed rows are lost, the full part is readable
    got = read_log(tmp_path)
    pd.testing.assert_frame_equal(got, pd.DataFrame.from_records(_rows(4)))


def test_unwritable_log_folder_is_an_output_error_naming_it(tmp_path):
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("a file where the run folder should go")
    target = blocker / "run" / LOG_DIR
    with pytest.raises(OutputError, match="cannot write the log folder") as err:
        RunLog(target)
    assert str(target) in str(err.value)
    assert isinstance(err.value, OSError)                    # callers catching OSError


def test_a_part_that_cannot_be_written_is_an_output_error_naming_it(tmp_path):
    folder = tmp_path / LOG_DIR
    rl = RunLog(folder, flush_every=100)
    rl.append(_rows(1)[0])
    folder.rmdir()                                           # the folder vanishes …
    folder.write_text("")                                    # … and a file takes its place
    with pytest.raises(OutputError) as err:
        rl.flush()
    assert str(folder / log_part_name(0)) in str(err.value)


def test_empty_log_folder_is_an_output_error_naming_it(tmp_path):
    (tmp_path / LOG_DIR).mkdir()
    with pytest.raises(OutputError, match="no log parts") as err:
        read_log(tmp_path)
    assert str(tmp_path / LOG_DIR) in str(err.value)


def _three_parts(folder, corrupt: int):
    with RunLog(folder, flush_every=2) as rl:
        for r in _rows(6):
            rl.append(r)
    (folder / log_part_name(corrupt)).write_bytes(b"PAR1 this is not a parquet file PAR1")


def test_a_corrupt_part_in_the_middle_is_skipped_with_a_warning_naming_it(tmp_path):
    """A hole in the log: the other parts are returned, the warning names the part and
    the missing stretch of simulated time (rows 2–3 of 0.002 s spacing: 0.002 → 0.008 s)."""
    _three_parts(tmp_path / LOG_DIR, corrupt=1)
    with pytest.warns(UserWarning, match=log_part_name(1)) as caught:
        got = read_log(tmp_path)
    assert "t = 0.002 s to 0.008 s is missing" in str(caught[0].message)
    want = pd.DataFrame.from_records(_rows(2) + _rows(2, start=4))
    pd.testing.assert_frame_equal(got, want)


def test_an_unreadable_last_part_is_skipped_quietly(tmp_path, recwarn):
    """The part being written when the process died: expected, no warning."""
    _three_parts(tmp_path / LOG_DIR, corrupt=2)
    got = read_log(tmp_path)
    pd.testing.assert_frame_equal(got, pd.DataFrame.from_records(_rows(4)))
    assert not [w for w in recwarn if "log part" in str(w.message)]


def test_a_log_with_only_corrupt_parts_is_an_output_error_naming_the_folder(tmp_path):
    folder = tmp_path / LOG_DIR
    folder.mkdir()
    (folder / log_part_name(0)).write_bytes(b"garbage")
    with pytest.raises(OutputError, match="no readable log part") as err:
        read_log(tmp_path)
    assert str(folder) in str(err.value)
