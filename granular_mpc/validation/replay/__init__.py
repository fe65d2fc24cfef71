"""Replay every stance from its measured touchdown state (multiple shooting) and score it.

``validate(DATA, model=…)`` replays each complete stance phase of a measurement data set
(:mod:`..prepare`: one :class:`~..prepare.StanceWindow` per stance) from its measured
first sample with the measured joint torques held over each sample, and compares the
predicted joint angles, ground reaction force and intrusion of the stance foot with the
measured ones: RMSE by channel × stance-phase bin × commanded speed with intervals from
resampling whole trials (:func:`granular_mpc.analysis.rmse_table`), ``report.json`` and
figures.

Models (``--model``):

* ``granular`` — the 3-D plant (:class:`~granular_mpc.dynamics.Plant`) with the terrain
  model (RFT closed form, elastic–plastic contact, bulldozing, added mass), both feet in
  contact as measured at the window start; extra effects of every kind can be added;
* ``rigid`` — the paper's rigid-ground model (Sec. IV): non-slip, non-sinkage; the stance
  foot's contact point is pinned with its Jacobian J₀ frozen at touchdown; the GRF is the
  constraint force of M v̇ + h = S τ + J₀ᵀ λ, J₀ v̇ = −k J₀ v (inverse dynamics of the
  constrained motion); intrusion ≡ 0; single stance (the other foot is free);
* ``planar`` — the paper's decoupled planar model: sagittal 7-DoF and frontal 5-DoF
  (:mod:`granular_mpc.dynamics.planar`) driven by the mapped torques, the stance foot's
  force from the same terrain law evaluated on the planar foot kinematics (the x and z
  forces go to the sagittal model, y and z to the frontal one); single stance.

Speed: one stance (≈ 0.2 s, 400 plant steps) replays in ≈ 40 ms (granular); windows are
spread over a process pool (``workers``).

Modules, one job each: :mod:`.model` (the replayed model and its variants),
:mod:`.outputs` (what a replay returns), :mod:`.measurement` (sensor effects: true
inputs and initial state from measured ones, checks), :mod:`.granular`, :mod:`.rigid`, :mod:`.planar`
(one stance window on each model), :mod:`.pool` (many replays over a process pool),
:mod:`.scoring` (RMSE tables), :mod:`.validation` (``validate`` and its report).
"""

from .granular import replay_granular
from .measurement import check_sensor_inversion, check_sensor_specs, true_window, window_columns
from .model import (MODELS, REPLAY_PARAMS, TERRAIN_THETA_CONFIG, ReplayModel, Variant,
                    build_replay_model, effect_variant, model_terrain, resolve_effect_specs)
from .planar import replay_planar
from .pool import REPLAYERS, ReplayPool
from .rigid import replay_rigid
from .scoring import rmse_tables, role_channels
# last: validate reads diagnosis files (granular_mpc.validation.diagnosis.result)
from .validation import ValidationReport, load_fitted, validate

__all__ = ["validate", "ValidationReport", "Variant", "ReplayModel", "ReplayPool",
           "build_replay_model", "effect_variant", "replay_granular", "replay_rigid",
           "replay_planar", "rmse_tables", "model_terrain", "load_fitted",
           "resolve_effect_specs", "role_channels", "MODELS", "REPLAYERS", "REPLAY_PARAMS",
           "TERRAIN_THETA_CONFIG", "check_sensor_inversion", "check_sensor_specs", "true_window",
           "window_columns"]
