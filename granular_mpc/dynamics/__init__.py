"""Dynamics: the 3-D augmented plant and the paper's planar augmented models.

``granular_mpc.dynamics.planar`` holds the sagittal (7-DoF) and frontal (5-DoF) augmented
models (docs/planar-models.md).
"""
from . import planar
from .plant import Plant, PlantData

__all__ = ["Plant", "PlantData", "planar"]
