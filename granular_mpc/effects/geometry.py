"""Effects of kind ``geometry``: terrain parameters of the plant's compiled contact function.

Each is ``fn(p) -> {theta_name: value}`` with names from :data:`GEOMETRY_THETA`;
:func:`geometry_theta` collects the values of several (later ones win). Library:
``terrain_slope``.
"""

from __future__ import annotations

from typing import Mapping, Sequence

from ..exceptions import ConfigError
from .api import register_geometry_effect
from .params import Param
from .registry import EffectInfo

#: θ names a geometry effect may set (terrain parameters of the compiled contact function)
GEOMETRY_THETA = ("surface_height", "surface_slope_x", "surface_slope_y", "layer_depth")


@register_geometry_effect("terrain_slope", params={
    "slope_x": Param(0.02, -0.3, 0.3, "-", "dz/dx of the free surface (uphill along +x > 0)"),
    "slope_y": Param(0.0, -0.3, 0.3, "-", "dz/dy of the free surface"),
}, main="slope_x", neutral={"slope_x": 0.0, "slope_y": 0.0},
    depends_on=("position of the footprint along the walk",))
def terrain_slope(p):
    """A sloped free surface z = h + s_x x + s_y y (an inclined sand bed)."""
    return {"surface_slope_x": p["slope_x"], "surface_slope_y": p["slope_y"]}


def geometry_theta(specs: Sequence[tuple[EffectInfo, Mapping[str, float]]]) -> dict[str, float]:
    """Terrain parameters set by the geometry effects of ``specs`` (later ones win; other
    kinds skipped).

    Args:
        specs: ``(EffectInfo, parameter values)`` per effect.

    Raises:
        ConfigError: an effect sets a name that is not in :data:`GEOMETRY_THETA`.
    """
    out: dict[str, float] = {}
    for info, p in specs:
        if info.kind != "geometry":
            continue
        vals = info.fn(dict(p))
        for k, v in vals.items():
            if k not in GEOMETRY_THETA:
                raise ConfigError(f"geometry effect '{info.name}' sets {k!r}, which is not a "
                                  "terrain geometry parameter", key=f"effects.{info.name}",
                                  allowed=", ".join(GEOMETRY_THETA))
            out[k] = float(v)
    return out


__all__ = ["GEOMETRY_THETA", "terrain_slope", "geometry_theta"]
