"""Terrain models: granular (RFT closed form, solidified wedge, bulldozing), rigid ground,
and a track of them along x (:class:`TrackTerrain`).

Choose by name in YAML (``models/terrain/*.yaml``); build with :func:`build_terrain`.
The effects a terrain may add live in :mod:`granular_mpc.effects` (re-exported here).
"""
from ..effects import Param, PatchState, get_effect, register_effect, registered_effects
from .base import TerrainModel, build_terrain
from .rft import alpha
from .track import TrackTerrain

__all__ = ["TerrainModel", "TrackTerrain", "build_terrain", "alpha", "Param", "PatchState", "register_effect",
           "get_effect", "registered_effects"]
