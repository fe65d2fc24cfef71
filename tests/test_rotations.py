"""granular_mpc.rotations against independent references (SciPy's Rotation, Pinocchio)."""

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

from granular_mpc import rotations as rot


@pytest.fixture
def unit_quats_xyzw():
    rng = np.random.default_rng(7)
    q = rng.normal(size=(200, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_component_order_round_trip(unit_quats_xyzw):
    wxyz = rot.wxyz_from_xyzw(unit_quats_xyzw)
    assert np.array_equal(wxyz[:, 0], unit_quats_xyzw[:, 3])
    assert np.array_equal(rot.xyzw_from_wxyz(wxyz), unit_quats_xyzw)


def test_matrix_matches_scipy_and_is_bit_identical_to_pinocchio(unit_quats_xyzw):
    for q in unit_quats_xyzw:
        R = rot.matrix_from_quat_xyzw(q)
        assert np.allclose(R, Rotation.from_quat(q).as_matrix(), atol=1e-14)
        # The controller's arithmetic must not change when it moved off pin.Quaternion.
        assert np.array_equal(R, pin.Quaternion(q[3], q[0], q[1], q[2]).matrix())
        assert np.array_equal(rot.matrix_from_quat_wxyz(rot.wxyz_from_xyzw(q)), R)


def test_normalised_matrix_is_orthonormal():
    R = rot.normalized_matrix_from_quat_xyzw([0.1, -0.2, 0.3, 2.0])
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)


def test_rpy_matches_scipy_zyx(unit_quats_xyzw):
    ref = Rotation.from_quat(unit_quats_xyzw).as_euler("ZYX")[:, ::-1]   # roll, pitch, yaw
    rows = rot.rpy_rows_from_quat_wxyz(rot.wxyz_from_xyzw(unit_quats_xyzw))
    assert np.allclose(rows, ref, atol=1e-9)
    for q, r in zip(unit_quats_xyzw, ref):
        assert np.allclose(rot.rpy_from_quat_xyzw(q), r, atol=1e-9)
        assert np.allclose(rot.roll_pitch_from_quat_xyzw(q), r[:2], atol=1e-9)


def test_elementary_rotations_compose_to_the_zyx_convention():
    roll, pitch, yaw = 0.3, -0.4, 1.2
    R = rot.rot_z(yaw) @ rot.rot_y(pitch) @ rot.rot_x(roll)
    q = Rotation.from_matrix(R).as_quat()
    assert np.allclose(rot.rpy_from_quat_xyzw(q), (roll, pitch, yaw), atol=1e-12)


def test_quaternion_product_matches_matrix_product(unit_quats_xyzw):
    a = rot.wxyz_from_xyzw(unit_quats_xyzw[:100])
    b = rot.wxyz_from_xyzw(unit_quats_xyzw[100:])
    ab = rot.quat_mul_rows_wxyz(a, b)
    for qa, qb, qab in zip(a, b, ab):
        assert np.allclose(rot.matrix_from_quat_wxyz(qab),
                           rot.matrix_from_quat_wxyz(qa) @ rot.matrix_from_quat_wxyz(qb), atol=1e-13)


def test_rotvec_quaternion_matches_scipy():
    rng = np.random.default_rng(3)
    rv = rng.normal(scale=0.7, size=(50, 3))
    rv[0] = 0.0
    q = rot.quat_rows_wxyz_from_rotvec(rv)
    ref = Rotation.from_rotvec(rv).as_quat()            # x, y, z, w
    assert np.allclose(q, rot.wxyz_from_xyzw(ref), atol=1e-14)


def test_skew_is_the_cross_product():
    r, v = np.array([0.3, -1.0, 2.0]), np.array([-0.5, 0.25, 4.0])
    assert np.allclose(rot.skew(r) @ v, np.cross(r, v))


def test_scalar_functions_give_the_same_numbers_for_arrays_and_sequences(unit_quats_xyzw):
    """The float64-array fast path (one ``tolist``) equals the per-component path."""
    for q in unit_quats_xyzw[:50]:
        as_tuple = tuple(float(c) for c in q)
        assert np.array_equal(rot.matrix_from_quat_xyzw(q), rot.matrix_from_quat_xyzw(as_tuple))
        assert rot.roll_pitch_from_quat_xyzw(q) == rot.roll_pitch_from_quat_xyzw(as_tuple)
        assert rot.rpy_from_quat_xyzw(q) == rot.rpy_from_quat_xyzw(list(as_tuple))
        # a float32 array takes the per-component path: its values, as Python floats
        q32 = q.astype(np.float32)
        assert np.array_equal(rot.matrix_from_quat_xyzw(q32),
                              rot.matrix_from_quat_xyzw(q32.astype(float)))
