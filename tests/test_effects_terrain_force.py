"""The library's terrain forces (granular_mpc.effects.terrain_force) and terrain forces in
general: from config dicts and YAML strings into the contact function and the plant, the
library's formulas on floats and compiled, config errors for names and parameters."""
from __future__ import annotations

import math
import textwrap
import uuid

import numpy as np
import pinocchio as pin
import pytest

from granular_mpc.config import SimConfig, load_terrain, terrain_from_dict
from granular_mpc.dynamics import Plant
from granular_mpc.effects import Param, PatchState, effect_info, register_effect
from granular_mpc.exceptions import ConfigError
from granular_mpc.terrain import build_terrain
from granular_mpc.terrain.closed_form import FLOAT

from test_contact import DT, step_foot

PUSH = f"test_constant_push_{uuid.uuid4().hex[:8]}"


@register_effect(PUSH, params={"f0": Param(2.0, 0.0, 50.0, "N", "constant upward push")})
def _constant_push(o, s, p):
    """A constant upward push while the patch is in contact."""
    return (0.0, 0.0, p["f0"] * s.in_contact)


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


def _state(**kw) -> PatchState:
    base = dict(depth=0.02, in_contact=1.0, p_c=(0.0, 0.0, -0.02), v_c=(0.0, 0.0, 0.1),
                a_c=(0.0, 0.0, 0.0), intrusion=(0.0, 0.0, 0.02), heading=(1.0, 0.0, 0.0),
                lateral=(0.0, 1.0, 0.0), f_terrain=(3.0, -1.0, 60.0), f_yield_z=60.0,
                area_h=2.0e-3, width=0.0315, density=1660.0, dt=5e-4, depth_max=0.025,
                t_stance=0.1)
    base.update(kw)
    return PatchState(**base)


def test_cohesion_pulls_a_rising_sole_down():
    f = effect_info("cohesion").fn
    p = {"suction": 3000.0, "release": 0.003}
    # at the deepest point: no pull; 3 mm above it: 1 − e⁻¹ of the full suction
    assert f(FLOAT, _state(depth=0.025, depth_max=0.025), p) == (0.0, 0.0, 0.0) or \
        abs(f(FLOAT, _state(depth=0.025, depth_max=0.025), p)[2]) < 1e-12
    fz = f(FLOAT, _state(depth=0.022, depth_max=0.025), p)[2]
    assert fz == pytest.approx(-3000.0 * 2.0e-3 * (1.0 - math.exp(-1.0)), rel=1e-12)


def test_depth_hardening_scales_the_terrain_force_by_the_depth_power():
    f = effect_info("depth_hardening").fn
    s = _state(depth=0.04)
    extra = f(FLOAT, s, {"n": 1.5, "d_ref": 0.02})
    factor = (0.04 / 0.02) ** 0.5 - 1.0
    np.testing.assert_allclose(extra, np.array(s.f_terrain) * factor, rtol=1e-12)
    assert f(FLOAT, s, {"n": 1.0, "d_ref": 0.02}) == (0.0, 0.0, 0.0)     # neutral
    np.testing.assert_allclose(f(FLOAT, _state(depth=0.02), {"n": 2.0, "d_ref": 0.02}), 0.0)


def test_elastic_unloading_peaks_at_the_recovery_rise():
    f = effect_info("elastic_unloading").fn
    p = {"pressure": 4000.0, "recovery": 0.002}
    rises = np.linspace(0.0, 0.01, 201)
    fz = [f(FLOAT, _state(depth=0.025 - r, depth_max=0.025), p)[2] for r in rises]
    k = int(np.argmax(fz))
    assert rises[k] == pytest.approx(0.002, abs=1e-4)
    assert max(fz) == pytest.approx(4000.0 * 2.0e-3, rel=1e-3)
    assert fz[0] == 0.0


@pytest.mark.parametrize("name,params", [("cohesion", {"suction": 5000.0}),
                                         ("elastic_unloading", {"pressure": 8000.0}),
                                         ("depth_hardening", {"n": 2.0})])
def test_library_terrain_effects_compile_into_the_contact_function(robot_config, name, params):
    """Same kinematics (a foot pressed 10 mm into sand, then lifted 2 mm): the compiled
    effect changes the force as its float formula says (cohesion / unloading: only while
    rising; hardening: while pressed)."""
    data = dict(load_terrain("dry_sand").model_dump())
    with_eff = build_terrain(terrain_from_dict({**data, "effects": [{"name": name,
                                                                     "params": params}]}),
                             robot_config)
    plain = build_terrain(load_terrain("dry_sand"), robot_config)
    R = robot_config.foot.radius
    out = []
    for terrain in (plain, with_eff):
        d = terrain.new_data(DT)
        for k in range(25):                      # press to 10 mm
            f_down, _ = step_foot(d, [0.0, 0.0, R - 0.0004 * k], v=(0.0, 0.0, -0.8))
        for k in range(10):                      # rise 2 mm
            f_up, _ = step_foot(d, [0.0, 0.0, R - 0.0096 + 0.0002 * k], v=(0.0, 0.0, 0.4))
        out.append((f_down, f_up))
    (d0, u0), (d1, u1) = out
    if name == "depth_hardening":
        assert d1[2] < d0[2]                     # 10 mm < d_ref = 20 mm: softer (n = 2)
    else:
        np.testing.assert_allclose(d1, d0, atol=1e-6)        # no effect while penetrating
        assert (u1[2] - u0[2]) * (1 if name == "elastic_unloading" else -1) > 0.5
