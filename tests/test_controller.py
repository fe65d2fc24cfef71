"""The walking controller: granular awareness derived from the ground model, and short
closed loops on both terrains (the 20 s matrix lives in bench/controller_matrix.py)."""

import math

import pinocchio as pin
import pytest

from granular_mpc.config import CommandConfig, ControllerConfig, SimConfig
from granular_mpc.control.controller import WalkingController
from granular_mpc.dynamics import Plant
from granular_mpc.robot.kinematics import balanced_stance


def test_sand_controller_derives_its_gait_from_the_ground(biped, sand, rigid):
    cfg = ControllerConfig()
    c_sand = WalkingController.build(cfg, CommandConfig(), biped, sand)
    c_rigid = WalkingController.build(cfg, CommandConfig(), biped, rigid)
    # load transfer: time to sink to the depth bearing the weight at the allowed rate
    z_w = sand.quasi_static_depth(biped.weight)
    lt = c_sand.config.gait.load_transfer
    assert lt == pytest.approx(z_w / cfg.mpc.max_sink_rate, rel=0.02)
    assert c_sand.config.gait.swing_fraction == pytest.approx(0.5 - lt / 0.4, rel=1e-6)
    assert c_rigid.config.gait.swing_fraction == 0.5 and c_rigid.config.gait.load_transfer == 0.0
    # a wide nominal stance is narrowed so the LIP's lateral force fits the sand's
    # lateral capacity (rigid ground keeps it)
    wide = cfg.model_copy(update={"foothold": cfg.foothold.model_copy(update={"step_width": 0.19})})
    w_sand = WalkingController.build(wide, CommandConfig(), biped, sand).step_width
    w_rigid = WalkingController.build(wide, CommandConfig(), biped, rigid).step_width
    assert w_sand < w_rigid == 0.19
    assert w_sand == pytest.approx(
        2 * cfg.foothold.lateral_margin * c_sand.ground.lateral_ratio * cfg.mpc.com_height)
    # the QP size follows the gait: double support adds (step, foot) blocks on sand
    assert c_sand.mpc.max_pairs > c_rigid.mpc.max_pairs == cfg.mpc.horizon


def walk(biped, terrain, speed, seconds, ctrl_terrain=None):
    plant = Plant(biped, terrain, SimConfig(dt=5e-4))
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(speed=speed), biped,
                                   ctrl_terrain or terrain)
    q0 = balanced_stance(biped, clearance=0.0 if terrain.kind == "rigid" else -0.005)
    d, cd = plant.new_data(q0), ctrl.new_data(q0)
    worst, both, depth = 0.0, 0, 0.0
    tau = None
    for k in range(int(seconds / plant.dt)):
        if k % 4 == 0:
            tau = ctrl.compute(cd, d.t, d.q, d.v)
        plant.step(d, tau)
        R = pin.Quaternion(d.q[6], d.q[3], d.q[4], d.q[5]).matrix()
        rpy = pin.rpy.matrixToRpy(R)
        worst = max(worst, abs(rpy[0]), abs(rpy[1]))
        both += d.foot_in_contact(0) and d.foot_in_contact(1) and d.t > 0.6
        depth = max(depth, d.foot_diag(0)[0], d.foot_diag(1)[0])
    return d, cd, math.degrees(worst), both * plant.dt, depth


@pytest.mark.parametrize("terrain_name", ["rigid", "sand"])
def test_short_walk_stays_upright_and_advances(biped, sand, rigid, terrain_name):
    terrain = {"rigid": rigid, "sand": sand}[terrain_name]
    d, cd, worst_deg, double_support_s, depth = walk(biped, terrain, 0.3, 3.0)
    assert worst_deg < 10.0
    assert d.q[2] > 0.3
    assert d.q[0] > 0.25                    # ramp starts at 0.8 s: ≥ ~0.3 m/s·1.5 s worth
    assert cd.qp_failures <= 5
    if terrain_name == "sand":
        assert depth > 0.015                # the feet really sink
        assert double_support_s > 0.1       # the planned load transfer happens
    else:
        assert depth < 3e-3                 # only transient penetration at touchdown impacts
    mpc = [r for r in cd.records if r.kind == "mpc"]
    assert len(mpc) == pytest.approx(3.0 * 40 - 20, abs=5)   # 40 Hz after the weight shift


def test_rigid_assumption_controller_on_sand_uses_rigid_limits(biped, sand, rigid):
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(), biped, rigid)
    assert not ctrl.ground.granular
    assert ctrl.config.gait.load_transfer == 0.0
    d, cd, worst, _, depth = walk(biped, sand, 0.2, 2.0, ctrl_terrain=rigid)
    assert depth > 0.01                     # the plant is sand whatever the controller believes
