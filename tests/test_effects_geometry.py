"""Geometry effects (granular_mpc.effects.geometry): the library's terrain slope mapped to the
contact function's surface parameters; names outside GEOMETRY_THETA refused."""
from __future__ import annotations

import uuid

import pytest

from granular_mpc.effects import all_effects, effect_info, geometry_theta, register_geometry_effect
from granular_mpc.exceptions import ConfigError


def test_terrain_slope_maps_to_the_surface_slope(robot_config):
    th = geometry_theta([(effect_info("terrain_slope"), {"slope_x": 0.02, "slope_y": -0.01})])
    assert th == {"surface_slope_x": 0.02, "surface_slope_y": -0.01}
    with pytest.raises(ConfigError, match="not a terrain geometry parameter"):
        register_geometry_effect(f"bad_{uuid.uuid4().hex[:6]}", params={})(lambda p: {"zeta": 1.0})
        geometry_theta([(effect_info(next(n for n in all_effects() if n.startswith("bad_"))), {})])
