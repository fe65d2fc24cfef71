"""The walking controller: granular awareness derived from the ground model, and short
closed loops on both terrains (the 20 s matrix lives in bench/controller_matrix.py).

The closed loops run on ProxSuite's generic build (GRANULAR_MPC_PROXSUITE=generic), which is
bit-reproducible: every machine tests the same realisation. The build is fixed at the first
import of ``proxsuite`` in the process, not per solver, so the variable is set when this
module is collected (before any test runs) and the fixture below checks it took effect.
Thresholds on closed-loop figures state the measured value on that build (the native AVX2
build gave the same figures to 1e-3 relative on the two walks) and what they are set from.
"""

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import pytest

from granular_mpc.config import CommandConfig, ControllerConfig, SimConfig
from granular_mpc.control.controller import ControllerData, WalkingController
from granular_mpc.control.solvers.proxqp import proxsuite_build
from granular_mpc.dynamics import Plant
from granular_mpc.dynamics.plant import PlantData
from granular_mpc.robot.kinematics import balanced_stance
from granular_mpc.terrain.closed_form import FLOAT
from granular_mpc.terrain.contact import slice_geometry

#: name of ProxSuite's generic (SSE2, deterministic) binding module
GENERIC_BINDING = "proxsuite_pywrap"


@pytest.fixture(autouse=True, scope="module")
def reproducible_proxsuite():
    assert proxsuite_build() == GENERIC_BINDING, (
        "closed-loop tests need ProxSuite's generic build: proxsuite was imported with "
        f"another build ({proxsuite_build()}); tests/conftest.py sets "
        "GRANULAR_MPC_PROXSUITE=generic before anything imports it")


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


@dataclass(frozen=True)
class Walk:
    """Outcome of one short closed loop."""

    plant: PlantData            # final plant state
    ctrl: ControllerData        # final controller state (records, failures)
    worst_tilt_deg: float       # largest |roll| or |pitch| of the trunk [deg]
    double_support_s: float     # time with both feet in contact after t = 0.6 s [s]
    max_depth: float            # deepest mean patch depth of either foot [m]
    x_at_2s: float              # trunk x at t = 2 s [m] (mean speed over the last second)


def walk(biped, terrain, speed, seconds, ctrl_terrain=None) -> Walk:
    plant = Plant(biped, terrain, SimConfig(dt=5e-4))
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(speed=speed), biped,
                                   ctrl_terrain or terrain)
    q0 = balanced_stance(biped, clearance=0.0 if terrain.kind == "rigid" else -0.005)
    d, cd = plant.new_data(q0), ctrl.new_data(q0)
    worst, both, depth, x2 = 0.0, 0, 0.0, math.nan
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
        if k + 1 == int(round(2.0 / plant.dt)):
            x2 = float(d.q[0])
    return Walk(d, cd, math.degrees(worst), both * plant.dt, depth, x2)


@pytest.mark.parametrize("terrain_name", ["rigid", "sand"])
def test_short_walk_stays_upright_and_advances(biped, sand, rigid, terrain_name):
    """3 s at 0.3 m/s commanded (ramp from 0.8 s, 0.5 m/s², 2 m/s³: at 0.3 m/s from 1.65 s)."""
    terrain = {"rigid": rigid, "sand": sand}[terrain_name]
    w = walk(biped, terrain, 0.3, 3.0)
    d, cd = w.plant, w.ctrl
    # upright: measured 0.91° (rigid), 0.43° (sand); 5° is 5× that and 5× below the 25.6°
    # of the fall in test_rigid_assumption_controller_on_sand_uses_rigid_limits
    assert w.worst_tilt_deg < 5.0
    # standing trunk height 0.46 m; measured 0.462 / 0.438 at the end; a fall ends < 0.03 m
    assert d.q[2] > 0.3
    # advances: the command covers 0.53 m by 3 s; measured 0.334 m (rigid), 0.272 m (sand).
    # Bound 0.2 m (≈ 40 % of the command): a robot stepping in place or walking backwards
    # fails it, the ramp's lag (the DCM feedback converges over ~1 s) does not.
    assert d.q[0] > 0.2
    # speed near the command over the last second (the ramp has ended): measured 0.243 m/s
    # (rigid), 0.230 m/s (sand) against 0.3; band 0.15–0.45 (± 50 %) excludes stepping in
    # place and running away, and holds the sand's slower, sinking gait
    mean_speed = d.q[0] - w.x_at_2s
    assert 0.15 < mean_speed < 0.45, mean_speed
    # no QP failure: measured 0 on both grounds (both builds); every tick is a fresh QP on
    # feasible data, so a failure is a regression (the fallback has its own MPC test)
    assert cd.qp_failures == 0
    if terrain_name == "sand":
        # the feet really sink: plastic flow stops only where the capacity carries the
        # load, so single support reaches at least the quasi-static depth of the full
        # weight (23.4 mm); measured 40.4 mm (dynamic loads exceed the weight)
        assert w.max_depth > sand.quasi_static_depth(biped.weight)
        # the planned load transfer happens: 12 touchdowns in 0.6–3.0 s (period 0.4 s) ×
        # load_transfer (39 ms on this sand) = 0.47 s planned; measured 1.03 s (a foot
        # leaving sand stays in contact while it rises out of its hole)
        planned = 12 * cd_gait(biped, sand).load_transfer
        assert w.double_support_s > planned
    else:
        # only transient penetration: static single support sinks W/K = 1.0 mm into the
        # 1e5 N/m contact spring; bound 3 × that for touchdown impacts; measured 0.63 mm
        assert w.max_depth < 3.0 * biped.weight / rigid.config.contact_stiffness
        # swing_fraction 0.5 plans no double support: measured 0.049 s of touchdown jitter
        assert w.double_support_s < 0.1
    mpc = [r for r in cd.records if r.kind == "mpc"]
    # 40 Hz after the 0.5 s weight shift: 3.0·40 − 20 = 100 planned; measured 97
    assert len(mpc) == pytest.approx(3.0 * 40 - 20, abs=5)


def cd_gait(biped, terrain):
    """The gait the controller derives for ``terrain`` (defaults, 0.3 m/s)."""
    return WalkingController.build(ControllerConfig(), CommandConfig(speed=0.3), biped,
                                   terrain).config.gait


def test_rigid_assumption_controller_on_sand_uses_rigid_limits(biped, sand, rigid):
    """A controller that believes the ground is rigid, walking on sand, falls — the sand
    model matters. (The sand-aware controller walks the same sand upright above.)"""
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(), biped, rigid)
    assert not ctrl.ground.granular
    assert ctrl.config.gait.load_transfer == 0.0
    w = walk(biped, sand, 0.2, 4.0, ctrl_terrain=rigid)
    # the plant is sand whatever the controller believes: measured 110 mm (the feet plough)
    assert w.max_depth > sand.quasi_static_depth(biped.weight)
    # the outcome: it falls (at ≈ 3.1 s since the touchdown hand-over fix; ≈ 1.7 s before
    # it). Measured (generic build, 4 s) tilt 180°, trunk −0.51 m. Bounds: tilt > 15° and
    # trunk < 0.3 m (the "upright" limit above). (With ProxSuite as the WBC's solver, the
    # default before session 20, 53 QPs also failed on the way down; DAQP's active set
    # solves them: the fall is the outcome, not the failed QPs.)
    assert w.worst_tilt_deg > 15.0
    assert w.plant.q[2] < 0.3


def test_foot_points_are_the_lowest_points_of_the_sole_slices(biped, sand):
    """The controller's vectorised contact points equal the plant's slice geometry
    (:func:`~granular_mpc.terrain.contact.slice_geometry`, float evaluation) bit for bit,
    over random configurations including soles pitched beyond the arc's half-angle."""
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(), biped, sand)
    foot = biped.config.foot
    rng = np.random.default_rng(3)
    pd = biped.create_data()
    for trial in range(40):
        q = balanced_stance(biped)
        quat = np.array([*rng.normal(0.0, 0.3, 3), 1.0])
        q[3:7] = quat / np.linalg.norm(quat)
        q[7:] += rng.normal(0.0, 0.4 if trial % 2 else 1.5, biped.model.nq - 7)
        pin.framesForwardKinematics(biped.model, pd, q)
        feet = ctrl.foot_points(pd)
        for i, side in enumerate(("left", "right")):
            oMf = pd.oMf[biped.foot_frame[side]]
            kin = list(oMf.translation) + list(oMf.rotation.ravel("F")) + [0.0] * 6
            ref = np.array([slice_geometry(FLOAT, kin, float(y), foot.radius,
                                           foot.half_angle, 0.0).p_c
                            for y in biped.slice_offsets])
            np.testing.assert_array_equal(feet[i].points, ref)
            np.testing.assert_array_equal(feet[i].offsets, ref - oMf.translation)
        # the tick's form: the same points, and each foot's mean point as floats (numpy's
        # mean: the same numbers)
        (left, right), means = ctrl.sole_contacts(pd)
        for fp, ref_fp, mean in zip((left, right), feet, means):
            np.testing.assert_array_equal(fp.points, ref_fp.points)
            np.testing.assert_array_equal(fp.offsets, ref_fp.offsets)
            assert list(mean) == ref_fp.points.mean(axis=0).tolist()
    # another Pinocchio data (the controller keeps views of the last one's placements):
    # its own placements are read, and the first data's again after it
    pd2 = biped.create_data()
    pin.framesForwardKinematics(biped.model, pd2, balanced_stance(biped))
    for data in (pd2, pd):
        oMf = data.oMf[biped.foot_frame["left"]]
        np.testing.assert_allclose(ctrl.foot_points(data)[0].offsets + oMf.translation,
                                   ctrl.foot_points(data)[0].points, rtol=0, atol=1e-15)
    assert not np.array_equal(ctrl.foot_points(pd2)[0].points, ctrl.foot_points(pd)[0].points)


def test_command_velocity_is_the_ticks_reference_or_the_ramps(biped, sand):
    """The loop's ``cmd_vx, cmd_vy`` come from the tick at the same time (no second ramp
    evaluation) and equal the ramp's reference there; at any other time, the ramp's."""
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(speed=0.3, start_delay=0.1),
                                   biped, sand)
    q0 = balanced_stance(biped, clearance=-0.005)
    plant = Plant(biped, sand, SimConfig(dt=5e-4))
    d, cd = plant.new_data(q0), ctrl.new_data(q0)
    t = 0.4                                  # inside the ramp: a non-zero, changing reference
    ctrl.compute(cd, t, d.q, d.v)
    v_tick = cd.command_velocity(t)
    assert v_tick is cd.last_v_ref
    np.testing.assert_array_equal(v_tick, cd.ramp.reference(t)[1])
    assert v_tick[0] > 0.0
    later = cd.command_velocity(t + 0.1)
    np.testing.assert_array_equal(later, cd.ramp.reference(t + 0.1)[1])
    assert later[0] > v_tick[0]
