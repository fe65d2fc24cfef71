"""granular_mpc — bipedal walking on granular terrain.

Augmented sinkage/slip dynamics (Chen et al., ICRA 2026), a centroidal-plus-sinkage MPC with
a whole-body controller, a closed-loop simulator and a validation workbench.
"""
from .exceptions import GranularMpcError

__version__ = "0.1.0"
__all__ = ["GranularMpcError", "__version__"]
