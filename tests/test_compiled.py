"""The compiled plant step (granular_mpc.dynamics.compiled, rigid_body_sx, step_sx) against
the reference Pinocchio plant: rigid-body pieces, one step, N steps, both terrains, feet
in contact and sinking, the PD law in the loop, joint effects, the trunk wrench, divergence."""
from __future__ import annotations

import casadi
import numpy as np
import pinocchio as pin
import pytest

from granular_mpc.config import EffectSpec, SimConfig, load_terrain
from granular_mpc.dynamics import Plant
from granular_mpc.dynamics import rigid_body_sx as rb
from granular_mpc.dynamics.compiled import STEP_COUNTS, CompiledPlant
from granular_mpc.dynamics.step_sx import AUX_SLICES
from granular_mpc.exceptions import ConfigError, PlantDivergedError
from granular_mpc.terrain import build_terrain

KP, KD = 150.0, 3.0


@pytest.fixture(scope="module")
def sand_pair(biped, sand):
    plant = Plant(biped, sand, SimConfig())
    return plant, CompiledPlant(plant)


@pytest.fixture(scope="module")
def rigid_pair(biped, rigid):
    plant = Plant(biped, rigid, SimConfig())
    return plant, CompiledPlant(plant)


def _friction(q_a, dq_a):
    """A traceable joint effect (numpy ufuncs work on CasADi symbols too)."""
    return -0.05 * dq_a - 0.2 * np.tanh(dq_a / 0.2)


@pytest.fixture(scope="module")
def euler_pair(biped, robot_config):
    """Sand with two terrain effects (one from the terrain file's list, one extra), the
    semi-implicit Euler integrator and a joint effect: one compiled model for all three."""
    config = load_terrain("dry_sand").model_copy(
        update={"effects": [EffectSpec(name="cohesion", params={"suction": 2500.0})]})
    terrain = build_terrain(config, robot_config,
                            extra_effects=[EffectSpec(name="inertial_drag", params={"c_d": 3.0})])
    plant = Plant(biped, terrain, SimConfig(integrator="semi_implicit_euler"),
                  joint_effects=(_friction,))
    return plant, CompiledPlant(plant)


def _contact_state(plant, rng, *, depth_mm=(-2.0, 12.0), settle_steps=4, v_sigma=0.2,
                   v_down=0.3, tilt=0.03):
    """Reference data with both feet pressed into the ground and moving (sinking).

    Standing pose with random joint offsets, the lowest sole point ``depth`` below the
    surface, random velocities biased downward; a few reference steps with a random
    PD-held torque then give the patches a touchdown point and an elastic displacement.
    """
    biped = plant.biped
    q_a = biped.actuated(biped.standing_configuration()) + rng.normal(0.0, 5 * tilt / 3, 6)
    q = biped.standing_configuration(0.0, q_a=q_a)
    quat = pin.Quaternion(pin.exp3(rng.normal(0.0, tilt, 3)))
    q[3:7] = [quat.x, quat.y, quat.z, quat.w]
    # the higher of the two soles' lowest points `depth` below the surface
    surface = plant.terrain.surface_height
    q[2] -= biped.lowest_sole_point(q).max() - surface + rng.uniform(*depth_mm) * 1e-3
    v = rng.normal(0.0, v_sigma, biped.model.nv)
    v[2] -= rng.uniform(0.0, v_down)
    d = plant.new_data(q, v)
    q_hold = q_a + rng.normal(0.0, 0.02, 6)
    for _ in range(settle_steps):
        plant.step(d, KP * (q_hold - d.q[biped.idx_q]) - KD * d.v[biped.idx_v])
    return d, q_hold


def _assert_same(fast, state, d, tol=1e-9):
    L = fast.layout
    ref = fast.state_from_data(d)
    np.testing.assert_allclose(state.q, ref.q, rtol=0, atol=tol)
    np.testing.assert_allclose(state.v, ref.v, rtol=tol, atol=tol * (1 + np.abs(ref.v).max()))
    np.testing.assert_allclose(state.a, ref.a, rtol=tol, atol=tol * (1 + np.abs(ref.a).max()))
    np.testing.assert_allclose(state.x[L.contact], ref.x[L.contact], rtol=tol,
                               atol=tol * (1 + np.abs(ref.x[L.contact]).max()))
    assert state.t == pytest.approx(d.t) and state.steps == d.steps


# ------------------------------------------------------------------ rigid-body pieces
def test_symbolic_aba_minv_kinematics_integrate_match_pinocchio(biped):
    """ABA with external forces, M⁻¹τ, foot placement/velocity (LOCAL_WORLD_ALIGNED) and
    integrate written in SX equal Pinocchio's at 20 random states."""
    ca = casadi
    model, data = biped.model, biped.create_data()
    tree = rb.tree_from_model(model)
    q, v = ca.SX.sym("q", model.nq), ca.SX.sym("v", model.nv)
    tau, fx = ca.SX.sym("tau", model.nv), ca.SX.sym("f", 6 * len(tree))
    pl = rb.placements(tree, q)
    fext = [fx[6 * i:6 * i + 6] for i in range(len(tree))]
    acc = ca.Function("aba", [q, v, tau, fx],
                      [rb.aba(tree, pl, model.nv, tau, v=v, fext=fext,
                              gravity=np.array(model.gravity.linear))])
    minv = ca.Function("minv", [q, tau], [rb.aba(tree, pl, model.nv, tau)])
    dv = ca.SX.sym("dv", model.nv)
    integ = ca.Function("integrate", [q, dv], [rb.integrate(tree, q, dv)])
    fid, jid = biped.foot_frame["right"], biped.foot_joint["right"]
    P = model.frames[fid].placement
    fk = ca.Function("fk", [q, v], list(rb.frame_kinematics(
        pl, rb.velocities(tree, pl, v), jid, P.rotation, P.translation)))
    rng = np.random.default_rng(12)
    lo, hi = biped.position_limits
    for k in range(20):
        quat = rng.normal(size=4)
        qn = biped.q_from_parts(rng.uniform(-1, 1, 3), quat / np.linalg.norm(quat),
                                rng.uniform(lo, hi))
        vn, tn, fn = (rng.normal(0, 1, model.nv), rng.normal(0, 5, model.nv),
                      rng.normal(0, 5, 6 * len(tree)))
        forces = pin.StdVec_Force()
        forces.append(pin.Force.Zero())
        for i in range(len(tree)):
            forces.append(pin.Force(fn[6 * i:6 * i + 6]))
        a_ref = pin.aba(model, data, qn, vn, tn, forces)
        np.testing.assert_allclose(np.array(acc(qn, vn, tn, fn)).ravel(), a_ref,
                                   rtol=1e-11, atol=1e-11 * np.abs(a_ref).max())
        M_inv = pin.computeMinverse(model, data, qn)
        M_inv = np.triu(M_inv) + np.triu(M_inv, 1).T
        np.testing.assert_allclose(np.array(minv(qn, tn)).ravel(), M_inv @ tn,
                                   rtol=1e-10, atol=1e-10 * np.abs(M_inv @ tn).max())
        step = rng.normal(0, 1, model.nv) * (1e-6 if k % 2 else 0.3)  # both exp6 branches
        np.testing.assert_allclose(np.array(integ(qn, step)).ravel(),
                                   pin.integrate(model, qn, step), atol=1e-14)
        pin.forwardKinematics(model, data, qn, vn)
        oMf = pin.updateFramePlacement(model, data, fid)
        vel = pin.getFrameVelocity(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        p, R, lin, ang = (np.array(e) for e in fk(qn, vn))
        np.testing.assert_allclose(p.ravel(), oMf.translation, atol=1e-14)
        np.testing.assert_allclose(R, oMf.rotation, atol=1e-14)
        np.testing.assert_allclose(lin.ravel(), vel.linear, atol=1e-13)
        np.testing.assert_allclose(ang.ravel(), vel.angular, atol=1e-13)


# ------------------------------------------------------------------ the whole step
@pytest.mark.parametrize("pair", ["sand_pair", "rigid_pair"])
def test_single_step_matches_reference_in_contact(pair, request):
    """One compiled step equals one reference step from 8 random in-contact states (feet
    pressed in and sinking), with the torque held and with the PD law in the loop."""
    plant, fast = request.getfixturevalue(pair)
    rng = np.random.default_rng(1200 + len(pair))
    biped = plant.biped
    in_contact = 0
    for k in range(8):
        d, q_hold = _contact_state(plant, rng)
        in_contact += d.foot_in_contact(0) + d.foot_in_contact(1)
        s = fast.state_from_data(d)
        if k % 2:
            tau = rng.normal(0.0, 3.0, 6)
            s1 = fast.step(s, tau)
            plant.step(d, tau)
        else:
            s1 = fast.step(s, q_ref=q_hold, kp=KP, kd=KD)
            plant.step(d, KP * (q_hold - d.q[biped.idx_q]) - KD * d.v[biped.idx_v])
        _assert_same(fast, s1, d)
        for foot in (0, 1):
            np.testing.assert_allclose(s1.foot_force(foot), d.foot_force(foot),
                                       rtol=1e-9, atol=1e-7)
            assert s1.foot_in_contact(foot) == d.foot_in_contact(foot)
    assert in_contact >= 10          # most of the 16 feet really are in contact


@pytest.mark.parametrize("pair", ["sand_pair", "rigid_pair"])
def test_n_steps_match_reference_while_sinking(pair, request):
    """40 compiled steps (chunked calls, PD in the loop) equal 40 reference steps from the
    first step of fresh data (the Verlet start), both feet in contact throughout (on sand
    sinking meanwhile); then 23 steps with a held torque (2 chunks + 3 single steps)."""
    plant, fast = request.getfixturevalue(pair)
    biped = plant.biped
    rng = np.random.default_rng(77)
    sand = plant.terrain.kind == "granular"
    d, q_hold = _contact_state(plant, rng, depth_mm=(3.0, 6.0) if sand else (0.1, 0.4),
                               settle_steps=0, v_sigma=0.02,
                               v_down=0.1 if sand else 0.0, tilt=0.003)
    s = fast.state_from_data(d)
    assert not s.started
    s = fast.step(s, n_steps=40, q_ref=q_hold, kp=KP, kd=KD)
    depths = []
    for _ in range(40):
        plant.step(d, KP * (q_hold - d.q[biped.idx_q]) - KD * d.v[biped.idx_v])
        assert d.foot_in_contact(0) and d.foot_in_contact(1)
        depths.append(d.contact.feet[0].diag[:, 0].max())
    _assert_same(fast, s, d, tol=1e-8)
    assert s.foot_in_contact(0) and s.foot_in_contact(1)
    if sand:
        assert depths[-1] > depths[0] + 2e-4            # the feet sank meanwhile
    tau = rng.normal(0.0, 2.0, 6)
    s = fast.step(s, tau, n_steps=23)
    for _ in range(23):
        plant.step(d, tau)
    _assert_same(fast, s, d, tol=1e-8)


def test_semi_implicit_euler_with_effects_and_wrench(euler_pair):
    """The semi-implicit Euler step with two terrain effects (cohesion, inertial drag), a
    traced joint effect and a constant trunk wrench, in contact, equals the reference over
    15 steps."""
    plant, fast = euler_pair
    assert {"cohesion.suction", "inertial_drag.c_d"} <= set(plant.terrain.param_names)
    rng = np.random.default_rng(5)
    d, q_hold = _contact_state(plant, rng)
    wrench = np.array([3.0, -2.0, 5.0, 0.3, 0.1, -0.2])
    d.base_wrench = wrench
    s = fast.state_from_data(d)
    tau = rng.normal(0.0, 2.0, 6)
    s = fast.step(s, tau, n_steps=15, wrench=wrench)
    for _ in range(15):
        plant.step(d, tau)
    _assert_same(fast, s, d, tol=1e-8)


def test_end_stops_free_flight(rigid_pair):
    """Far from the ground, joints beyond their limits (end stops active) and fast random
    velocities: compiled and reference agree over 10 steps."""
    plant, fast = rigid_pair
    biped = plant.biped
    rng = np.random.default_rng(9)
    lo, hi = biped.position_limits
    for _ in range(4):
        q_a = np.where(rng.random(6) < 0.5, lo - 0.05, hi + 0.05)
        quat = rng.normal(size=4)
        q = biped.q_from_parts([0.0, 0.0, 2.0], quat / np.linalg.norm(quat), q_a)
        d = plant.new_data(q, rng.normal(0.0, 1.0, biped.model.nv))
        s = fast.state_from_data(d)
        tau = rng.normal(0.0, 2.0, 6)
        s = fast.step(s, tau, n_steps=10)
        for _ in range(10):
            plant.step(d, tau)
        _assert_same(fast, s, d)


def test_divergence_raises(rigid_pair):
    """A state beyond the velocity bound raises PlantDivergedError with the time."""
    plant, fast = rigid_pair
    q = plant.biped.standing_configuration(1.0)
    v = np.zeros(plant.biped.model.nv)
    v[0] = 2.0 * plant.sim.max_speed
    with pytest.raises(PlantDivergedError) as err:
        fast.step(fast.initial_state(q, v), n_steps=3)
    assert err.value.reason == "velocity-bound"


def _advance_one_by_one(fast, d, n, points):
    """``n`` calls of ``advance(d, 1)``, each foot's evaluated contact point kept per step
    (what ``advance_steps`` documents), read through the public aux slices."""
    for _ in range(n):
        fast.advance(d, 1)
        for foot in (0, 1):
            if d.aux[AUX_SLICES[foot, "evaluated"].start] > 0.5:
                points[foot] = d.aux[AUX_SLICES[foot, "point"]]


def test_advance_steps_equals_single_steps(sand_pair):
    """advance_steps in multi-step calls (8, 4, 2 and single steps) gives bit for bit the
    states, aux, time, step count and kept contact points of one advance per step, with
    a torque changing between calls, in contact in the sand."""
    plant, fast = sand_pair
    biped = plant.biped
    rng = np.random.default_rng(5)
    d_ref, q_hold = _contact_state(plant, rng)
    d1 = fast.data_from_state(fast.state_from_data(d_ref))
    dn = fast.data_from_state(fast.state_from_data(d_ref))
    p1, pn = np.full((2, 3), np.nan), np.full((2, 3), np.nan)
    fast.advance(d1, 1)
    fast.advance(dn, 1)
    ns = (13, 8, 4, 3, 2, 1, 7, 15, 6, 5)
    assert {k for k in STEP_COUNTS if k <= max(ns)} == set(STEP_COUNTS)   # every call size
    for n in ns:
        tau = KP * (q_hold - d1.q[biped.idx_q]) - KD * d1.v[biped.idx_v]
        d1.tau[:] = dn.tau[:] = tau
        _advance_one_by_one(fast, d1, n, p1)
        fast.advance_steps(dn, n, pn)
        assert np.array_equal(dn.x, d1.x) and np.array_equal(dn.aux, d1.aux)
        assert dn.t == d1.t and dn.steps == d1.steps
        assert np.array_equal(pn, p1, equal_nan=True)
    assert not np.isnan(p1).any()          # both feet's points were read


def test_advance_steps_raises_at_the_step_where_it_diverges(rigid_pair):
    """A free fall that crosses the velocity bound in the middle of a multi-step call
    raises PlantDivergedError at the same step (time, state, aux) as single steps."""
    plant, fast = rigid_pair
    q = plant.biped.standing_configuration(1.0)
    v = np.zeros(plant.biped.model.nv)
    v[2] = -(plant.sim.max_speed - 2.5 * 9.81 * plant.dt)       # crosses at step 3
    d1, dn = fast.new_data(q, v), fast.new_data(q, v)
    p1, pn = np.zeros((2, 3)), np.zeros((2, 3))
    with pytest.raises(PlantDivergedError) as e1:
        _advance_one_by_one(fast, d1, 8, p1)
    with pytest.raises(PlantDivergedError) as en:
        fast.advance_steps(dn, 8, pn)
    assert en.value.reason == e1.value.reason == "velocity-bound"
    assert dn.steps == d1.steps == 3 and dn.t == d1.t
    assert np.array_equal(dn.x, d1.x) and np.array_equal(dn.aux, d1.aux)
    assert np.array_equal(pn, p1)


def test_untraceable_joint_effect_rejected(biped, rigid):
    """A joint effect that only works on floats is refused (not silently dropped)."""
    def floats_only(q_a, dq_a):
        return np.array([-0.1 * float(x) for x in dq_a])

    with pytest.raises(ConfigError, match="joint effect"):
        CompiledPlant(Plant(biped, rigid, SimConfig(), joint_effects=(floats_only,)))


def test_state_is_immutable_and_typed(sand_pair):
    """States are frozen, carry read-only arrays and the step does not modify its input."""
    plant, fast = sand_pair
    s0 = fast.initial_state(plant.biped.standing_configuration(0.01))
    x0 = s0.x.copy()
    s1 = fast.step(s0, n_steps=2)
    np.testing.assert_array_equal(s0.x, x0)
    assert s1.steps == 2 and s1.t == pytest.approx(2 * plant.dt)
    with pytest.raises(ValueError):
        s1.x[0] = 1.0
    assert s1.contact.shape == (2, fast.layout.n_patches, fast.layout.patch_state)


def test_in_place_path_equals_step(sand_pair):
    """advance() on CompiledData (torques written in place, per-step Python PD) gives the
    same states as step() and as the reference plant over 25 steps in contact."""
    plant, fast = sand_pair
    biped = plant.biped
    rng = np.random.default_rng(21)
    d_ref, q_hold = _contact_state(plant, rng)
    d = fast.data_from_state(fast.state_from_data(d_ref))
    for _ in range(25):
        tau = KP * (q_hold - d.q[biped.idx_q]) - KD * d.v[biped.idx_v]
        d.tau[:] = tau
        fast.advance(d)
        plant.step(d_ref, tau)
    _assert_same(fast, d.state(), d_ref)
    d.tau[:] = 0.0
    d.q_ref[:], d.kp[:], d.kd[:] = q_hold, KP, KD
    s = fast.step(d.state(), n_steps=12, q_ref=q_hold, kp=KP, kd=KD)
    fast.advance(d, 12)
    np.testing.assert_array_equal(d.state().x, s.x)


def test_actuator_model_refused(biped, rigid):
    """sim.actuators (not compiled yet) is refused rather than silently ignored."""
    sim = SimConfig.model_validate({"actuators": {"friction": {"enabled": True}}})
    with pytest.raises(ConfigError, match="actuators"):
        CompiledPlant(Plant(biped, rigid, sim))


def test_per_foot_theta_and_joint_parameters_match_reference(biped):
    """The replay's compiled model (each foot its own terrain θ, joint friction's parameters
    in θ; :meth:`ReplayModel.compiled_plant`) equals the reference plant with the same
    per-foot surfaces and the joint effect as a hook, over 30 steps in contact; the
    neutral joint parameters leave the plant without friction."""
    from granular_mpc.effects import effect_info, joint_torque_function
    from granular_mpc.validation.replay import build_replay_model, model_terrain

    rm = build_replay_model(biped, model_terrain("dry_sand"), sample_rate_hz=200.0,
                            terrain_effects=["cohesion"], plant="compiled")
    fast, choice = rm.compiled_plant()
    assert choice.resolved == "compiled" and fast is not None
    c = fast.compiled
    assert c.layout.per_foot and "left:zeta" in c.theta_names
    assert "joint_friction.coulomb" in c.theta_names
    info = effect_info("joint_friction")
    p = info.resolve_params({"viscous": 0.08, "coulomb": 0.4})
    plant = Plant(biped, rm.terrain, rm.sim,
                  joint_effects=(joint_torque_function([(info, p)]),))
    rng = np.random.default_rng(31)
    d, q_hold = _contact_state(plant, rng, depth_mm=(3.0, 6.0), settle_steps=0, v_sigma=0.02,
                               v_down=0.1, tilt=0.003)
    surfaces = (0.0007, -0.0004)             # each foot its own free surface [m]
    i_h = rm.terrain.param_names.index("surface_height")
    theta = c.theta.copy()
    for i, h in enumerate(surfaces):
        d.contact.feet[i].params[i_h] = h
        theta[c.layout.terrain_theta(i).start + i_h] = h
    names = list(c.theta_names)
    for k in info.params:
        theta[names.index(f"joint_friction.{k}")] = p[k]
    assert c.layout.joint_theta.start == 2 * len(rm.terrain.param_names)
    s = c.state_from_data(d)
    s = c.step(s, n_steps=30, q_ref=q_hold, kp=KP, kd=KD, theta=theta)
    for _ in range(30):
        plant.step(d, KP * (q_hold - d.q[biped.idx_q]) - KD * d.v[biped.idx_v])
        assert d.foot_in_contact(0) and d.foot_in_contact(1)
    _assert_same(c, s, d, tol=1e-8)
    # the same steps with the default (neutral) θ differ: friction and surfaces matter
    s0 = c.step(c.state_from_data(_contact_state(plant, np.random.default_rng(31),
                                                 depth_mm=(3.0, 6.0), settle_steps=0,
                                                 v_sigma=0.02, v_down=0.1, tilt=0.003)[0]),
                n_steps=30, q_ref=q_hold, kp=KP, kd=KD)
    assert np.abs(s0.v - s.v).max() > 1e-6


def test_initial_x_and_reset_data_equal_a_fresh_data(sand_pair):
    """initial_x is initial_state's x bit for bit (normalised quaternion, v0 default zero,
    the fresh contact state); reset_data after a run in contact gives the data new_data
    gives (state, aux, command, θ, wrench, time, started)."""
    plant, fast = sand_pair
    rng = np.random.default_rng(3)
    d_ref, q_hold = _contact_state(plant, rng)
    for q0, v0 in ((d_ref.q * 1.01, d_ref.v), (d_ref.q, None)):
        assert np.array_equal(fast.initial_x(q0, v0), fast.initial_state(q0, v0).x)
    with pytest.raises(ConfigError):
        fast.initial_x(d_ref.q[:-1])
    d = fast.data_from_state(fast.state_from_data(d_ref))
    d.tau[:], d.wrench[:] = 1.0, 3.0
    fast.advance(d, 12)
    d.kp[:], d.theta[0] = 2.0, 7.0
    fast.reset_data(d, d_ref.q, d_ref.v)
    fresh = fast.new_data(d_ref.q, d_ref.v)
    for name in ("x", "aux", "u", "theta", "wrench"):
        assert np.array_equal(getattr(d, name), getattr(fresh, name)), name
    assert (d.t, d.steps, d.started) == (fresh.t, fresh.steps, fresh.started)


@pytest.mark.parametrize("pair", ["sand_pair", "rigid_pair"])
def test_advance_samples_equals_advance_per_sample(pair, request):
    """advance_samples gives bit for bit the per-row state and aux of one advance(d, chunk)
    per torque row (the chunk path, on a stepped and on a fresh data, and the general
    path, n_steps ≠ chunk)."""
    plant, fast = request.getfixturevalue(pair)
    biped = plant.biped
    rng = np.random.default_rng(8)
    d_ref, q_hold = _contact_state(plant, rng)
    tau = 20.0 * rng.standard_normal((9, len(biped.idx_v)))
    start = fast.state_from_data(d_ref)
    for n_steps, started in ((fast.chunk, True), (3, True), (fast.chunk, False)):
        if started:                     # stepped before
            d1, dn = fast.data_from_state(start), fast.data_from_state(start)
        else:                           # fresh: the Verlet start sees row 0's torque
            d1, dn = fast.new_data(start.q, start.v), fast.new_data(start.q, start.v)
        X, A, done = fast.advance_samples(dn, tau, n_steps)
        assert done == len(tau)
        for k in range(len(tau)):
            d1.tau[:] = tau[k]
            fast.advance(d1, n_steps)
            assert np.array_equal(X[k], d1.x) and np.array_equal(A[k], d1.aux)
        assert np.array_equal(dn.x, d1.x) and dn.steps == d1.steps
        assert dn.t == pytest.approx(d1.t, abs=1e-15)


def test_advance_samples_stops_at_the_row_where_it_diverges(rigid_pair):
    """A free fall crossing the velocity bound after the first row: the rows before it
    as advance gives them, NaN from that row on, done = the row where advance raises."""
    plant, fast = rigid_pair
    q = plant.biped.standing_configuration(1.0)
    v = np.zeros(plant.biped.model.nv)
    v[2] = -(plant.sim.max_speed - 25.0 * 9.81 * plant.dt)       # crosses after ≈ 25 steps
    tau = np.zeros((6, len(plant.biped.idx_v)))
    d1, dn = fast.new_data(q, v), fast.new_data(q, v)
    X, A, done = fast.advance_samples(dn, tau, fast.chunk)
    rows = 0
    with pytest.raises(PlantDivergedError):
        for k in range(len(tau)):
            fast.advance(d1, fast.chunk)
            assert np.array_equal(X[k], d1.x) and np.array_equal(A[k], d1.aux)
            rows += 1
    assert done == rows >= 1 and np.isnan(X[done:]).all() and np.isnan(A[done:]).all()
