"""Effects: physically named terms a model may be missing, of four kinds, in one registry.

The validation workbench injects effects into synthetic data (``granular-mpc synth
--effect``), adds them to a replayed model (``granular-mpc validate --effect``) and tests
them as candidates (``granular-mpc diagnose``); a terrain config switches terrain forces on
(``effects: ["inertial_drag:c_d=1.2"]``). Modules:

* :mod:`.registry`: the one registry keyed by name, entries typed by kind
  (``terrain_force``, ``joint``, ``sensor``, ``geometry``) with their parameters and
  diagnosis metadata; lookups and lists.
* :mod:`.api`: the plugin API a user's effect file imports (``Param``,
  ``register_effect`` and the decorators of the other kinds, ``load_effect_file``).
* :mod:`.params`, :mod:`.state`: parameter specs; what an effect reads (``PatchState``,
  ``SensorContext``).
* :mod:`.tracing`: a terrain force traced on CasADi symbols (what a terrain model
  compiles), with one :class:`~granular_mpc.exceptions.EffectError` for Python control flow
  on the patch state.
* the library, one file per kind: :mod:`.terrain_force` (``inertial_drag``, ``cohesion``,
  ``depth_hardening``, ``elastic_unloading``), :mod:`.joint` (``joint_friction``),
  :mod:`.sensor` (``force_sensor_bias``), :mod:`.geometry` (``terrain_slope``), each with
  the function that applies its kind.
* :mod:`.measurement` (opt-in, not imported here): the measurement model as sensor-effect
  candidates (per-joint torque gain / offset, encoder offsets, force-sensor gain, torque
  time offset); importing it registers them.

Importing this package registers the library.
"""

# the library registers itself on import, kind by kind in this order (isort: skip)
from . import terrain_force, joint, sensor, geometry  # noqa: F401
from .api import (load_effect_file, register_effect, register_geometry_effect,
                  register_joint_effect, register_sensor_effect)
from .geometry import GEOMETRY_THETA, geometry_theta, terrain_slope
from .joint import joint_friction, joint_torque_function
from .params import Param, resolve_params
from .registry import (FORBIDDEN_NAME_CHARS, KINDS, NAME_FORM, Effect, EffectInfo, EffectKind,
                       all_effects, check_name, describe_effect, effect_info, effect_kind,
                       get_effect, registered_effects, registered_names)
from .sensor import (apply_sensor_effects, check_sensor_effect, force_sensor_bias,
                     invert_sensor_effects)
from .state import ForceFn, PatchState, SensorContext
from .terrain_force import cohesion, depth_hardening, elastic_unloading, inertial_drag

__all__ = [
    # registry
    "EffectKind", "KINDS", "FORBIDDEN_NAME_CHARS", "NAME_FORM", "EffectInfo", "Effect",
    "check_name", "describe_effect", "effect_info", "effect_kind", "get_effect",
    "all_effects", "registered_effects", "registered_names",
    # plugin API
    "Param", "resolve_params", "PatchState", "ForceFn", "SensorContext", "register_effect",
    "register_joint_effect", "register_sensor_effect", "register_geometry_effect",
    "load_effect_file",
    # applying each kind
    "joint_torque_function", "apply_sensor_effects", "check_sensor_effect",
    "invert_sensor_effects", "geometry_theta", "GEOMETRY_THETA",
    # the library
    "inertial_drag", "cohesion", "depth_hardening", "elastic_unloading", "joint_friction",
    "force_sensor_bias", "terrain_slope",
]
