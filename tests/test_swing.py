"""Cycloid swing trajectory: endpoints at rest, apex, derivatives."""

import numpy as np
import pytest

from granular_mpc.control.swing import cycloid, cycloid_components


def test_endpoints_are_reached_at_rest():
    p0, p1 = np.array([0.0, 0.1, 0.04]), np.array([0.12, 0.08, 0.04])
    for s, target in ((0.0, p0), (1.0, p1)):
        pos, vel, acc = cycloid(p0.copy(), p1.copy(), 0.1, s, 0.2)
        np.testing.assert_allclose(pos, target, atol=1e-12)
        np.testing.assert_allclose(vel, 0.0, atol=1e-12)
    _, _, acc_end = cycloid(p0.copy(), p1.copy(), 0.1, 1.0, 0.2)
    np.testing.assert_allclose(acc_end[:2], 0.0, atol=1e-9)   # lands without horizontal jerk


def test_apex_height_at_mid_swing():
    p0 = np.zeros(3)
    p1 = np.array([0.1, 0.0, 0.0])
    pos, _, _ = cycloid(p0, p1.copy(), 0.1, 0.5, 0.2)
    assert pos[2] == pytest.approx(0.1)
    zs = [cycloid(p0, p1.copy(), 0.1, s, 0.2)[0][2] for s in np.linspace(0, 1, 101)]
    assert max(zs) == pytest.approx(0.1, abs=1e-4)


def test_velocity_and_acceleration_are_the_time_derivatives():
    p0, p1, T = np.array([0.0, 0.1, 0.0]), np.array([0.15, 0.05, -0.01]), 0.16
    h = 1e-6
    for s in (0.1, 0.37, 0.5, 0.83):
        pos, vel, acc = cycloid(p0.copy(), p1.copy(), 0.1, s, T)
        pp = cycloid(p0.copy(), p1.copy(), 0.1, s + h / T, T)
        pm = cycloid(p0.copy(), p1.copy(), 0.1, s - h / T, T)
        np.testing.assert_allclose(vel, (pp[0] - pm[0]) / (2 * h), rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(acc, (pp[1] - pm[1]) / (2 * h), rtol=1e-5, atol=1e-5)


def test_cycloid_components_are_the_cycloids_numbers():
    """The float form the controller's tick uses gives :func:`cycloid`'s numbers, and both
    equal the module's formulas evaluated independently."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        p0, p1 = rng.normal(0.0, 0.1, 3), rng.normal(0.0, 0.1, 3)
        h, s, T = rng.uniform(0.01, 0.1), rng.uniform(-0.1, 1.1), rng.uniform(0.1, 0.5)
        pos, vel, acc = cycloid_components(tuple(p0.tolist()), tuple(p1.tolist()), h, s, T)
        arrays = cycloid(p0, p1, h, s, T)
        for got, arr in zip((pos, vel, acc), arrays):
            assert list(got) == arr.tolist()
        sc = min(max(s, 0.0), 1.0)
        phi, w = 2 * np.pi * sc, 2 * np.pi / T
        c = (phi - np.sin(phi)) / (2 * np.pi)
        up = np.array([0.0, 0.0, 1.0])
        np.testing.assert_allclose(pos, p0 + (p1 - p0) * c + up * h * (1 - np.cos(phi)) / 2,
                                   rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(vel, (p1 - p0) * (1 - np.cos(phi)) / (2 * np.pi) * w
                                   + up * h * np.sin(phi) / 2 * w, rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(acc, (p1 - p0) * np.sin(phi) / (2 * np.pi) * w * w
                                   + up * h * np.cos(phi) / 2 * w * w, rtol=1e-12, atol=1e-11)
