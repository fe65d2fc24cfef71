"""Dynamics: the 3-D augmented plant and the paper's planar augmented models."""
from .plant import Plant, PlantData

__all__ = ["Plant", "PlantData"]
