"""Foot identity and depth in terrain-force effects (PatchState.foot, .depth, .depth_rate;
granular_mpc.effects.variants): a per-foot term written with the public plugin API acts on
its foot only, on floats and compiled alike; the reference (Pinocchio) plant and the
compiled plant agree with per-foot and layered terms on; a layered term changes the force
only below its layer."""
from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.config import SimConfig, load_terrain, terrain_from_dict
from granular_mpc.dynamics import Plant
from granular_mpc.dynamics.compiled import CompiledPlant
from granular_mpc.effects import Param, PatchState, effect_info, register_effect
from granular_mpc.effects.variants import (PER_FOOT_TAG, hard_layer, per_foot_variant,
                                           register_variants)
from granular_mpc.exceptions import ConfigError
from granular_mpc.terrain import build_terrain
from granular_mpc.terrain.closed_form import FLOAT

from test_contact import DT, set_kin

WORN = "test_worn_right_sole"
LEFT_DRAG = "test_left_track_sink_drag"
KP, KD = 150.0, 3.0


def worn_right_sole(o, s, p):
    """The right sole bears ``wear`` less of the terrain's force (a worn sole)."""
    k = -p["wear"] * s.is_right * s.in_contact
    return (k * s.f_terrain[0], k * s.f_terrain[1], k * s.f_terrain[2])


def left_track_sink_drag(o, s, p):
    """Extra vertical drag ∝ the sinking rate, in the left track only (written with if_else)."""
    left = o.if_else(s.foot < 0.5, 1.0, 0.0)
    return (0.0, 0.0, p["c"] * s.depth_rate * left * s.in_contact)


@pytest.fixture(scope="module", autouse=True)
def registered():
    """The user terms, through the public plugin API, and the variants module's effects."""
    register_effect(WORN, params={"wear": Param(0.3, 0.0, 0.9, "-", "lost share")},
                    replace=True)(worn_right_sole)
    register_effect(LEFT_DRAG, params={"c": Param(200.0, 0.0, 5000.0, "N·s/m", "drag")},
                    replace=True)(left_track_sink_drag)
    return register_variants()


def _terrain(robot_config, effects):
    data = dict(load_terrain("dry_sand").model_dump())
    data["effects"] = effects
    return build_terrain(terrain_from_dict(data), robot_config)


def _press_both(terrain, n_steps, v_z=-0.2, rise_after=None):
    """Both feet moved identically (level, sinking at ``v_z``; rising at |v_z| after step
    ``rise_after``); per step and foot the per-patch forces and depths."""
    data = terrain.new_data(DT)
    z, out = terrain.foot.radius, []
    for k in range(n_steps):
        v = v_z if rise_after is None or k < rise_after else -v_z
        z += v * DT
        for i in (0, 1):
            set_kin(data.feet[i], [0.0, 0.0, z], v=(0.0, 0.0, v))
            data.evaluate(i)
        out.append([(data.feet[i].force.copy(), data.feet[i].diag[:, 0].copy()) for i in (0, 1)])
        data.commit()
    return out


def _patch(force, depth, foot, v_z):
    """Float PatchState of one patch from the compiled law's outputs (level ground)."""
    return PatchState(depth=float(depth), in_contact=float(depth > 0.0), p_c=(0.0, 0.0, 0.0),
                      v_c=(0.0, 0.0, v_z), a_c=(0.0, 0.0, 0.0), intrusion=(0.0, 0.0, 0.0),
                      heading=(1.0, 0.0, 0.0), lateral=(0.0, 1.0, 0.0),
                      f_terrain=tuple(float(x) for x in force), f_yield_z=0.0, area_h=0.0,
                      width=0.0, density=0.0, dt=DT, foot=float(foot), depth_rate=-v_z)


def test_patch_state_foot_defaults_and_indicators():
    base = _patch((0.0, 0.0, 1.0), 0.01, 0, -0.1)
    assert base.is_left == 1.0 and base.is_right == 0.0
    right = _patch((0.0, 0.0, 1.0), 0.01, 1, -0.1)
    assert right.is_left == 0.0 and right.is_right == 1.0
    old_style = PatchState(depth=0.01, in_contact=1.0, p_c=(0, 0, 0), v_c=(0, 0, 0),
                           a_c=(0, 0, 0), intrusion=(0, 0, 0), heading=(1, 0, 0),
                           lateral=(0, 1, 0), f_terrain=(0, 0, 0), f_yield_z=0.0, area_h=0.0,
                           width=0.0, density=0.0, dt=DT)
    assert old_style.foot == 0.0 and old_style.depth_rate == 0.0   # effects written before


def test_per_foot_terms_change_only_their_foot_float_and_compiled_agree(robot_config, sand):
    """Same kinematics for both feet: the worn-right-sole term changes only the right
    foot's force, the left-track drag only the left's; each difference equals the term on
    floats (PatchState built from the compiled law's own outputs) to 1e-12."""
    wear, c, v_z = 0.35, 400.0, -0.2
    on = _terrain(robot_config, [f"{WORN}:wear={wear}", f"{LEFT_DRAG}:c={c}"])
    plain, with_terms = _press_both(sand, 120, v_z), _press_both(on, 120, v_z)
    checked = 0
    for (p_l, p_r), (t_l, t_r) in zip(plain, with_terms):
        for foot, (f0, depth), (f1, _) in ((0, p_l, t_l), (1, p_r, t_r)):
            for k in range(len(depth)):
                s = _patch(f0[k], depth[k], foot, v_z)
                expected = np.add(worn_right_sole(FLOAT, s, {"wear": wear}),
                                  left_track_sink_drag(FLOAT, s, {"c": c}))
                np.testing.assert_allclose(f1[k] - f0[k], expected, rtol=0, atol=1e-12)
                checked += depth[k] > 0.0
        if p_r[1].max() > 0.0:
            assert np.abs(t_r[0][:, 2] - p_r[0][:, 2]).max() > 1.0    # right foot changed…
            np.testing.assert_allclose(t_r[0][:, 0:2], p_r[0][:, 0:2], atol=1e-12)
            assert np.abs(t_l[0][:, 2] - p_l[0][:, 2]).max() > 1.0    # … and so did the left
    assert checked > 100                               # patches in contact were compared


def test_per_foot_variant_of_a_library_term(robot_config, sand):
    """per_foot_variant('cohesion', 'right'): the base's parameters, the per-foot tag, and
    on the compiled law, through a sink and a pull-out, the base's force on the right foot
    and the plain law's on the left."""
    name = per_foot_variant("cohesion", "right")
    assert name == "cohesion_right" and per_foot_variant("cohesion", "right") == name
    info = effect_info(name)
    assert set(info.params) == {"suction", "release"} and PER_FOOT_TAG in info.tags
    assert info.main == "suction" and "right foot only" in info.depends_on
    runs = [_press_both(t, 240, -0.2, rise_after=120) for t in
            (sand, _terrain(robot_config, ["cohesion:suction=8000"]),
             _terrain(robot_config, [f"{name}:suction=8000"]))]
    pulled = 0.0
    for plain, both, right in zip(*runs):
        np.testing.assert_allclose(right[1][0], both[1][0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(right[0][0], plain[0][0], rtol=0, atol=1e-12)
        pulled = max(pulled, np.abs(both[1][0] - plain[1][0]).max())
    assert pulled > 1.0                               # the suction acted on the right foot


def test_per_foot_variant_rejects_unknown_side_and_non_terrain_effect():
    with pytest.raises(ConfigError, match="foot side"):
        per_foot_variant("cohesion", "middle")
    with pytest.raises(ConfigError):
        per_foot_variant("joint_friction", "left")


def test_hard_layer_changes_the_force_only_below_the_layer(robot_config, sand):
    """ratio 3 below 10 mm: per patch the force equals the plain law's above the interface
    and f (1 + (r − 1)(d − d_L)/d) below it; the float form gives the same difference."""
    r, d_l, v_z = 3.0, 0.010, -0.2
    layered = _terrain(robot_config, [f"hard_layer:ratio={r},interface_depth={d_l}"])
    plain, with_layer = _press_both(sand, 200, v_z), _press_both(layered, 200, v_z)
    above = below = 0
    for (p_l, _), (t_l, _) in zip(plain, with_layer):
        f0, depth = p_l
        f1 = t_l[0]
        for k in range(len(depth)):
            s = _patch(f0[k], depth[k], 0, v_z)
            np.testing.assert_allclose(f1[k] - f0[k],
                                       hard_layer(FLOAT, s, {"ratio": r, "interface_depth": d_l}),
                                       rtol=0, atol=1e-12)
            if 0.0 < depth[k] <= d_l:
                np.testing.assert_array_equal(f1[k], f0[k])
                above += 1
            elif depth[k] > d_l:
                factor = 1.0 + (r - 1.0) * (depth[k] - d_l) / depth[k]
                np.testing.assert_allclose(f1[k], factor * f0[k], rtol=1e-12, atol=1e-12)
                below += 1
    assert above > 50 and below > 50
    deepest = with_layer[-1][0]
    assert deepest[1].max() > 0.018
    assert deepest[0][:, 2].sum() > 1.4 * plain[-1][0][0][:, 2].sum()


@pytest.fixture(scope="module")
def asymmetric_pair(biped, robot_config):
    """Sand with a worn right sole, a left-track drag and a hard layer at 4 mm: the
    reference plant and its compiled twin."""
    terrain = _terrain(robot_config, [f"{WORN}:wear=0.4", f"{LEFT_DRAG}:c=300",
                                      "hard_layer:ratio=4,interface_depth=0.004"])
    plant = Plant(biped, terrain, SimConfig())
    return plant, CompiledPlant(plant)


def test_reference_and_compiled_plant_agree_with_per_foot_and_layered_terms(asymmetric_pair,
                                                                          biped, sand):
    """Dropped 3 mm into the sand, joints held by PD: after 60 steps the compiled state
    equals the reference's to 1e-8; at the first evaluation only the right foot's force
    differs from plain sand by the wear term (both feet start above the layer, at rest)."""
    plant, fast = asymmetric_pair
    q = biped.standing_configuration(clearance=-0.003)
    q_hold = biped.actuated(q)
    plain = Plant(biped, sand, SimConfig())
    forces = []
    for p in (plain, plant):
        d0 = p.new_data(q)
        p.forward(d0, d0.q, d0.v)
        forces.append([d0.contact.feet[i].force.sum(axis=0).copy() for i in (0, 1)])
    np.testing.assert_allclose(forces[1][0], forces[0][0], atol=1e-12)
    np.testing.assert_allclose(forces[1][1], 0.6 * forces[0][1], rtol=1e-12, atol=1e-12)
    d = plant.new_data(q)
    s = fast.step(fast.state_from_data(d), n_steps=60, q_ref=q_hold, kp=KP, kd=KD)
    deepest = 0.0
    for _ in range(60):
        plant.step(d, KP * (q_hold - d.q[biped.idx_q]) - KD * d.v[biped.idx_v])
        deepest = max(deepest, d.foot_diag(0)[0], d.foot_diag(1)[0])
    ref = fast.state_from_data(d)
    tol = 1e-8
    np.testing.assert_allclose(s.q, ref.q, rtol=0, atol=tol)
    np.testing.assert_allclose(s.v, ref.v, rtol=tol, atol=tol * (1 + np.abs(ref.v).max()))
    np.testing.assert_allclose(s.x, ref.x, rtol=tol, atol=tol * (1 + np.abs(ref.x).max()))
    assert deepest > 0.004                                  # the layer was reached
    for i in (0, 1):
        np.testing.assert_allclose(s.foot_force(i), d.foot_force(i), rtol=1e-7, atol=1e-6)
