"""The effects library (granular_mpc.terrain.effects_library): taxonomy, the library's
forces on floats and compiled, the plant's joint-effect hook, sensor and geometry maps."""
from __future__ import annotations

import math
import uuid

import numpy as np
import pytest

from granular_mpc.config import SimConfig, load_terrain, terrain_from_dict
from granular_mpc.dynamics import Plant
from granular_mpc.exceptions import ConfigError
from granular_mpc.terrain import build_terrain
from granular_mpc.terrain.closed_form import FLOAT
from granular_mpc.terrain.effects import Param, PatchState, register_effect
from granular_mpc.terrain.effects_library import (
    SensorContext, all_effects, apply_sensor_effects, effect_info, effect_kind, geometry_theta,
    joint_torque_function, register_geometry_effect, register_joint_effect,
    register_sensor_effect)

from test_contact import DT, step_foot

LIBRARY = {"inertial_drag": "terrain_force", "cohesion": "terrain_force",
           "depth_hardening": "terrain_force", "elastic_unloading": "terrain_force",
           "joint_friction": "joint", "force_sensor_bias": "sensor", "terrain_slope": "geometry"}


def _state(**kw) -> PatchState:
    base = dict(depth=0.02, in_contact=1.0, p_c=(0.0, 0.0, -0.02), v_c=(0.0, 0.0, 0.1),
                a_c=(0.0, 0.0, 0.0), intrusion=(0.0, 0.0, 0.02), heading=(1.0, 0.0, 0.0),
                lateral=(0.0, 1.0, 0.0), f_terrain=(3.0, -1.0, 60.0), f_yield_z=60.0,
                area_h=2.0e-3, width=0.0315, density=1660.0, dt=5e-4, depth_max=0.025,
                t_stance=0.1)
    base.update(kw)
    return PatchState(**base)


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


def test_unknown_effect_gets_a_did_you_mean():
    with pytest.raises(ConfigError, match="did you mean 'cohesion'"):
        effect_info("cohesoin")
    with pytest.raises(ConfigError, match="has no parameter 'sucktion'; did you mean 'suction'"):
        effect_info("cohesion").resolve_params({"sucktion": 1.0})
    with pytest.raises(ConfigError, match="out of range"):
        effect_info("cohesion").resolve_params({"suction": -5.0})


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


def test_joint_effect_hook_adds_its_torque_in_the_plant(biped, sand):
    """Plant.forward with a joint effect differs from the plain plant by M⁻¹ S τ_f."""
    import pinocchio as pin

    info = effect_info("joint_friction")
    fn = joint_torque_function([(info, {"viscous": 0.5, "coulomb": 0.3, "smoothing": 0.2})])
    q = biped.standing_configuration(clearance=0.05)
    v = np.zeros(biped.model.nv)
    v[biped.idx_v] = [1.0, -2.0, 0.5, 0.0, 3.0, -1.0]
    accs = []
    for hook in ((), (fn,)):
        plant = Plant(biped, sand, SimConfig(), joint_effects=hook)
        d = plant.new_data(q, v)
        accs.append(plant.forward(d, d.q, d.v).copy())
    tau_f = np.zeros(biped.model.nv)
    dqa = v[biped.idx_v]
    tau_f[biped.idx_v] = -0.5 * dqa - 0.3 * np.tanh(dqa / 0.2)
    data = biped.create_data()
    M = pin.crba(biped.model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    np.testing.assert_allclose(accs[1] - accs[0], np.linalg.solve(M, tau_f), rtol=1e-8, atol=1e-9)
    assert Plant(biped, sand).joint_effects == ()             # off by default


def test_force_sensor_bias_shifts_stance_rows_only():
    info = effect_info("force_sensor_bias")
    stance = np.array(["left", "left", "none", "right"], dtype=object)
    cols = {f"grf_{a}": np.array([1.0, 2.0, 0.0, 3.0]) for a in "xyz"}
    ctx = SensorContext(stance, np.arange(4) * 0.002, ("a",))
    out = apply_sensor_effects(cols, [(info, {"bias_x": 1.0, "bias_y": 0.0, "bias_z": -2.0})], ctx)
    np.testing.assert_allclose(out["grf_x"], [2.0, 3.0, 0.0, 4.0])
    np.testing.assert_allclose(out["grf_z"], [-1.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(cols["grf_z"], [1.0, 2.0, 0.0, 3.0])        # input untouched


def test_terrain_slope_maps_to_the_surface_slope(robot_config):
    th = geometry_theta([(effect_info("terrain_slope"), {"slope_x": 0.02, "slope_y": -0.01})])
    assert th == {"surface_slope_x": 0.02, "surface_slope_y": -0.01}
    with pytest.raises(ConfigError, match="not a terrain geometry parameter"):
        register_geometry_effect(f"bad_{uuid.uuid4().hex[:6]}", params={})(lambda p: {"zeta": 1.0})
        geometry_theta([(effect_info(next(n for n in all_effects() if n.startswith("bad_"))), {})])
