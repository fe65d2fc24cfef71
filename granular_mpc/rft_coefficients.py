"""The generic resistive-force-theory coefficients of Li, Zhang & Goldman (Science 2013).

Defined once, here at the bottom of the import stack: :mod:`granular_mpc.terrain.rft`
evaluates the stresses with them and the terrain config
(:class:`granular_mpc.config.RFTCoefficients`) takes its defaults from them. This module
imports nothing from the package.

    α_z(β, γ) = A00 + A10 cos2β + B11 sin(2β+γ) + B01 sinγ + B₋₁₁ sin(γ−2β)
    α_x(β, γ) = C11 cos(2β+γ) + C01 cosγ + C₋₁₁ cos(γ−2β) + D10 sin2β
"""

from __future__ import annotations

from typing import NamedTuple


class Coefficients(NamedTuple):
    """The nine Fourier coefficients of the generic RFT set [N/cm³]."""

    A00: float = 0.206
    A10: float = 0.169
    B11: float = 0.212
    B01: float = 0.358
    Bm11: float = 0.055
    C11: float = -0.124
    C01: float = 0.253
    Cm11: float = 0.007
    D10: float = 0.088

    @classmethod
    def from_config(cls, cfg) -> "Coefficients":
        """The nine values of a config object with the same attribute names
        (:class:`granular_mpc.config.RFTCoefficients`)."""
        return cls(*(getattr(cfg, name) for name in cls._fields))


GENERIC = Coefficients()
"""Li et al.'s generic set, normalised so that α_z(0, π/2) = 1."""

__all__ = ["Coefficients", "GENERIC"]
