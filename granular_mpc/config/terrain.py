"""Terrain section of the config: a granular layer, rigid ground, or a track of segments
(``models/terrain/*.yaml``)."""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Mapping, Optional, Union

from pydantic import Field, field_validator, model_validator

from ..exceptions import ConfigError
from ..paths import resolve_file
from ..rft_coefficients import GENERIC
from .base import FiniteFloat, NonNegFloat, PositiveFloat, StrictModel
from .effects import EffectSpec
from .yaml_io import load_yaml


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
    bulldozing_length: PositiveFloat = Field(
        0.01, description="Bulldozing saturation length λ [m]: an assumed default (the paper "
                          "gives no value; not identifiable from walking data by the workbench).")
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


UniformTerrainConfig = Annotated[Union[GranularTerrainConfig, RigidTerrainConfig],
                                 Field(discriminator="kind")]
"""One medium everywhere (granular or rigid), told apart by its ``kind`` key."""


def _segment_terrain_mapping(ref: Any, index_key: str) -> Any:
    """A segment's ``terrain`` reference → mapping: a file name (``models/terrain/<name>``
    or a path), a mapping with ``file:`` plus keys to change, or a full mapping."""
    if isinstance(ref, str):
        data = _read_terrain_file(ref, index_key)
    elif isinstance(ref, Mapping) and "file" in ref:
        if not isinstance(ref["file"], str):
            raise ConfigError("must be a terrain file name", key=f"{index_key}.file", value=ref["file"])
        data = _read_terrain_file(ref["file"], f"{index_key}.file")
        data.update({k: v for k, v in ref.items() if k != "file"})
    else:
        return ref
    if data.get("kind") == "track":
        raise ConfigError("a track segment must be one medium, not another track",
                          key=index_key, value=data.get("name"))
    return data


def _read_terrain_file(name: str, key: str) -> dict:
    """The mapping of terrain file ``name`` (not validated; duplicate keys, non-UTF-8 text
    and malformed YAML are ConfigErrors naming the file)."""
    return load_yaml(resolve_file("terrain", name, key=key))


class TrackSegment(StrictModel):
    """One stretch of a :class:`TrackTerrainConfig`: a medium up to ``until_x``."""

    until_x: Optional[FiniteFloat] = Field(
        None, description="End of the segment along world x [m] (exclusive); the last "
                          "segment has none and runs to +∞.")
    terrain: UniformTerrainConfig = Field(
        description="The segment's medium: a terrain file name (models/terrain/), a mapping "
                    "with 'file:' plus keys to change, or a full terrain mapping.")

    @field_validator("terrain", mode="before")
    @classmethod
    def _load(cls, value: Any) -> Any:
        return _segment_terrain_mapping(value, "terrain")


class TrackTerrainConfig(StrictModel):
    """A track whose ground law changes along world x (the paper's rigid platform then a
    12 cm sand layer level with it).

    Segment k holds for ``until_x[k-1] ≤ x < until_x[k]`` (the first from −∞, the last to
    +∞), x being the foot's lowest sole point at touchdown (see
    :mod:`granular_mpc.terrain.track`). Every segment must have the same free surface
    (height and slope): the track is level across its edges.
    """

    kind: Literal["track"] = "track"
    name: str = Field("track", description="Human-readable name of the track.")
    description: str = ""
    source: str = Field("", description="Where the layout comes from.")
    segments: list[TrackSegment] = Field(min_length=2, description="Segments in increasing x.")

    @model_validator(mode="after")
    def _layout(self) -> "TrackTerrainConfig":
        ends = [s.until_x for s in self.segments]
        if any(e is None for e in ends[:-1]):
            raise ValueError("every segment but the last needs until_x [m]")
        if ends[-1] is not None:
            raise ValueError("the last segment runs to +inf: drop its until_x")
        inner = [float(e) for e in ends[:-1]]
        if any(b <= a for a, b in zip(inner, inner[1:])):
            raise ValueError(f"until_x must increase from segment to segment, got {inner}")
        first = self.segments[0].terrain
        for s in self.segments[1:]:
            t = s.terrain
            if not (math.isclose(t.surface_height, first.surface_height, abs_tol=1e-12)
                    and list(t.surface_slope) == list(first.surface_slope)):
                raise ValueError("every segment must have the same surface_height and "
                                 "surface_slope (a level track); got "
                                 f"{first.name}: {first.surface_height:g} m, {list(first.surface_slope)} and "
                                 f"{t.name}: {t.surface_height:g} m, {list(t.surface_slope)}")
        return self

    @property
    def surface_height(self) -> float:
        """Height of the (common) free surface [m], world frame."""
        return float(self.segments[0].terrain.surface_height)

    @property
    def surface_slope(self) -> list[float]:
        """The (common) surface slope dz/dx, dz/dy [-]."""
        return list(self.segments[0].terrain.surface_slope)

    @property
    def edges(self) -> tuple[float, ...]:
        """x of each edge between segments [m], increasing."""
        return tuple(float(s.until_x) for s in self.segments[:-1])

    def segment_index(self, x: float) -> int:
        """Index of the segment holding world x [m] (an edge belongs to the next one)."""
        for k, e in enumerate(self.edges):
            if x < e:
                return k
        return len(self.segments) - 1

    def terrain_at(self, x: float):
        """The medium (a granular or rigid config) at world x [m]."""
        return self.segments[self.segment_index(x)].terrain


TerrainConfig = Annotated[Union[GranularTerrainConfig, RigidTerrainConfig, TrackTerrainConfig],
                          Field(discriminator="kind")]
"""Any terrain kind (granular, rigid or a track of them), told apart by its ``kind`` key."""

__all__ = ["RFTCoefficients", "GranularTerrainConfig", "RigidTerrainConfig",
           "UniformTerrainConfig", "TrackSegment", "TrackTerrainConfig", "TerrainConfig"]
