"""granular_mpc.columns: the one vocabulary of data-format and run-folder names."""

import re

import pytest

from granular_mpc import columns as col

JOINTS = ("left_hip_abd", "left_hip", "left_knee")


def test_joint_columns_keep_actuator_order_and_reject_unknown_kinds():
    assert col.joint_columns(JOINTS, "dq") == ["dq_left_hip_abd", "dq_left_hip", "dq_left_knee"]
    with pytest.raises(ValueError, match="'q', 'dq' or 'tau'"):
        col.joint_columns(JOINTS, "ddq")  # type: ignore[arg-type]


def test_format_columns_are_unique_and_hold_every_required_group():
    cols = col.format_columns(JOINTS)
    assert len(cols) == len(set(cols))
    assert cols[:2] == [col.TIME, col.STANCE]
    n_joint = 3 * len(JOINTS)
    assert len(cols) == 2 + n_joint + 13 + 3 + 3
    for group in (col.BASE_COLUMNS, col.GRF_COLUMNS, col.INTRUSION_COLUMNS):
        assert set(group) <= set(cols)
    assert col.BASE_QUATERNION[0] == "base_qw"          # (w, x, y, z): data format v1


def test_log_part_names_sort_in_write_order():
    names = [col.log_part_name(i) for i in (0, 9, 10, 123)]
    assert names == sorted(names)
    assert all(re.fullmatch(r"part-\d{5}\.parquet", n) for n in names)


def test_foot_columns_are_side_prefixed():
    assert [col.foot_column(s, "grf_z") for s in col.FOOT_SIDES] == ["left_grf_z", "right_grf_z"]
