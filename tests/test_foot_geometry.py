"""The row-wise foot geometry (``foot_pitch_rows``, ``contact_point_rows``) equals the
per-placement functions it vectorises, on random placements — including pitches beyond the
sole's half angle, where the lowest point sits on the toe or heel edge."""

import numpy as np
import pinocchio as pin
import pytest

from granular_mpc.validation.foot_geometry import (contact_point_rows, foot_pitch,
                                                   foot_pitch_rows, patch_points)


def _placements(n: int, seed: int) -> list[pin.SE3]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        rpy = rng.uniform([-0.4, -1.2, -np.pi], [0.4, 1.2, np.pi])   # pitch up to ±69°
        out.append(pin.SE3(pin.rpy.rpyToMatrix(*rpy), rng.normal(0.0, 0.3, 3)))
    return out


def test_rows_equal_the_per_placement_functions(biped):
    oMfs = _placements(200, seed=5)
    pos = np.array([m.translation for m in oMfs])
    rot = np.array([m.rotation for m in oMfs])
    half = biped.config.foot.half_angle
    pitches = np.array([foot_pitch(m) for m in oMfs])
    assert (np.abs(pitches) > half).any() and (np.abs(pitches) < half).any()  # both regimes
    np.testing.assert_allclose(foot_pitch_rows(rot), pitches, rtol=0, atol=1e-15)
    mean_pts = np.array([patch_points(biped, m).mean(axis=0) for m in oMfs])
    np.testing.assert_allclose(contact_point_rows(biped, pos, rot), mean_pts, rtol=0, atol=1e-12)


def test_contact_point_lies_on_the_sole_arc(biped):
    """Independent of patch_points: with the foot level the contact point is R below the
    foot frame (mean slice offset across); pitched by less than the half angle it stays
    at distance R from the arc's centre line, at the lowest height."""
    foot = biped.config.foot
    y_mean = float(np.mean(biped.slice_offsets))
    level = contact_point_rows(biped, np.zeros((1, 3)), np.eye(3)[None])[0]
    np.testing.assert_allclose(level, [0.0, y_mean, -foot.radius], atol=1e-15)
    theta = 0.5 * foot.half_angle
    R = pin.rpy.rpyToMatrix(0.0, theta, 0.0)
    c = contact_point_rows(biped, np.zeros((1, 3)), R[None])[0]
    assert c[2] == pytest.approx(-foot.radius, abs=1e-12)               # lowest arc point
    assert np.hypot(c[0], c[2]) == pytest.approx(foot.radius, abs=1e-12)
