"""The one effects registry (granular_mpc.effects.registry): registration, duplicates across
kinds, name validation, lookups with did-you-mean, the taxonomy and metadata of the library."""
from __future__ import annotations

import uuid

import pytest

from granular_mpc.effects import (KINDS, NAME_FORM, EffectInfo, Param, all_effects,
                                  check_name, describe_effect, effect_info, effect_kind,
                                  get_effect, register_effect, register_joint_effect,
                                  registered_effects, registered_names)
from granular_mpc.effects.registry import register
from granular_mpc.exceptions import ConfigError

PUSH = f"test_registry_push_{uuid.uuid4().hex[:8]}"

#: the library: every built-in effect and its kind
LIBRARY = {"inertial_drag": "terrain_force", "cohesion": "terrain_force",
           "depth_hardening": "terrain_force", "elastic_unloading": "terrain_force",
           "joint_friction": "joint", "force_sensor_bias": "sensor", "terrain_slope": "geometry"}


@register_effect(PUSH, params={"f0": Param(2.0, 0.0, 50.0, "N", "constant upward push")})
def _constant_push(o, s, p):
    """A constant upward push while the patch is in contact."""
    return (0.0, 0.0, p["f0"] * s.in_contact)


def _tag() -> str:
    return uuid.uuid4().hex[:8]


def test_registered_effect_is_listed():
    eff = get_effect(PUSH)
    assert eff.name == PUSH and "f0" in eff.params
    assert PUSH in registered_effects()
    assert eff.doc.startswith("A constant upward push")
    assert isinstance(eff, EffectInfo) and eff.kind == "terrain_force"
    assert eff.force is eff.fn is _constant_push


def test_duplicate_registration_is_refused():
    with pytest.raises(ConfigError, match="already registered"):
        register_effect(PUSH)(_constant_push)


def test_a_name_is_taken_across_kinds_and_replace_switches_kind():
    name = f"shared_{_tag()}"
    register_effect(name, params={"k": Param(1.0, 0.0, 2.0)})(lambda o, s, p: (0, 0, 0))
    with pytest.raises(ConfigError, match="already registered"):
        register_joint_effect(name)(lambda q, dq, p: dq)
    register_joint_effect(name, params={"b": Param(1.0, 0.0, 2.0)}, replace=True)(
        lambda q, dq, p: -p["b"] * dq)
    assert effect_kind(name) == "joint"
    assert name not in registered_effects()                 # no longer a terrain force
    assert name in registered_effects(kinds=KINDS)
    with pytest.raises(ConfigError, match="is a joint effect, not a terrain force"):
        get_effect(name)


def test_taxonomy_of_the_library():
    effects = all_effects()
    for name, kind in LIBRARY.items():
        assert effects[name].kind == kind == effect_kind(name)
        info = effect_info(name)
        assert info.main in info.params and info.neutral, name
        for p, v in info.neutral.items():           # neutral values are allowed values
            spec = info.params[p]
            assert spec.lower <= v <= spec.upper
    assert all_effects(kinds=("joint",)).keys() == {"joint_friction"} | {
        n for n, e in effects.items() if e.kind == "joint"}
    assert list(registered_names())[:len(LIBRARY)] == list(LIBRARY)     # library order
    assert list(registered_effects())[:4] == [n for n, k in LIBRARY.items()
                                              if k == "terrain_force"]


def test_library_metadata():
    assert effect_info("depth_hardening").neutral == {"n": 1.0}
    assert effect_info("joint_friction").main == "coulomb"
    assert effect_info("inertial_drag").depends_on == ("sole speed squared",)
    assert effect_info("cohesion").neutral_params() == {"suction": 0.0, "release": 0.003}
    assert effect_info("cohesion").summary.startswith("Suction of wet (cohesive) sand")


def test_unknown_effect_gets_a_did_you_mean():
    with pytest.raises(ConfigError, match="did you mean 'cohesion'"):
        effect_info("cohesoin")
    with pytest.raises(ConfigError, match="has no parameter 'sucktion'; did you mean 'suction'"):
        effect_info("cohesion").resolve_params({"sucktion": 1.0})
    with pytest.raises(ConfigError, match="out of range"):
        effect_info("cohesion").resolve_params({"suction": -5.0})
    with pytest.raises(ConfigError, match="did you mean 'inertial_drag'") as err:
        get_effect("inertial_drg")
    assert err.value.key == "effects" and "joint_friction" not in err.value.allowed


@pytest.mark.parametrize("bad", ["a/b", "a:b", "a=b", "a,b", "a b", "tab\tname", " ", ""])
def test_invalid_names_are_refused_naming_the_allowed_form(bad):
    with pytest.raises(ConfigError, match="invalid effect name") as err:
        register_effect(bad)(lambda o, s, p: (0, 0, 0))
    assert err.value.allowed == NAME_FORM
    assert bad not in registered_names()
    with pytest.raises(ConfigError, match="invalid parameter"):
        register_effect(f"ok_{_tag()}", params={bad: Param(1.0, 0.0, 2.0)})(
            lambda o, s, p: (0, 0, 0))


def test_valid_names_pass():
    for good in ("_bench_hidden_skew", "oblique-flow2", "sole.adhesion", "Ümlaut"):
        assert check_name(good) == good


def test_metadata_must_name_parameters_and_kind_must_exist():
    with pytest.raises(ConfigError, match="main coefficient 'zz' is not one of its parameters"):
        register_effect(f"m_{_tag()}", params={"k": Param(1.0, 0.0, 2.0)}, main="zz")(
            lambda o, s, p: (0, 0, 0))
    with pytest.raises(ConfigError, match="neutral value for unknown parameter 'zz'"):
        register_effect(f"n_{_tag()}", params={"k": Param(1.0, 0.0, 2.0)},
                        neutral={"zz": 0.0})(lambda o, s, p: (0, 0, 0))
    with pytest.raises(ConfigError, match="unknown kind 'actuator'") as err:
        register(EffectInfo(f"k_{_tag()}", "actuator", {}, lambda: None))
    assert err.value.allowed == ", ".join(KINDS)


def test_describe_effect_sets_metadata_and_keeps_defaults():
    name = f"d_{_tag()}"
    register_effect(name, params={"a": Param(1.0, 0.5, 2.0), "b": Param(0.0, -1.0, 1.0)})(
        lambda o, s, p: (0, 0, 0))
    assert effect_info(name).main == "a" and effect_info(name).neutral == {"a": 0.5}
    describe_effect(name, main="b", depends_on=("depth",), tags=("per_foot",))
    info = effect_info(name)
    assert (info.main, info.neutral, info.depends_on, info.tags) == ("b", {"b": 0.0},
                                                                    ("depth",), ("per_foot",))
    describe_effect(name, neutral={"a": 1.0})
    assert effect_info(name).neutral == {"b": 0.0, "a": 1.0}
    with pytest.raises(ConfigError, match="unknown effect"):
        describe_effect(f"never_{_tag()}", main="x")
