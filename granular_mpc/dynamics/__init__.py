"""Dynamics: the 3-D augmented plant and the paper's planar augmented models.

* :mod:`.plant` — the reference plant (Pinocchio + the terrain's compiled contact law);
  :mod:`.actuators` — its optional joint friction and motor model;
* :mod:`.planar` — the sagittal (7-DoF) and frontal (5-DoF) augmented models
  (docs/planar-models.md);
* :mod:`.rigid_body_sx`, :mod:`.step_sx`, :mod:`.compiled` — the whole plant step as one
  compiled CasADi function (:class:`CompiledPlant`), :mod:`.fast_plant` — the
  :class:`Plant` interface on it, :mod:`.batch` — many robots per call
  (:class:`BatchPlant`), :mod:`.select` — which of the two steps a run or a replay
  (``sim.plant``, ``$GRANULAR_MPC_PLANT``; docs/speed.md).
"""
from . import planar
from .actuators import ActuatorModel
from .batch import BatchPlant
from .compiled import CompiledPlant
from .fast_plant import FastPlant
from .plant import Plant, PlantData

__all__ = ["Plant", "PlantData", "ActuatorModel", "CompiledPlant", "FastPlant", "BatchPlant",
           "planar"]
