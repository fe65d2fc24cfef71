"""Compatibility module: the effects library lives in :mod:`granular_mpc.effects` (one file
per kind: ``terrain_force``, ``joint``, ``sensor``, ``geometry``; the registry in
``registry``). Every name this module exported is re-exported here; new code imports from
:mod:`granular_mpc.effects`.
"""

from ..effects import (GEOMETRY_THETA, KINDS, EffectInfo, EffectKind, SensorContext,
                       all_effects, apply_sensor_effects, cohesion, depth_hardening,
                       describe_effect, effect_info, effect_kind, elastic_unloading,
                       force_sensor_bias, geometry_theta, joint_friction, joint_torque_function,
                       register_geometry_effect, register_joint_effect, register_sensor_effect,
                       terrain_slope)

__all__ = ["EffectKind", "KINDS", "EffectInfo", "SensorContext", "GEOMETRY_THETA",
           "register_joint_effect", "register_sensor_effect", "register_geometry_effect",
           "describe_effect", "effect_info", "effect_kind", "all_effects",
           "joint_torque_function", "apply_sensor_effects", "geometry_theta",
           "cohesion", "depth_hardening", "elastic_unloading", "joint_friction",
           "force_sensor_bias", "terrain_slope"]
