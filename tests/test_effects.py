"""Optional physical effects (granular_mpc.terrain.effects): registry, plugin files,
config paths, and their forces in the contact function and the plant."""
from __future__ import annotations

import math
import textwrap
import uuid

import numpy as np
import pinocchio as pin
import pytest

from granular_mpc.config import SimConfig, load_terrain, terrain_from_dict
from granular_mpc.dynamics import Plant
from granular_mpc.exceptions import ConfigError
from granular_mpc.terrain import build_terrain
from granular_mpc.terrain.effects import (Param, get_effect, load_effect_file, register_effect,
                                          registered_effects)

from test_contact import DT, step_foot

PUSH = f"test_constant_push_{uuid.uuid4().hex[:8]}"


@register_effect(PUSH, params={"f0": Param(2.0, 0.0, 50.0, "N", "constant upward push")})
def _constant_push(o, s, p):
    """A constant upward push while the patch is in contact."""
    return (0.0, 0.0, p["f0"] * s.in_contact)


def test_registered_effect_is_listed():
    eff = get_effect(PUSH)
    assert eff.name == PUSH and "f0" in eff.params
    assert PUSH in registered_effects()
    assert eff.doc.startswith("A constant upward push")


def test_duplicate_registration_is_refused():
    with pytest.raises(ConfigError, match="already registered"):
        register_effect(PUSH)(_constant_push)


def _terrain_with(robot_config, effects, base="dry_sand"):
    data = dict(load_terrain(base).model_dump())
    data["effects"] = effects
    return build_terrain(terrain_from_dict(data), robot_config)


def test_user_effect_from_dict_adds_its_force_per_patch(robot_config, sand):
    """Same kinematics with and without the effect: every patch in contact gets +f0 in z."""
    pushed = _terrain_with(robot_config, [{"name": PUSH, "params": {"f0": 7.5}}])
    assert f"{PUSH}.f0" in pushed.param_names
    R = robot_config.foot.radius
    forces = []
    for terrain in (sand, pushed):
        data = terrain.new_data(DT)
        for k in range(30):
            f, _ = step_foot(data, [0.0, 0.0, R - 0.0004 * k], v=(0.0, 0.0, -0.8))
        forces.append(f)
    n = robot_config.foot.slices
    np.testing.assert_allclose(forces[1] - forces[0], [0.0, 0.0, n * 7.5], atol=1e-9)


def test_effect_from_yaml_string_form(tmp_path, robot_config):
    path = tmp_path / "pushy_sand.yaml"
    path.write_text(textwrap.dedent(f"""\
        kind: granular
        name: pushy_sand
        zeta: 1.36
        effects: ["{PUSH}:f0=3", "inertial_drag"]
        """))
    cfg = load_terrain(str(path))
    assert [e.name for e in cfg.effects] == [PUSH, "inertial_drag"]
    terrain = build_terrain(cfg, robot_config)
    values = dict(zip(terrain.param_names, terrain.param_values))
    assert values[f"{PUSH}.f0"] == 3.0
    assert values["inertial_drag.c_d"] == 1.0            # the default


def test_effect_force_appears_in_the_plant(biped, robot_config):
    """Feet 5 mm into sand at rest: the plant's foot forces differ by n·f0 per foot, and
    its acceleration differs by M⁻¹ Σ Jᵀ Δf computed independently with Pinocchio."""
    plain = _terrain_with(robot_config, [])
    pushed = _terrain_with(robot_config, [{"name": PUSH, "params": {"f0": 10.0}}])
    q = biped.standing_configuration(clearance=-0.005)
    results = []
    for terrain in (plain, pushed):
        plant = Plant(biped, terrain, SimConfig())
        d = plant.new_data(q)
        a = plant.forward(d, d.q, d.v)
        results.append((a.copy(), [d.contact.feet[i].force.copy() for i in range(2)],
                        [d.contact.feet[i].point.copy() for i in range(2)]))
    (a0, f0, pts), (a1, f1, _) = results
    n = robot_config.foot.slices
    model, data = biped.model, biped.create_data()
    pin.computeJointJacobians(model, data, q)
    gen = np.zeros(model.nv)
    for i, side in enumerate(("left", "right")):
        np.testing.assert_allclose(f1[i].sum(axis=0) - f0[i].sum(axis=0), [0, 0, n * 10.0], atol=1e-9)
        J = pin.getJointJacobian(model, data, biped.foot_joint[side], pin.ReferenceFrame.WORLD)
        for k in range(n):
            J_p = J[0:3] - pin.skew(pts[i][k]) @ J[3:6]      # linear Jacobian of the patch point
            gen += J_p.T @ (f1[i][k] - f0[i][k])
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    np.testing.assert_allclose(a1 - a0, np.linalg.solve(M, gen), rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("depth", [0.005, 0.015])
def test_inertial_drag_is_half_cd_rho_area_v_squared(robot_config, sand, depth):
    """F = ½ c_d ρ A_h v² against the motion. A_h, the horizontal extent of the submerged
    intruder times the width, by hand: while the surface cuts the wedge faces
    (d < R(1 − cos φ)) the half-extent is d_apex / tan φ with d_apex = d + R/cos φ − R;
    once it cuts the arc, √(2Rd − d²)."""
    c_d, v = 1.7, 0.6
    drag = _terrain_with(robot_config, [{"name": "inertial_drag", "params": {"c_d": c_d}}])
    R, W = robot_config.foot.radius, robot_config.foot.width
    phi = math.radians(sand.config.phi_s_deg)
    if depth < R * (1 - math.cos(phi)):
        half = (depth + R / math.cos(phi) - R) / math.tan(phi)
    else:
        half = math.sqrt(2 * R * depth - depth ** 2)
    expected = 0.5 * c_d * sand.config.density * (2 * half * W) * v ** 2
    diffs = []
    for terrain in (sand, drag):
        data = terrain.new_data(DT)
        f, _ = step_foot(data, [0.0, 0.0, R - depth], v=(0.0, 0.0, -v))
        diffs.append(f)
    np.testing.assert_allclose(diffs[1] - diffs[0], [0.0, 0.0, expected], rtol=1e-6, atol=1e-9)


def test_unknown_effect_gets_did_you_mean(robot_config):
    cfg = terrain_from_dict({"kind": "granular", "effects": [{"name": "inertial_drg"}]})
    with pytest.raises(ConfigError, match="did you mean 'inertial_drag'") as err:
        build_terrain(cfg, robot_config)
    assert err.value.key == "effects"
    assert "inertial_drag" in err.value.allowed


def test_unknown_effect_parameter_gets_did_you_mean(robot_config):
    cfg = terrain_from_dict({"kind": "granular", "effects": ["inertial_drag:cd=1.0"]})
    with pytest.raises(ConfigError, match="did you mean 'c_d'") as err:
        build_terrain(cfg, robot_config)
    assert err.value.key == "effects.inertial_drag.cd"


def test_out_of_range_effect_parameter(robot_config):
    cfg = terrain_from_dict({"kind": "granular", "effects": [{"name": "inertial_drag", "params": {"c_d": 50}}]})
    with pytest.raises(ConfigError, match="out of range") as err:
        build_terrain(cfg, robot_config)
    assert err.value.key == "effects.inertial_drag.c_d"
    assert err.value.value == 50.0
    assert "20.0" in err.value.allowed


def test_malformed_effect_string():
    with pytest.raises(ConfigError, match="must be a number"):
        terrain_from_dict({"kind": "granular", "effects": ["inertial_drag:c_d=fast"]})
    with pytest.raises(ConfigError, match="name=value"):
        terrain_from_dict({"kind": "granular", "effects": ["inertial_drag:c_d"]})


def test_load_effect_file(tmp_path, robot_config):
    name = f"user_sole_adhesion_{uuid.uuid4().hex[:8]}"
    path = tmp_path / "my_effects.py"
    path.write_text(textwrap.dedent(f'''\
        from granular_mpc.terrain.effects import Param, register_effect

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


def test_load_effect_file_missing(tmp_path):
    with pytest.raises(ConfigError, match="effect file not found"):
        load_effect_file(str(tmp_path / "nope.py"))
