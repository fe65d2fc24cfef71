"""Li, Zhang & Goldman (Science 2013) RFT stresses: granular_mpc.terrain.rft.

Reference values are computed by hand from the published Fourier coefficients (generic
set, N/cm³) and the folding rules of the paper's supplement; see
``../shared/reference/physics-notes.md`` §2 and ``docs/model.md`` §2.1.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from granular_mpc.config import RFTCoefficients
from granular_mpc.terrain.rft import GENERIC, Coefficients, alpha, alpha_raw

DEG = math.pi / 180.0

# (β [deg], γ [deg]) → (α_x, α_z), generic units, from the worked table of physics-notes §2
WORKED = [
    ((0.0, 90.0), (0.0, 1.000)),        # horizontal plate, straight down: the normalisation
    ((0.0, -90.0), (0.0, -0.250)),      # horizontal plate pulled straight up (extraction)
    ((90.0, 0.0), (0.370, 0.037)),      # vertical plate pushed horizontally
    ((38.0, 90.0), (0.2125, 0.6695)),
    ((-38.0, 90.0), (-0.2125, 0.6695)),
    ((38.0, 0.0), (0.310, 0.399)),
    ((-38.0, 0.0), (0.139, 0.0945)),
    ((0.0, 0.0), (0.136, 0.375)),       # horizontal plate dragged horizontally
]


@pytest.mark.parametrize("angles,expected", WORKED, ids=[f"b{b:g}_g{g:g}" for (b, g), _ in WORKED])
def test_worked_values(angles, expected):
    beta, gamma = angles
    ax, az = alpha(beta * DEG, gamma * DEG)
    # the table is rounded to 3-4 significant digits
    assert ax == pytest.approx(expected[0], abs=6e-4)
    assert az == pytest.approx(expected[1], abs=6e-4)


def test_vertical_intrusion_closed_forms():
    """Along γ = 90°: α_z = (A00+B01) + (A10+B11+B₋₁₁) cos2β = 0.564 + 0.436 cos 2β and
    α_x = (D10 − C11 + C₋₁₁) sin 2β = 0.219 sin 2β (the cos(γ) terms vanish)."""
    for beta in np.linspace(-math.pi / 2, math.pi / 2, 37):
        ax, az = alpha(beta, math.pi / 2)
        assert az == pytest.approx(0.564 + 0.436 * math.cos(2 * beta), abs=1e-12)
        assert ax == pytest.approx(0.219 * math.sin(2 * beta), abs=1e-12)


def test_mirror_symmetry_everywhere():
    """Mirroring x → −x maps (β, γ) to (−β, π − γ): α_z is unchanged, α_x flips sign.
    Checked for angles in every quadrant (both sides use the folding)."""
    rng = np.random.default_rng(1)
    for beta, gamma in rng.uniform(-2 * math.pi, 2 * math.pi, size=(500, 2)):
        ax, az = alpha(beta, gamma)
        mx, mz = alpha(-beta, math.pi - gamma)
        assert az == pytest.approx(mz, abs=1e-12)
        assert ax == pytest.approx(-mx, abs=1e-12)


def test_folding_beta_plus_minus_pi_invariant():
    """A plate's tangent line is the same after a half turn: α(β ± π, γ) = α(β, γ)."""
    rng = np.random.default_rng(2)
    for beta, gamma in rng.uniform(-math.pi, math.pi, size=(300, 2)):
        ref = alpha(beta, gamma)
        for shift in (math.pi, -math.pi):
            assert alpha(beta + shift, gamma) == pytest.approx(ref, abs=1e-12)


def test_wrap_two_pi():
    rng = np.random.default_rng(3)
    for beta, gamma in rng.uniform(-math.pi, math.pi, size=(300, 2)):
        ref = alpha(beta, gamma)
        for kb, kg in ((1, 0), (0, 1), (-1, 2), (3, -2)):
            got = alpha(beta + 2 * math.pi * kb, gamma + 2 * math.pi * kg)
            assert got == pytest.approx(ref, abs=1e-11)


def test_in_range_equals_raw_polynomial():
    """Inside β, γ ∈ (−π/2, π/2) no folding applies: α is the bare trig polynomial,
    written out here term by term from Li et al.'s formula."""
    c = GENERIC
    rng = np.random.default_rng(4)
    for beta, gamma in rng.uniform(-math.pi / 2 + 1e-9, math.pi / 2 - 1e-9, size=(300, 2)):
        az = (c.A00 + c.A10 * math.cos(2 * beta) + c.B11 * math.sin(2 * beta + gamma)
              + c.B01 * math.sin(gamma) + c.Bm11 * math.sin(gamma - 2 * beta))
        ax = (c.C11 * math.cos(2 * beta + gamma) + c.C01 * math.cos(gamma)
              + c.Cm11 * math.cos(gamma - 2 * beta) + c.D10 * math.sin(2 * beta))
        assert alpha(beta, gamma) == pytest.approx((ax, az), abs=1e-12)
        assert alpha_raw(beta, gamma) == pytest.approx((ax, az), abs=1e-12)


@pytest.mark.parametrize("fixed", ["gamma=+90", "gamma=-90", "beta=+90", "beta=-90"])
def test_continuous_across_folding_seams(fixed):
    """The folded map has no jump where the folding switches branch (|γ| = π/2, |β| = π/2);
    a wrong sign in the folding rules shows up as a jump of order 0.1 N/cm³ here."""
    eps = 1e-7
    for other in np.linspace(-math.pi / 2, math.pi / 2, 25):
        if fixed.startswith("gamma"):
            g0 = math.copysign(math.pi / 2, float(fixed[-3:]))
            a, b = alpha(other, g0 - eps), alpha(other, g0 + eps)
        else:
            b0 = math.copysign(math.pi / 2, float(fixed[-3:]))
            a, b = alpha(b0 - eps, other), alpha(b0 + eps, other)
        assert a == pytest.approx(b, abs=1e-6)


def test_pressing_pushes_and_dragging_resists():
    """Physical signs: a plate moving down is pushed up (α_z > 0 for γ ∈ (0, π));
    a vertical plate moving in +x is pushed back (α_x > 0) and in −x pushed forward."""
    for beta in np.linspace(-1.2, 1.2, 13):
        for gamma in np.linspace(0.2, math.pi - 0.2, 13):
            assert alpha(beta, gamma)[1] > 0.0
    assert alpha(math.pi / 2, 0.0)[0] > 0.0
    assert alpha(math.pi / 2, math.pi)[0] < 0.0


def test_coefficients_match_config_defaults():
    """The generic set in rft.py and the config defaults are the same nine numbers."""
    assert Coefficients.from_config(RFTCoefficients()) == GENERIC
    assert GENERIC == Coefficients(0.206, 0.169, 0.212, 0.358, 0.055, -0.124, 0.253, 0.007, 0.088)
