"""Whole-body QP: its torques and forces satisfy the rigid-body dynamics, respect the
limits, keep swing feet force-free and respect the sand's present capacity."""

import dataclasses
import os

import numpy as np
import pinocchio as pin
import pytest

from granular_mpc.codegen import compiler

from granular_mpc.config import CommandConfig, ControllerConfig
from granular_mpc.control.controller import WalkingController
from granular_mpc.control.solvers.proxqp import QPSolution, QPStatus
from granular_mpc.control.wbc import WBCReference
from granular_mpc.robot.kinematics import balanced_stance
from granular_mpc.rotations import matrix_from_quat_xyzw, rot_z
from granular_mpc.runner import build_simulation, closed_loop
from granular_mpc.scenario import load_scenario


def with_solver(wbc, solver: str):
    """The same whole-body controller with ``controller.wbc.solver = solver``."""
    return dataclasses.replace(wbc, config=wbc.config.model_copy(update={"solver": solver}))


def record_solutions(data) -> list[QPSolution]:
    """Wrap the WBC's solver so every QPSolution it returns is kept (public interface:
    the solver's ``solve``, as the failure test below replaces it)."""
    seen: list[QPSolution] = []
    solve = data.solver.solve

    def spy(problem):
        seen.append(solve(problem))
        return seen[-1]

    data.solver.solve = spy
    return seen


def reference(ctrl, q, stance, forces, force_cap=None):
    z3 = np.zeros((2, 3))
    com = ctrl.biped.com(q)
    return WBCReference(com=com, com_vel=np.zeros(3), com_acc=np.zeros(3),
                        R_trunk=np.eye(3), omega=np.zeros(3), stance=stance,
                        forces=forces, swing_pos=z3 + [0.0, 0.0, 0.1], swing_vel=z3,
                        swing_acc=z3, sink_accel=np.zeros(2), force_cap=force_cap)


@pytest.fixture(scope="module")
def setup(biped, rigid):
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(), biped, rigid)
    q = balanced_stance(biped)
    rng = np.random.default_rng(2)
    v = rng.normal(0.0, 0.05, biped.model.nv)
    return ctrl, q, v


@pytest.mark.parametrize("solver", ["proxsuite", "daqp"])
def test_solution_satisfies_the_floating_base_dynamics(setup, biped, solver):
    ctrl, q, v = setup
    wbc = with_solver(ctrl.wbc, solver)
    data = wbc.new_data()
    data.keep_residuals = True
    solutions = record_solutions(data)
    forces = np.zeros((2, 2, 3))
    forces[0, :, 2] = biped.weight / 2
    pd = data.pin
    pin.framesForwardKinematics(biped.model, pd, q)
    feet = ctrl.foot_points(pd)
    tau = wbc.solve(data, q, v, reference(ctrl, q, (True, False), forces), feet)
    assert data.last_status.ok
    x = solutions[-1].x
    nv = biped.model.nv
    qdd, f = x[:nv], x[nv:].reshape(2, 2, 3)
    # independent: ABA with the solution's torques and contact forces as external forces
    m = biped.model
    d = m.createData()
    pin.framesForwardKinematics(m, d, q)
    tau_full = np.zeros(nv)
    tau_full[biped.idx_v] = tau
    J_ext = np.zeros(nv)
    pin.computeJointJacobians(m, d, q)
    for i, side in enumerate(("left", "right")):
        J6 = pin.getFrameJacobian(m, d, biped.foot_frame[side], pin.LOCAL_WORLD_ALIGNED)
        for k, r in enumerate(feet[i].offsets):
            Jp = J6[:3] - pin.skew(r) @ J6[3:]
            J_ext += Jp.T @ f[i, k]
    qdd_aba = pin.aba(m, d, q, v, tau_full + J_ext)
    # The joint rows of the dynamics hold exactly (τ is computed from them); the 6 base
    # rows are QP equalities with residual ≤ eps_abs = 1e-5 N, N·m, which moves q̈ by at
    # most ‖M⁻¹[:, base]‖∞·eps_abs = 4.1e-4 here. Measured 6e-7 (velocity seeds 2–5);
    # bound 1e-4: 170× the measurement, inside the solver's guarantee.
    np.testing.assert_allclose(qdd, qdd_aba, atol=1e-4)
    assert np.all(np.abs(tau) <= biped.torque_limits + 1e-9)    # box rows: clipped exactly
    # swing foot: its force variables are boxed to 0, so |f| ≤ eps_abs (measured 5.6e-6;
    # was 1e-4, ten times the solver's tolerance)
    np.testing.assert_allclose(f[1], 0.0, atol=data.solver.eps_abs)
    # the stance foot carries the weight: measured ≥ 50 N per point (weight/2 ≈ 52 N)
    assert np.all(f[0, :, 2] >= 0.4 * biped.weight / 2)


@pytest.mark.parametrize("solver", ["proxsuite", "daqp"])
def test_force_cap_limits_the_loading_foot_on_sand(biped, sand, solver):
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(), biped, sand)
    q = balanced_stance(biped, clearance=-0.002)
    wbc = with_solver(ctrl.wbc, solver)
    data = wbc.new_data()
    solutions = record_solutions(data)
    pd = data.pin
    pin.framesForwardKinematics(biped.model, pd, q)
    feet = ctrl.foot_points(pd)
    forces = np.zeros((2, 2, 3))
    forces[:, :, 2] = biped.weight / 4
    cap = np.array([15.0, 200.0])
    wbc.solve(data, q, np.zeros(biped.model.nv),
              reference(ctrl, q, (True, True), forces, force_cap=cap), feet)
    assert solutions[-1].status.ok
    f = solutions[-1].x[biped.model.nv:].reshape(2, 2, 3)
    # one capacity row per point, each within eps_abs: bound 15 N + n_points·eps_abs
    # (measured excess 2.4e-9 N; was 1e-4); the other foot takes the rest of the weight
    assert f[0, :, 2].sum() <= 15.0 + f.shape[1] * data.solver.eps_abs
    assert f[1, :, 2].sum() > biped.weight / 2


def test_a_failed_qp_holds_the_previous_torques(setup, biped):
    ctrl, q, v = setup
    data = ctrl.wbc.new_data()
    forces = np.zeros((2, 2, 3))
    forces[0, :, 2] = biped.weight / 2
    pd = data.pin
    pin.framesForwardKinematics(biped.model, pd, q)
    feet = ctrl.foot_points(pd)
    ref = reference(ctrl, q, (True, False), forces)
    tau0 = ctrl.wbc.solve(data, q, v, ref, feet)
    data.solver.solve = lambda p: QPSolution(np.zeros(ctrl.wbc.n), QPStatus.PRIMAL_INFEASIBLE)
    tau1 = ctrl.wbc.solve(data, q, v, ref, feet)
    assert data.failures == 1
    np.testing.assert_allclose(tau1, tau0)


def record_problems(data) -> list[dict]:
    """Wrap the WBC's solver so a copy of every QP it is handed is kept."""
    seen: list[dict] = []
    solve = data.solver.solve

    def spy(problem):
        seen.append({k: np.array(getattr(problem, k)) for k in QP_ARRAYS})
        return solve(problem)

    data.solver.solve = spy
    return seen


QP_ARRAYS = ("H", "g", "A", "b", "C", "l", "u", "lb", "ub")


@pytest.mark.parametrize("terrain_name", ["sand", "rigid"])
def test_compiled_assembly_builds_the_numpy_reference_qp(biped, sand, rigid, terrain_name):
    """The compiled QP assembly (``assembly="compiled"``, the default) hands ProxSuite the
    QP of the NumPy assembly (the reference, ``assembly="numpy"``) over random states and
    references, in every stance pair, with and without a force cap."""
    if compiler() is None or os.environ.get("GRANULAR_MPC_JIT", "1") == "0":
        pytest.skip("nothing compiled (no C compiler or GRANULAR_MPC_JIT=0): NumPy assembly")
    terrain = sand if terrain_name == "sand" else rigid
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(), biped, terrain)
    wbc_c = ctrl.wbc
    wbc_n = dataclasses.replace(ctrl.wbc, assembly="numpy")
    dc, dn = wbc_c.new_data(), wbc_n.new_data()
    assert dc.assembly is not None and dn.assembly is None
    qp_c, qp_n = record_problems(dc), record_problems(dn)
    rng = np.random.default_rng(7)
    nv = biped.model.nv
    stances = [(True, True), (True, False), (False, True), (False, False)]
    taus = []
    for trial in range(24):
        stance = stances[trial % 4]
        q = balanced_stance(biped)
        q[:3] += rng.normal(0.0, 0.02, 3)
        quat = np.array([*rng.normal(0.0, 0.05, 3), 1.0])
        q[3:7] = quat / np.linalg.norm(quat)
        q[7:] += rng.normal(0.0, 0.2, nv - 6)
        v = rng.normal(0.0, 0.5, nv)
        pd = dc.pin
        pin.framesForwardKinematics(biped.model, pd, q)
        feet = ctrl.foot_points(pd)
        forces = rng.uniform(-5.0, 60.0, (2, 2, 3))
        ref = WBCReference(
            com=ctrl.biped.com(q) + rng.normal(0.0, 0.01, 3), com_vel=rng.normal(0.0, 0.1, 3),
            com_acc=rng.normal(0.0, 0.5, 3), R_trunk=rot_z(rng.uniform(-0.3, 0.3)),
            omega=rng.normal(0.0, 0.1, 3), stance=stance, forces=forces,
            swing_pos=rng.normal(0.0, 0.1, (2, 3)), swing_vel=rng.normal(0.0, 0.2, (2, 3)),
            swing_acc=rng.normal(0.0, 1.0, (2, 3)), sink_accel=rng.normal(0.0, 0.5, 2),
            force_weight=None if trial % 3 else 1e-3,
            force_cap=None if trial % 2 else rng.uniform(-10.0, 300.0, 2))
        taus.append((wbc_c.solve(dc, q, v, ref, feet), wbc_n.solve(dn, q, v, ref, feet)))
    assert len(qp_c) == len(qp_n) == 24
    for c, n in zip(qp_c, qp_n):
        for key in QP_ARRAYS:
            finite = np.abs(n[key]) < 1e19          # ±1e20: the free sides, equal exactly
            np.testing.assert_array_equal(c[key][~finite], n[key][~finite])
            scale = max(1.0, float(np.abs(n[key][finite]).max(initial=0.0)))
            # measured ≤ 2e-15 relative (summation order of the products)
            assert np.abs(c[key] - n[key])[finite].max(initial=0.0) <= 1e-12 * scale, key
    for tau_c, tau_n in taus:
        # the same QP solved by two warm-started solvers: equal within the QP's tolerance
        np.testing.assert_allclose(tau_c, tau_n, atol=1e-6 * max(1.0, np.abs(tau_n).max()))


@pytest.mark.parametrize("solver", ["proxsuite", "daqp"])
def test_compiled_torques_are_the_dynamics_of_the_solution(biped, sand, solver):
    """The compiled torque read-out (the default path) returns, for the QP solution it
    was handed, ``τ = (M q̈ + h − Σ Jᵢᵀ fᵢ)`` of the actuated rows, clipped to the limits
    and in actuator order — evaluated here independently with Pinocchio (CRBA, RNEA,
    frame Jacobians) to round-off (≤ 1e-12 of the terms' magnitudes), over random states
    in every stance pair."""
    if compiler() is None or os.environ.get("GRANULAR_MPC_JIT", "1") == "0":
        pytest.skip("nothing compiled (no C compiler or GRANULAR_MPC_JIT=0): NumPy read-out")
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(), biped, sand)
    wbc = with_solver(ctrl.wbc, solver)
    data = wbc.new_data()
    solutions = record_solutions(data)
    m, nv = biped.model, biped.model.nv
    d = m.createData()
    rng = np.random.default_rng(12)
    stances = [(True, True), (True, False), (False, True), (False, False)]
    clipped = 0
    for trial in range(16):
        q = balanced_stance(biped)
        q[7:] += rng.normal(0.0, 0.2, nv - 6)
        v = rng.normal(0.0, 0.5, nv)
        pin.framesForwardKinematics(m, data.pin, q)
        feet = ctrl.foot_points(data.pin)
        forces = rng.uniform(0.0, 80.0, (2, 2, 3))
        ref = reference(ctrl, q, stances[trial % 4], forces)
        tau = wbc.solve(data, q, v, ref, feet)
        assert data.last_status.ok
        x = solutions[-1].x
        qdd, f = x[:nv], x[nv:].reshape(2, 2, 3)
        M = pin.crba(m, d, q)
        M = np.triu(M) + np.triu(M, 1).T
        h = pin.nle(m, d, q, v)
        pin.computeJointJacobians(m, d, q)
        pin.framesForwardKinematics(m, d, q)
        JTf, scale_f = np.zeros(nv), np.zeros(nv)
        for i, side in enumerate(("left", "right")):
            J6 = pin.getFrameJacobian(m, d, biped.foot_frame[side], pin.LOCAL_WORLD_ALIGNED)
            for k, r in enumerate(feet[i].offsets):
                Jp = J6[:3] - pin.skew(r) @ J6[3:]
                JTf += Jp.T @ f[i, k]
                scale_f += np.abs(Jp.T) @ np.abs(f[i, k])
        lim = biped.torque_limits[np.argsort(biped.idx_v)]      # v order of the joints
        for gain in (1.0, 30.0):
            # the solution itself, and 30 × it through the same read-out (torques beyond
            # the limits: the clip)
            if gain != 1.0:
                data.assembly.torques(gain * x)
                tau = data.assembly.tau_act.copy()
            full = M @ (gain * qdd) + h - gain * JTf
            scale = gain * np.abs(M) @ np.abs(qdd) + np.abs(h) + gain * scale_f
            expected = np.clip(full[6:], -lim, lim)
            clipped += int(np.sum(np.abs(full[6:]) > lim))
            got = np.empty(nv - 6)
            got[biped.idx_v - 6] = tau                  # actuator order → v order
            assert np.all(np.abs(got - expected) <= 1e-12 * scale[6:])
    assert clipped > 0          # the clip was exercised


def test_free_flyer_placement_is_the_quaternion_matrix(biped):
    """The compiled assembly and the run log take the trunk's rotation from Pinocchio's
    free-flyer placement instead of building it from q's quaternion: the two are the same
    numbers bit for bit (the same formula), for unit and slightly non-unit quaternions."""
    model = biped.model
    assert model.joints[1].shortname() == "JointModelFreeFlyer"
    data = model.createData()
    rng = np.random.default_rng(3)
    for i in range(500):
        q = biped.standing_configuration()
        quat = rng.normal(size=4)
        q[3:7] = quat / np.linalg.norm(quat) * (1.0 + 1e-9 * rng.normal() * (i % 2))
        pin.forwardKinematics(model, data, q)
        assert np.array_equal(data.oMi[1].rotation, matrix_from_quat_xyzw(q[3:7]))


@pytest.mark.parametrize("terrain_name", ["sand", "rigid"])
def test_daqp_solves_the_qp_proxsuite_is_given(biped, sand, rigid, terrain_name):
    """``controller.wbc.solver = "daqp"``: the QP (built in DAQP's own stacked arrays) is
    the ProxSuite path's QP bit for bit, in every stance pair; DAQP's solution is the
    ProxSuite one within ProxSuite's tolerance, and exact for the equalities."""
    terrain = sand if terrain_name == "sand" else rigid
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(), biped, terrain)
    wbc_p, wbc_d = ctrl.wbc, with_solver(ctrl.wbc, "daqp")
    dp, dd = wbc_p.new_data(), wbc_d.new_data()
    assert np.shares_memory(dd.work.C_poly, dd.work.C)     # the polytope view writes into C
    qp_p, qp_d = record_problems(dp), record_problems(dd)
    sol_p, sol_d = record_solutions(dp), record_solutions(dd)
    rng = np.random.default_rng(11)
    nv = biped.model.nv
    stances = [(True, True), (True, False), (False, True), (False, False)]
    for trial in range(8):
        q = balanced_stance(biped, clearance=-0.002 if terrain_name == "sand" else 0.0)
        q[7:] += rng.normal(0.0, 0.05, nv - 6)
        v = rng.normal(0.0, 0.2, nv)
        pin.framesForwardKinematics(biped.model, dp.pin, q)
        feet = ctrl.foot_points(dp.pin)
        forces = np.zeros((2, 2, 3))
        forces[:, :, 2] = biped.weight / 4
        ref = reference(ctrl, q, stances[trial % 4], forces)
        tau_p = wbc_p.solve(dp, q, v, ref, feet)
        tau_d = wbc_d.solve(dd, q, v, ref, feet)
        assert dd.last_status.ok and dp.last_status.ok
        # τ = M_a q̈ + h_a − J_aᵀ f of two solutions equal to ProxSuite's eps_abs = 1e-5:
        # measured ≤ 1.1e-6 N·m (torques up to 6.5 N·m); bound 1e-4 N·m
        np.testing.assert_allclose(tau_d, tau_p, atol=1e-4)
    for p, d in zip(qp_p, qp_d):
        for key in QP_ARRAYS:
            np.testing.assert_array_equal(p[key], d[key])
    for p, sp, sd in zip(qp_p, sol_p, sol_d):
        # DAQP: equalities in its working set, exact to round-off (measured ≤ 3.4e-13 N);
        # ProxSuite's residual is up to its eps_abs (measured ≤ 1.8e-6 N)
        assert np.abs(p["A"] @ sd.x - p["b"]).max() <= 1e-9
        assert np.abs(p["A"] @ sp.x - p["b"]).max() <= 1e-5
        # the solutions (q̈ up to 360 rad/s², forces): measured ≤ 3.5e-5 apart; bound 1e-3
        np.testing.assert_allclose(sd.x, sp.x, atol=1e-3)


def test_closed_loop_walks_with_daqp():
    """A short sand walk with ``controller.wbc.solver=daqp`` through the public runner API:
    no fall, no QP failure, and it moves forward."""
    scenario = load_scenario("sim/sand_walk.yaml",
                             ["sim.duration=2.5", "controller.wbc.solver=daqp"])
    sim = build_simulation(scenario)
    assert sim.controller.wbc.config.solver == "daqp"
    state = sim.new_state()
    for _ in closed_loop(sim, state):
        pass
    assert state.fall is None
    assert state.controller.qp_failures == 0
    wbc = [r for r in state.controller.records if r.kind == "wbc"]
    assert len(wbc) >= 1000 and all(r.status == "solved" for r in wbc)
    # 2.5 s with a 0.8 s start delay, then the ramp to 0.2 m/s: measured 0.134 m
    assert state.plant.q[0] > 0.05


def test_torque_limits_in_velocity_order_are_the_actuator_limits_permuted(biped):
    """The WBC clips τ in the order of the actuated velocity rows (v[6:]) and returns it
    in actuator order (``τ_v[idx_v − 6]``): its limits in v order, taken the same way,
    are the actuator-order limits, joint by joint (by the joint's own velocity index)."""
    lim_v = biped.torque_limits_v
    assert lim_v.shape == (biped.model.nv - 6,)
    np.testing.assert_array_equal(lim_v[biped.idx_v - 6], biped.torque_limits)
    for name, iv, lim in zip(biped.joint_names, biped.idx_v, biped.torque_limits):
        jid = biped.model.getJointId(name)
        assert biped.model.joints[jid].idx_v == iv
        assert lim_v[iv - 6] == lim
