"""Terrain section of the config: a granular layer or rigid ground (``models/terrain/*.yaml``)."""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field

from ..rft_coefficients import GENERIC
from .base import FiniteFloat, NonNegFloat, PositiveFloat, StrictModel
from .effects import EffectSpec


class RFTCoefficients(StrictModel):
    """Li et al. (2013) discrete-Fourier coefficients of the RFT stresses, generic set [N/cm³].

    α_z = A00 + A10 cos2β + B11 sin(2β+γ) + B01 sinγ + Bm11 sin(γ−2β)
    α_x = C11 cos(2β+γ) + C01 cosγ + Cm11 cos(γ−2β) + D10 sin2β

    The defaults are :data:`granular_mpc.rft_coefficients.GENERIC`.
    """

    A00: FiniteFloat = GENERIC.A00
    A10: FiniteFloat = GENERIC.A10
    B11: FiniteFloat = GENERIC.B11
    B01: FiniteFloat = GENERIC.B01
    Bm11: FiniteFloat = GENERIC.Bm11
    C11: FiniteFloat = GENERIC.C11
    C01: FiniteFloat = GENERIC.C01
    Cm11: FiniteFloat = GENERIC.Cm11
    D10: FiniteFloat = GENERIC.D10


class _TerrainBase(StrictModel):
    """Keys every terrain kind has: name, provenance, surface plane, extra effects."""

    name: str = Field("terrain", description="Human-readable name of the medium.")
    description: str = ""
    source: str = Field("", description="Where the parameter values come from.")
    surface_height: FiniteFloat = Field(0.0, description="Height of the free surface z [m], world frame.")
    surface_slope: list[Annotated[float, Field(ge=-0.5, le=0.5)]] = Field(
        [0.0, 0.0], min_length=2, max_length=2,
        description="Surface slope dz/dx, dz/dy [-]: the surface is z = h + s_x x + s_y y.")
    effects: list[EffectSpec] = Field(default_factory=list)


class GranularTerrainConfig(_TerrainBase):
    """A granular layer (RFT closed form, solidified wedge, bulldozing) over rigid ground."""

    kind: Literal["granular"] = "granular"
    zeta: PositiveFloat = Field(1.36, description="RFT scaling ζ of the generic coefficients [-].")
    phi_s_deg: float = Field(38.0, gt=0.0, lt=90.0, allow_inf_nan=False,
                             description="Solidified-zone (granular friction) angle φ_s [deg], in (0, 90).")
    density: PositiveFloat = Field(1660.0, description="Bulk density ρ [kg/m³].")
    layer_depth: PositiveFloat = Field(0.12, description="Thickness of the layer over rigid ground [m].")
    bulldozing_length: PositiveFloat = Field(0.01, description="Bulldozing saturation length λ [m] (calibrated).")
    sole_shear_alpha: NonNegFloat = Field(0.136, description="Generic in-plane shear stress per depth of the sole [N/cm³] (α_x(0,0)).")
    added_mass_scale: NonNegFloat = Field(1.0, description="Scale of the solidified-zone added mass [-].")
    contact_stiffness: PositiveFloat = Field(2.0e5, description="Elastic regularisation stiffness per contact patch [N/m].")
    contact_damping: NonNegFloat = Field(100.0, description="Elastic-regime damping per patch [N·s/m].")
    bottom_friction: PositiveFloat = Field(0.8, description="Coulomb friction of the rigid floor under the layer [-].")
    direction_time_constant: PositiveFloat = Field(0.01, description="Blends elastic displacement into the flow direction at low speed [s].")
    rft: RFTCoefficients = Field(default_factory=RFTCoefficients)


class RigidTerrainConfig(_TerrainBase):
    """Rigid, non-sinking ground: stiff unilateral contact with Coulomb friction."""

    kind: Literal["rigid"] = "rigid"
    friction: PositiveFloat = Field(0.8, description="Coulomb friction coefficient μ [-].")
    contact_stiffness: PositiveFloat = Field(1.0e5, description="Normal and tangential stiffness per patch [N/m].")
    contact_damping: NonNegFloat = Field(100.0, description="Normal and tangential damping per patch [N·s/m].")


TerrainConfig = Annotated[Union[GranularTerrainConfig, RigidTerrainConfig],
                          Field(discriminator="kind")]
"""Either terrain kind, told apart by its ``kind`` key."""

__all__ = ["RFTCoefficients", "GranularTerrainConfig", "RigidTerrainConfig",
           "TerrainConfig"]
