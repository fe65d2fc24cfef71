"""Typed configuration: YAML → validated, immutable config objects.

Every config object is a frozen pydantic model that rejects unknown keys. Errors are
turned into one :class:`~granular_mpc.exceptions.ConfigError` naming the dotted key path,
the offending value, what is allowed and — for misspelt keys — the closest valid key.

Scenario files (``sim/*.yaml``) refer to a robot file (``models/<robot>.yaml``) and a
terrain file (``models/terrain/<name>.yaml``) by name. :func:`granular_mpc.scenario.load_scenario`
resolves those references into one plain dictionary (the *resolved config*, saved with
every run), applies ``--set key.path=value`` overrides, then validates it.

Modules, one job each (import from this package; every name below is re-exported):

* :mod:`.base` — :class:`StrictModel` and the constrained number types;
* :mod:`.schema_walk` — following a key path through the schema (did-you-mean hints);
* :mod:`.errors` — :func:`validate`: pydantic errors → one ``ConfigError``;
* :mod:`.effects` — :class:`EffectSpec` and the ``"name:k=v,…"`` form;
* :mod:`.terrain`, :mod:`.robot`, :mod:`.controller`, :mod:`.scenario` — the sections;
* :mod:`.loader` — YAML files, robot/terrain files by name, ``--set`` overrides.
"""

from .base import FiniteFloat, NonNegFloat, PositiveFloat, StrictModel
from .controller import (CommandConfig, ControllerConfig, FootholdConfig, GaitConfig, MPCConfig,
                         SwingConfig, WBCConfig)
from .effects import EffectSpec, parse_effect_string
from .errors import format_location, validate
from .loader import (apply_override, dump_yaml, load_robot, load_terrain, load_yaml,
                     parse_override, robot_dict, terrain_dict, terrain_from_dict, to_plain)
from .robot import FootConfig, FootGeometry, RobotConfig
from .scenario import (ActuatorsConfig, DropConfig, FallConfig, GuideRigConfig, PlaybackConfig,
                       JointFrictionConfig, MetricsConfig, MotorConfig, OutputConfig,
                       PushConfig, ScenarioConfig, SimConfig, SweepConfig, Vector3)
from .schema_walk import model_fields_at
from .terrain import (GranularTerrainConfig, RFTCoefficients, RigidTerrainConfig,
                      TerrainConfig, TrackSegment, TrackTerrainConfig)

__all__ = [
    "StrictModel", "PositiveFloat", "NonNegFloat", "FiniteFloat",
    "format_location", "model_fields_at", "validate",
    "EffectSpec", "parse_effect_string",
    "RFTCoefficients", "GranularTerrainConfig", "RigidTerrainConfig", "TerrainConfig",
    "TrackSegment", "TrackTerrainConfig",
    "FootGeometry", "FootConfig", "RobotConfig",
    "GaitConfig", "SwingConfig", "FootholdConfig", "MPCConfig", "WBCConfig", "ControllerConfig",
    "CommandConfig",
    "SimConfig", "ActuatorsConfig", "JointFrictionConfig", "MotorConfig", "DropConfig", "PlaybackConfig", "Vector3", "FallConfig", "PushConfig", "GuideRigConfig",
    "MetricsConfig", "OutputConfig", "SweepConfig", "ScenarioConfig",
    "load_yaml", "to_plain", "dump_yaml", "robot_dict", "terrain_dict", "load_robot",
    "load_terrain", "terrain_from_dict", "parse_override", "apply_override",
]
