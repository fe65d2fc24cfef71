"""Robot description: Pinocchio model, frames, planar views."""
from .model import SIDES, Biped, load_biped

__all__ = ["Biped", "load_biped", "SIDES"]
