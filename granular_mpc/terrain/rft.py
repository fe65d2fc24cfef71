"""Resistive force theory stresses of Li, Zhang & Goldman (Science 339:1408, 2013).

A surface element of area dA at depth |z| below the free surface, moving into the medium,
feels the stress ``(−α_x, α_z)·|z|`` per area in the lab's (x forward, z up) frame, where
α depends only on the element's attack angle β and the velocity angle γ:

    α_z(β, γ) = A00 + A10 cos2β + B11 sin(2β+γ) + B01 sinγ + B₋₁₁ sin(γ−2β)
    α_x(β, γ) = C11 cos(2β+γ) + C01 cosγ + C₋₁₁ cos(γ−2β) + D10 sin2β

Conventions (the paper's Fig. 2 of Li 2013):

* β ∈ [−π/2, π/2] is the angle of the element's tangent line from the horizontal, positive
  when it rises in the direction of horizontal motion (a horizontal plate: β = 0; vertical:
  β = ±π/2);
* γ ∈ [−π/2, π/2] is the angle of the velocity below the horizontal (γ = π/2: straight down);
* α_z > 0 pushes up; α_x > 0 resists motion in +x.

Outside those ranges the values are folded (wrap to (−π, π]; β ± π; mirror x → −x for
|γ| > π/2, keeping α_z and negating α_x). The generic coefficients are normalised so that
α_z(0, π/2) = 1; a medium is described by the scale ζ (α = ζ·α_generic, in N/cm³). The
coefficients (:class:`Coefficients`, :data:`GENERIC`) are defined in
:mod:`granular_mpc.rft_coefficients` and re-exported here.

Everything here is plain float math (fast in the plant loop); :mod:`.closed_form` uses the
same trig polynomial, written for any backend, to build CasADi expressions.
"""

from __future__ import annotations

import math

from ..rft_coefficients import GENERIC, Coefficients

N_PER_CM3 = 1.0e6  # 1 N/cm³ = 1e6 N/m³


def _wrap(angle: float) -> float:
    """Wrap to (−π, π]."""
    a = math.fmod(angle + math.pi, 2.0 * math.pi)
    if a <= 0.0:
        a += 2.0 * math.pi
    return a - math.pi


def alpha_raw(beta: float, gamma: float, c: Coefficients = GENERIC) -> tuple[float, float]:
    """The trig polynomial without folding: returns (α_x, α_z) in N/cm³ (generic units)."""
    s2b, c2b = math.sin(2.0 * beta), math.cos(2.0 * beta)
    sg, cg = math.sin(gamma), math.cos(gamma)
    az = (c.A00 + c.A10 * c2b + c.B11 * (s2b * cg + c2b * sg) + c.B01 * sg
          + c.Bm11 * (sg * c2b - cg * s2b))
    ax = (c.C11 * (c2b * cg - s2b * sg) + c.C01 * cg + c.Cm11 * (cg * c2b + sg * s2b)
          + c.D10 * s2b)
    return ax, az


def alpha(beta: float, gamma: float, c: Coefficients = GENERIC) -> tuple[float, float]:
    """RFT stresses per depth (α_x, α_z) [N/cm³, generic units] for any β, γ (folded).

    Args:
        beta: attack angle of the element's tangent line [rad].
        gamma: velocity angle below the +x horizontal [rad]; |γ| > π/2 means moving in −x.
    """
    beta = _wrap(beta)
    gamma = _wrap(gamma)
    if beta <= -math.pi / 2.0:
        beta += math.pi
    elif beta > math.pi / 2.0:
        beta -= math.pi
    if gamma > math.pi / 2.0:
        ax, az = alpha_raw(-beta, math.pi - gamma, c)
        return -ax, az
    if gamma < -math.pi / 2.0:
        ax, az = alpha_raw(-beta, -math.pi - gamma, c)
        return -ax, az
    return alpha_raw(beta, gamma, c)


__all__ = ["Coefficients", "GENERIC", "alpha", "alpha_raw", "N_PER_CM3"]
