"""Compatibility module: the effects registry and plugin API live in :mod:`granular_mpc.effects`.

``from granular_mpc.terrain.effects import Param, register_effect`` (users' effect files,
older scripts) keeps working; new code imports from :mod:`granular_mpc.effects`.
"""

from ..effects import (Effect, ForceFn, Param, PatchState, get_effect, inertial_drag,
                       load_effect_file, register_effect, registered_effects, resolve_params)

__all__ = ["Param", "PatchState", "Effect", "ForceFn", "register_effect", "resolve_params",
           "get_effect", "registered_effects", "load_effect_file", "inertial_drag"]
