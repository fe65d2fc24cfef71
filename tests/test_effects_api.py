"""The plugin API (granular_mpc.effects.api): decorators of every kind, effect files loaded
with ``--effect-file``, and the old import paths users' files still use."""
from __future__ import annotations

import textwrap
import uuid

import numpy as np
import pytest

import granular_mpc.effects as effects
import granular_mpc.terrain as terrain_pkg
import granular_mpc.terrain.effects as old_effects
import granular_mpc.terrain.effects_library as old_library
from granular_mpc.config import load_terrain, terrain_from_dict
from granular_mpc.effects import (KINDS, Param, effect_info, effect_kind, geometry_theta,
                                  load_effect_file, register_effect, register_geometry_effect,
                                  register_joint_effect, register_sensor_effect,
                                  registered_effects)
from granular_mpc.exceptions import ConfigError
from granular_mpc.terrain import build_terrain

from test_contact import DT, step_foot


def _terrain_with(robot_config, effects_list, base="dry_sand"):
    data = dict(load_terrain(base).model_dump())
    data["effects"] = effects_list
    return build_terrain(terrain_from_dict(data), robot_config)


def test_user_effects_of_every_kind_register_and_collide():
    tag = uuid.uuid4().hex[:6]

    @register_joint_effect(f"j_{tag}", params={"b": Param(1.0, 0.0, 5.0, "N·m·s/rad")})
    def _j(q, dq, p):
        return -p["b"] * dq

    @register_sensor_effect(f"s_{tag}", params={"k": Param(1.1, 0.5, 2.0)}, main="k",
                            neutral={"k": 1.0})
    def _s(cols, p, ctx):
        return {"grf_z": np.asarray(cols["grf_z"]) * p["k"]}

    @register_geometry_effect(f"g_{tag}", params={"h": Param(0.01, -0.1, 0.1, "m")})
    def _g(p):
        return {"surface_height": p["h"]}

    assert effect_kind(f"j_{tag}") == "joint"
    assert effect_info(f"s_{tag}").neutral == {"k": 1.0}          # explicit neutral
    assert effect_info(f"j_{tag}").neutral == {"b": 0.0}          # default: main at 0
    assert geometry_theta([(effect_info(f"g_{tag}"), {"h": 0.02})]) == {"surface_height": 0.02}
    with pytest.raises(ConfigError, match="already registered"):
        register_joint_effect(f"s_{tag}")(_j)
    with pytest.raises(ConfigError, match="already registered"):
        register_effect("cohesion")(lambda o, s, p: (0, 0, 0))


@pytest.mark.parametrize("module", ["granular_mpc.terrain.effects", "granular_mpc.effects"])
def test_load_effect_file(tmp_path, robot_config, module):
    """A user's terrain force from a file, with the old and the new import path."""
    name = f"user_sole_adhesion_{uuid.uuid4().hex[:8]}"
    path = tmp_path / "my_effects.py"
    path.write_text(textwrap.dedent(f'''\
        from {module} import Param, register_effect

        @register_effect("{name}", params={{"f0": Param(2.0, 0.0, 50.0, "N", "pull-off force")}})
        def sole_adhesion(o, s, p):
            """Constant pull toward the sand while the sole is buried and rising."""
            rising = o.if_else(s.v_c[2] > 0.0, 1.0, 0.0)
            return (0.0, 0.0, -p["f0"] * rising * s.in_contact)
        '''))
    assert load_effect_file(str(path)) == [name]
    terrain = _terrain_with(robot_config, [{"name": name, "params": {"f0": 4.0}}])
    plain = _terrain_with(robot_config, [])
    R = robot_config.foot.radius
    out = []
    for t in (plain, terrain):
        data = t.new_data(DT)
        step_foot(data, [0.0, 0.0, R - 0.02], v=(0.0, 0.0, -0.1))
        f, _ = step_foot(data, [0.0, 0.0, R - 0.02], v=(0.0, 0.0, 0.05))   # rising
        out.append(f)
    np.testing.assert_allclose(out[1] - out[0], [0.0, 0.0, -4.0 * robot_config.foot.slices], atol=1e-9)


def test_load_effect_file_returns_effects_of_every_kind(tmp_path):
    tag = uuid.uuid4().hex[:8]
    path = tmp_path / "kinds.py"
    path.write_text(textwrap.dedent(f'''\
        from granular_mpc.effects import (Param, register_effect, register_joint_effect,
                                          register_sensor_effect)

        @register_effect("f_{tag}", params={{"c": Param(1.0, 0.0, 2.0)}})
        def force(o, s, p):
            return (0.0, 0.0, p["c"] * s.in_contact)

        @register_joint_effect("j_{tag}", params={{"b": Param(1.0, 0.0, 2.0)}})
        def joint(q, dq, p):
            return -p["b"] * dq

        @register_sensor_effect("s_{tag}", params={{"g": Param(1.0, 0.5, 2.0)}})
        def sensor(cols, p, ctx):
            return {{"grf_z": cols["grf_z"] * p["g"]}}
        '''))
    assert load_effect_file(str(path)) == sorted([f"f_{tag}", f"j_{tag}", f"s_{tag}"])
    assert [effect_kind(n) for n in (f"f_{tag}", f"j_{tag}", f"s_{tag}")] == [
        "terrain_force", "joint", "sensor"]
    assert f"j_{tag}" in registered_effects(kinds=KINDS)


def test_load_effect_file_returns_its_names_when_loaded_again(tmp_path):
    """A file that registers with ``replace=True`` (as ``diagnose``'s proposals do) returns
    its names each time it is loaded, not only the first; an unrelated registration in
    between is not among them."""
    tag = uuid.uuid4().hex[:8]
    path = tmp_path / "again.py"
    path.write_text(textwrap.dedent(f'''\
        from granular_mpc.effects import Param, register_joint_effect

        @register_joint_effect("again_{tag}", replace=True, params={{"b": Param(1.0, 0.0, 2.0)}})
        def joint(q, dq, p):
            return -p["b"] * dq
        '''))
    assert load_effect_file(str(path)) == [f"again_{tag}"]
    other = tmp_path / "other.py"
    other.write_text(textwrap.dedent(f'''\
        from granular_mpc.effects import Param, register_joint_effect

        @register_joint_effect("other_{tag}", params={{"b": Param(1.0, 0.0, 2.0)}})
        def joint(q, dq, p):
            return -p["b"] * dq
        '''))
    assert load_effect_file(str(other)) == [f"other_{tag}"]
    assert load_effect_file(str(path)) == [f"again_{tag}"]


def test_load_effect_file_missing(tmp_path):
    with pytest.raises(ConfigError, match="effect file not found"):
        load_effect_file(str(tmp_path / "nope.py"))


def test_old_import_paths_name_the_same_objects():
    """granular_mpc.terrain.effects / .effects_library / granular_mpc.terrain re-export
    every name they exported, as the very objects of granular_mpc.effects."""
    for module in (old_effects, old_library):
        assert module.__all__
        for name in module.__all__:
            assert getattr(module, name) is getattr(effects, name), (module.__name__, name)
    assert {"Param", "PatchState", "register_effect", "load_effect_file", "get_effect",
            "registered_effects", "resolve_params", "inertial_drag", "Effect"} <= set(
        old_effects.__all__)
    assert {"register_joint_effect", "register_sensor_effect", "register_geometry_effect",
            "describe_effect", "effect_info", "all_effects", "SensorContext",
            "apply_sensor_effects", "joint_torque_function", "geometry_theta",
            "GEOMETRY_THETA", "KINDS"} <= set(old_library.__all__)
    for name in ("Param", "PatchState", "register_effect", "get_effect", "registered_effects"):
        assert getattr(terrain_pkg, name) is getattr(effects, name)
