"""Terrain models as built by build_terrain (granular_mpc.terrain.base): the finite layer,
the medium's scale ζ, quasi-static sinkage, surface height, parameters, and guards.

A single level foot carrying a point load is integrated here (no Pinocchio), the same
harness as in test_contact.py.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from granular_mpc.config import SimConfig, load_robot, load_terrain, terrain_from_dict
from granular_mpc.dynamics import Plant
from granular_mpc.exceptions import ConfigError
from granular_mpc.terrain import build_terrain

from test_contact import DT, G, PointLoadedFoot, step_foot, support_ramp


def test_granular_parameters_are_runtime_inputs(sand):
    names = sand.param_names
    assert {"surface_height", "zeta", "phi_s", "layer_depth"} <= set(names)
    values = dict(zip(names, sand.param_values))
    assert values["zeta"] == sand.config.zeta
    assert values["phi_s"] == pytest.approx(math.radians(sand.config.phi_s_deg))
    assert values["layer_depth"] == sand.config.layer_depth
    data = sand.new_data(DT)
    data.set_param("zeta", 2.0)
    assert data.param("zeta") == 2.0
    assert sand.param_values[names.index("zeta")] == sand.config.zeta   # the model is unchanged


def _elastic(terrain, load):
    """Elastic deflection of the patch springs under ``load`` [m]."""
    return load / (terrain.contact.n_slices * terrain.config.contact_stiffness)


def test_quasi_static_placement_matches_closed_form(sand, biped):
    """Support ramped from M g to 0 over 3 s: the plastic part of the sinkage (depth minus
    the elastic deflection M g/(n K)) is within 1 % of quasi_static_depth(M g), the
    bisection on the closed form. (Measured: +0.6 %; the excess shrinks with the ramp
    rate — the foot's momentum at the end of the ramp — +3.2 % at 1.5 s, +0.06 % at 6 s.)"""
    M = biped.mass / 2.0
    foot = PointLoadedFoot(sand, M)
    foot.run(3.5, support_ramp(M, 3.0))
    d_qs = sand.quasi_static_depth(M * G)
    assert foot.depth - _elastic(sand, M * G) == pytest.approx(d_qs, rel=0.01)
    assert foot.depth > d_qs
    assert sand.vertical_capacity(foot.depth) >= M * G * (1 - 1e-9)


def test_larger_zeta_sinks_less(sand, biped):
    """Same load, ζ = 0.68, 1.36, 2.72: quasi-static sinkage strictly decreases, each
    within 2 % of the closed-form depth for that ζ (closed form scales linearly in ζ)."""
    M = biped.mass / 2.0
    depths = []
    for zeta in (0.68, 1.36, 2.72):
        foot = PointLoadedFoot(sand, M, params={"zeta": zeta})
        foot.run(3.5, support_ramp(M, 3.0))
        depths.append(foot.depth)
        # capacity ∝ ζ: the depth where (ζ/ζ₀)·cap₀(d) = M g
        target = M * G * sand.config.zeta / zeta
        plastic = foot.depth - _elastic(sand, M * G)
        assert plastic == pytest.approx(sand.quasi_static_depth(target), rel=0.02), zeta
    assert depths[0] > depths[1] > depths[2]


def test_finite_layer_floor_stops_the_foot(sand, biped):
    """A weak medium (ζ = 0.05) over a 15 mm layer cannot carry half the robot: the foot
    goes through and rests on the rigid floor, just below layer_depth (floor spring
    2K per patch), with the floor carrying what the sand does not."""
    M = biped.mass / 2.0
    layer = 0.015
    weak = {"zeta": 0.05, "layer_depth": layer}
    foot = PointLoadedFoot(sand, M, params=weak)
    foot.run(1.5, support_ramp(M, 0.5))
    sand_part = sand.vertical_capacity(layer) * 0.05 / sand.config.zeta
    assert sand_part < 0.5 * M * G
    n, K = sand.contact.n_slices, sand.config.contact_stiffness
    expected = layer + (M * G - sand_part) / (n * 2.0 * K)
    assert foot.depth == pytest.approx(expected, abs=2e-5)
    assert abs(foot.v[2]) < 1e-6
    # without the floor the same foot keeps going well past 15 mm
    deep = PointLoadedFoot(sand, M, params={"zeta": 0.05})
    deep.run(1.5, support_ramp(M, 0.5))
    assert deep.depth > 2 * layer
    # and the closed form refuses a load the layer cannot bear above its floor
    weak_cfg = load_terrain("dry_sand", zeta=0.05, layer_depth=layer)
    weak_terrain = build_terrain(weak_cfg, load_robot())
    with pytest.raises(ConfigError, match="cannot bear"):
        weak_terrain.quasi_static_depth(M * G)


def test_surface_height_shifts_the_ground(robot_config):
    """The same foot 10 mm into sand whose surface is at z = 0.3 m feels the same force
    as 10 mm into sand at z = 0."""
    ref = build_terrain(load_terrain("dry_sand"), robot_config)
    high = build_terrain(load_terrain("dry_sand", surface_height=0.3), robot_config)
    R = robot_config.foot.radius
    forces = []
    for terrain, z0 in ((ref, 0.0), (high, 0.3)):
        data = terrain.new_data(DT)
        for k in range(40):
            f, _ = step_foot(data, [0.0, 0.0, z0 + R - 0.00025 * k], v=(0.0, 0.0, -0.5))
        forces.append(f)
        assert data.feet[0].diag[:, 0].mean() == pytest.approx(0.00975, abs=1e-12)
    np.testing.assert_allclose(forces[0], forces[1], rtol=1e-9)


def test_foot_clear_of_the_surface_feels_nothing(sand, rigid):
    for terrain in (sand, rigid):
        data = terrain.new_data(DT)
        force, state = step_foot(data, [0.0, 0.0, terrain.foot.radius + 1e-4], v=(0.0, 0.0, -1.0))
        assert np.all(force == 0.0)
        assert np.all(state[:, 6] == 0.0)     # not in contact


def test_slices_add_up_to_the_whole_foot(sand):
    """The per-patch vertical capacities (diagnostic f_cap_z) of a level foot sum to the
    whole-foot closed form."""
    data = sand.new_data(DT)
    R = sand.foot.radius
    step_foot(data, [0.0, 0.0, R - 0.012], v=(0.0, 0.0, -0.1))
    caps = data.feet[0].diag[:, 1]
    assert len(caps) == sand.contact.n_slices == 2
    assert caps.sum() == pytest.approx(sand.vertical_capacity(0.012), rel=1e-12)


def test_terrain_from_dict_builds(robot_config):
    cfg = terrain_from_dict({"kind": "granular", "name": "custom", "zeta": 0.9, "phi_s_deg": 30})
    terrain = build_terrain(cfg, robot_config)
    assert terrain.kind == "granular" and terrain.name == "custom"
    assert terrain.casadi_theta[0] == 0.9


def test_plant_rejects_terrain_built_for_another_foot(biped):
    other = load_robot().model_copy(update={"foot": load_robot().foot.model_copy(update={"width": 0.08})})
    terrain = build_terrain(load_terrain("rigid"), other)
    with pytest.raises(ConfigError, match="another foot geometry"):
        Plant(biped, terrain, SimConfig())
