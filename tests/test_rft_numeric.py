"""The package's slow brute-force RFT (granular_mpc.terrain.rft_numeric) against cases
solvable by hand, and its convergence to the closed form. (Agreement with the independent
brute force written in tests/test_closed_form.py is checked there.)"""
from __future__ import annotations

import math

import numpy as np
import pytest

from granular_mpc.terrain.closed_form import FLOAT, FootShape, sagittal_forces
from granular_mpc.terrain.rft_numeric import (effective_contour, sagittal_forces_numeric,
                                              side_moment_numeric)

PHI = math.radians(38.0)
ZETA = 1.36


@pytest.fixture(scope="module")
def shape(robot_config):
    return FootShape.from_geometry(robot_config.foot)


def test_pure_penetration_of_a_level_foot_by_hand(shape):
    """Level foot pushed straight down, surface across the wedge faces: only the faces at
    |β| = φ are submerged, F_z = 2ζ α_z(φ, 90°) W d_A² / (2 sin φ) with the apex depth
    d_A = d + R(1/cos φ − 1), F_h = 0 by symmetry. The faces are sampled with n/4
    straight elements, so the face integral is exact but for the element cut by the
    surface: measured error 3.4e-5 at n = 400 (d = 1 mm), 1e-6 at n = 1600; bound 1e-4."""
    R, W = shape.radius, shape.width
    az = 0.564 + 0.436 * math.cos(2 * PHI)          # Li's generic α_z at γ = 90°
    for d in (0.001, 0.004, 0.008):
        d_apex = d + R * (1.0 / math.cos(PHI) - 1.0)
        expected = 2 * ZETA * 1e6 * az * W * d_apex ** 2 / (2 * math.sin(PHI))
        num = sagittal_forces_numeric(shape, PHI, d, 0.0, 0.0, -1.0, zeta=ZETA, n=400)
        assert num["f_z"] == pytest.approx(expected, rel=1e-4)
        assert abs(num["f_h"]) < 1e-12 * expected


def test_effective_contour_is_closed_and_reaches_the_apex(shape):
    R = shape.radius
    depth = 0.01
    pts, bottom = effective_contour(shape, PHI, depth, 0.0, n=800)
    np.testing.assert_allclose(pts[0], pts[-1], atol=1e-15)          # closed
    # the lowest point is the wedge apex, R(1/cos φ − 1) below the arc's lowest point
    assert pts[:, 1].min() == pytest.approx(-(depth + R * (1.0 / math.cos(PHI) - 1.0)), abs=1e-12)
    # bottom = arcs + faces (4 pieces of n/4 points, shared ends), top = the chord
    assert bottom.size == len(pts) - 1 and bottom[:bottom.sum()].all() and not bottom[bottom.sum():].any()
    # the apex is where the two faces meet at ±φ to the horizontal
    k = int(np.argmin(pts[:, 1]))
    for nb in (pts[k - 1], pts[k + 1]):
        slope = abs((nb[1] - pts[k, 1]) / (nb[0] - pts[k, 0]))
        assert slope == pytest.approx(math.tan(PHI), rel=1e-9)


def test_side_moment_of_a_triangle_by_hand():
    """Right triangle with its a-long leg on the surface and its d-deep leg vertical:
    ∬ depth dA = a d²/6. Midpoint grid of n cells a side: O(1/n) boundary error;
    measured 2.5e-3 at n = 100, bound 1e-2 (and 8e-5 at n = 1000, bound 1e-3)."""
    a, d = 0.05, 0.02
    tri = np.array([[0.0, 0.0], [a, 0.0], [0.0, -d], [0.0, 0.0]])
    exact = a * d * d / 6.0
    assert side_moment_numeric(tri, 100) == pytest.approx(exact, rel=1e-2)
    assert side_moment_numeric(tri, 1000) == pytest.approx(exact, rel=1e-3)
    # entirely above the surface: nothing submerged
    assert side_moment_numeric(tri + [0.0, d + 0.001], 100) == 0.0


def test_converges_to_the_closed_form(shape):
    """Oblique motion, pitched foot: the error to the closed form falls with n (measured
    f_z: 5.0e-6 at n = 400, 2.6e-7 at n = 1600, relative to |F|; bound 2e-5 at n = 400
    and at least the 4× of a first-order method per 4× n; S₁ measured 4.7e-6 / 2.1e-7,
    bound 5e-5)."""
    cf = sagittal_forces(FLOAT, shape, PHI, 0.015, 0.1, 0.6, -0.8, zeta=ZETA)
    mag = math.hypot(cf.f_h, cf.f_z)
    errs = []
    for n in (400, 1600):
        num = sagittal_forces_numeric(shape, PHI, 0.015, 0.1, 0.6, -0.8, zeta=ZETA, n=n)
        errs.append(max(abs(num["f_h"] - cf.f_h), abs(num["f_z"] - cf.f_z)) / mag)
        assert num["shear_moment"] == pytest.approx(cf.shear_moment, rel=5e-5)
    assert errs[0] < 2e-5 and errs[1] < errs[0] / 4
