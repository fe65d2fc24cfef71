"""The paper's planar augmented models (sagittal 7-DoF, frontal 5-DoF) against independent
computations: finite differences, energy conservation, Pinocchio kinematics, energies and
dynamics of the 3-D model restricted to each plane, hand-derived momentum rows, and the
decoupled CoT against direct joint-power integrals."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import trapezoid

from granular_mpc.analysis.cot_decoupled import (cot_decoupled, decoupled_energy,
                                                 decoupled_power)
from granular_mpc.dynamics import planar as pl
from granular_mpc.exceptions import ConfigError, ModelError
from granular_mpc.robot import planar as rp

SIDES = ("left", "right")
SAG_ANG = slice(0, 5)
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def models(biped):
    """{side: (sagittal, frontal)} planar models."""
    return {s: pl.build_planar_models(biped, s) for s in SIDES}


def _sag_state(rng, view=None):
    q = np.r_[-0.6 + rng.uniform(-0.6, 0.6), 0.6 + rng.uniform(-0.6, 0.6),
              -0.6 + rng.uniform(-0.6, 0.6), 0.6 + rng.uniform(-0.6, 0.6),
              rng.uniform(-0.3, 0.3), rng.normal(0, 0.05), rng.normal(0, 0.02)]
    dq = np.r_[rng.normal(0, 2.0, 5), rng.normal(0, 0.3, 2)]
    ddq = np.r_[rng.normal(0, 20.0, 5), rng.normal(0, 1.0, 2)]
    return q, dq, ddq


def _front_state(rng, view):
    q = np.r_[view.offset_stance + rng.uniform(-0.3, 0.3),
              view.offset_trunk + rng.uniform(-0.3, 0.3),
              view.offset_swing + rng.uniform(-0.3, 0.3), rng.normal(0, 0.02),
              rng.normal(0, 0.02)]
    dq = np.r_[rng.normal(0, 2.0, 3), rng.normal(0, 0.3, 2)]
    ddq = np.r_[rng.normal(0, 20.0, 3), rng.normal(0, 1.0, 2)]
    return q, dq, ddq


def _state(rng, model):
    return (_sag_state(rng) if model.kind == "sagittal" else _front_state(rng, model.view))


def _all_models(models):
    return [m for s in SIDES for m in models[s]]


# ----------------------------------------------------------------------------- views
def test_views_hold_the_whole_robot(biped, models):
    for s in SIDES:
        sag, front = models[s]
        assert sag.view.total_mass == pytest.approx(biped.mass, rel=1e-12)
        assert front.view.total_mass == pytest.approx(biped.mass, rel=1e-12)
        assert sag.view.stance == s and front.view.swing != s
        # the calf+foot link is the knee body of the 3-D model: the foot COM sits forward
        # of the calf axis (foot mounted pitched), so the sagittal calf COM is off-axis
        assert sag.view.calf_stance.com_across > 0.0
        assert sag.view.foot_radius == pytest.approx(biped.config.foot.radius)
    # left and right views mirror each other in the frontal plane
    fl, fr = models["left"][1].view, models["right"][1].view
    assert fl.leg_stance.com[0] == pytest.approx(-fr.leg_stance.com[0])
    assert fl.offset_trunk == pytest.approx(-math.pi / 2)
    assert fr.offset_trunk == pytest.approx(math.pi / 2)


def test_view_failure_paths(biped):
    with pytest.raises(ConfigError):
        rp.sagittal_view(biped, "middle")
    with pytest.raises(ConfigError):
        rp.frontal_view(biped, "left", reference_joints=[0.0, 1.0])
    m = pin.Model()
    j1 = m.addJoint(0, pin.JointModelRevoluteUnaligned(0.0, -1.0, 0.0), pin.SE3.Identity(), "a")
    j2 = m.addJoint(j1, pin.JointModelRZ(), pin.SE3.Identity(), "b")
    assert rp._axis_sign(m, j1, 1) == -1
    with pytest.raises(ModelError):
        rp._axis_sign(m, j2, 1)
    # the signs enter S_s: a knee about −y flips its row
    S = rp.sagittal_selection("left", (1, 1), (-1, 1))
    assert S[2, 3] == -1.0 and S[2, 2] == 1.0


# ----------------------------------------------------------------------------- structure
def test_mass_matrix_symmetric_positive_definite(models):
    rng = np.random.default_rng(0)
    for model in _all_models(models):
        for _ in range(20):
            q, _, _ = _state(rng, model)
            D = pl.mass_matrix(model, q)
            assert np.allclose(D, D.T, atol=1e-12)
            assert np.linalg.eigvalsh(D).min() > 1e-4
            # the contact-coordinate block is the total mass times I₂
            assert np.allclose(D[-2:, -2:], model.view.total_mass * np.eye(2))


def test_ddot_minus_2c_is_skew_symmetric(models):
    rng = np.random.default_rng(1)
    eps = 1e-6
    for model in _all_models(models):
        for _ in range(10):
            q, dq, _ = _state(rng, model)
            Ddot = (pl.mass_matrix(model, q + eps * dq)
                    - pl.mass_matrix(model, q - eps * dq)) / (2 * eps)
            N = Ddot - 2.0 * pl.coriolis_matrix(model, q, dq)
            assert np.abs(N + N.T).max() < 1e-7 * max(1.0, np.abs(Ddot).max())
            # and C is not trivially zero
            assert np.abs(pl.coriolis_matrix(model, q, dq)).max() > 1e-3


def test_gravity_is_gradient_of_potential(models):
    rng = np.random.default_rng(2)
    eps = 1e-6
    for model in _all_models(models):
        g = model.view.gravity
        for _ in range(10):
            q, dq, _ = _state(rng, model)
            grad = np.array([(pl.energy(model, q + eps * e, dq)[1]
                              - pl.energy(model, q - eps * e, dq)[1]) / (2 * eps)
                             for e in np.eye(model.nq)])
            assert np.allclose(pl.gravity_vector(model, q), grad, atol=1e-6)
            # V is Σ m g z of the link COMs
            P = pl.points(model, q)
            V = sum(lk.mass * g * P[name][1] for lk, name in
                    zip(model.view.links, [n for n in model.point_names
                                           if n.startswith("com_")]))
            assert pl.energy(model, q, dq)[1] == pytest.approx(V, rel=1e-12, abs=1e-12)
        # the z_s entry of G is the whole weight
        assert pl.gravity_vector(model, q)[-1] == pytest.approx(model.view.total_mass * g)


def test_contact_jacobians_match_finite_differences(models):
    rng = np.random.default_rng(3)
    eps = 1e-6
    for model in _all_models(models):
        for _ in range(5):
            q, _, _ = _state(rng, model)
            for name, J in (("contact_stance", pl.contact_jacobian(model, q)),
                            ("contact_swing", pl.swing_contact_jacobian(model, q))):
                fd = np.column_stack([(pl.points(model, q + eps * e)[name]
                                       - pl.points(model, q - eps * e)[name]) / (2 * eps)
                                      for e in np.eye(model.nq)])
                assert np.allclose(J, fd, atol=1e-8), name
            # C1 is R below the stance arc centre
            P = pl.points(model, q)
            assert np.allclose(P["arc_stance"] - P["contact_stance"],
                               [0.0, model.view.foot_radius])


def test_inverse_and_forward_dynamics_agree(models):
    rng = np.random.default_rng(4)
    for model in _all_models(models):
        q, dq, _ = _state(rng, model)
        tau = rng.normal(0, 3, model.n_angles)
        F = rng.normal(0, 50, 2)
        ddq = pl.forward_dynamics(model, q, dq, tau, F)
        rhs = model.B @ tau + pl.contact_jacobian(model, q).T @ F
        assert np.allclose(pl.inverse_dynamics(model, q, dq, ddq), rhs, atol=1e-9)
    with pytest.raises(ConfigError):
        pl.forward_dynamics(model, np.zeros(3), np.zeros(3))


def test_energy_conserved_without_torque_or_contact(models):
    dt, n = 2e-4, 5000          # 1 s
    rng = np.random.default_rng(5)
    for model in models["left"]:
        q, dq, _ = _state(rng, model)
        X = pl.simulate_rk4(model, q, dq, np.zeros(model.n_angles), dt=dt, n_steps=n)
        E = np.array([sum(pl.energy(model, x[:model.nq], x[model.nq:])) for x in X[::50]])
        T0, V0 = pl.energy(model, q, dq)
        assert np.abs(E - E[0]).max() / (abs(T0) + abs(V0)) < 1e-6
        # the motion is not trivial: the links really moved and the body fell
        assert np.ptp(X[:, :model.n_angles], axis=0).max() > 0.5
        assert X[-1, model.nq - 1] < q[-1] - 1.0


# ----------------------------------------------------------------------------- maps vs 3-D
def _pitch(R):
    return math.atan2(R[0, 2], R[0, 0])


def _roll(R):
    return math.atan2(R[2, 1], R[1, 1])


@pytest.mark.parametrize("side", SIDES)
def test_sagittal_maps_match_pinocchio(biped, models, side):
    sag = models[side][0]
    view = sag.view
    sw = view.swing
    model = biped.model
    data = model.createData()
    rng = np.random.default_rng(6)
    R = view.foot_radius
    for _ in range(10):
        q_a = np.array(biped.config.standing_joints) + rng.uniform(-0.5, 0.5, 6)
        q_a[[0, 3]] = 0.0
        th = rng.uniform(-0.4, 0.4)
        q = biped.q_from_parts([rng.normal(), 0.0, 0.5 + rng.normal(0, 0.1)],
                               [0.0, math.sin(th / 2), 0.0, math.cos(th / 2)], q_a)
        v = np.zeros(model.nv)
        v_W = np.array([rng.normal(), 0.0, rng.normal()])
        w = rng.normal()
        Rb = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        v[0:3] = Rb.T @ v_W
        v[4] = w
        dq_a = rng.normal(0, 2, 6)
        dq_a[[0, 3]] = 0.0
        v[biped.idx_v] = dq_a
        pin.forwardKinematics(model, data, q, v)
        pin.updateFramePlacements(model, data)
        fr = {n: model.getFrameId(n) for n in
              ("trunk", f"{sw}_thigh", f"{sw}_calf", f"{side}_thigh", f"{side}_calf",
               f"{side}_foot", f"{sw}_foot")}
        order = (f"{sw}_thigh", f"{sw}_calf", f"{side}_thigh", f"{side}_calf", "trunk")
        ang = np.array([_pitch(data.oMf[fr[n]].rotation) for n in order])
        rates = np.array([pin.getFrameVelocity(model, data, fr[n], _LWA).angular[1]
                          for n in order])
        q_s = pl.sagittal_from_actuated(view, q_a, th)
        assert np.allclose(q_s, ang, atol=1e-12)
        assert np.allclose(pl.sagittal_from_actuated(view, dq_a, w), rates, atol=1e-12)
        assert np.allclose(pl.actuated_from_sagittal(view, q_s), q_a, atol=1e-12)
        assert np.allclose(view.selection @ q_s, q_a, atol=1e-12)
        # augmented state: C1 of the stance foot
        p_F = data.oMf[fr[f"{side}_foot"]].translation
        v_F = pin.getFrameVelocity(model, data, fr[f"{side}_foot"], _LWA).linear
        qq = np.r_[q_s, p_F[0], p_F[2] - R]
        dqq = np.r_[rates, v_F[0], v_F[2]]
        P = pl.points(sag, qq)
        pin.centerOfMass(model, data, q)
        assert np.allclose(P["com"], data.com[0][[0, 2]], atol=1e-12)
        assert np.allclose(P["arc_swing"], data.oMf[fr[f"{sw}_foot"]].translation[[0, 2]],
                           atol=1e-12)
        assert np.allclose(P["knee_stance"],
                           data.oMi[model.getJointId(f"{side}_knee")].translation[[0, 2]],
                           atol=1e-12)
        T, V = pl.energy(sag, qq, dqq)
        assert T == pytest.approx(pin.computeKineticEnergy(model, data, q, v), rel=1e-10)
        assert V == pytest.approx(pin.computePotentialEnergy(model, data, q), rel=1e-10)


@pytest.mark.parametrize("side", SIDES)
def test_frontal_maps_match_pinocchio(biped, models, side):
    front = models[side][1]
    view = front.view
    sw = view.swing
    model = biped.model
    data = model.createData()
    rng = np.random.default_rng(7)
    ref = np.array(view.reference_joints)
    jst = model.getJointId(f"{side}_hip_abd")
    jsw = model.getJointId(f"{sw}_hip_abd")
    for _ in range(10):
        q_a = ref.copy()
        q_a[[0, 3]] = rng.uniform(-0.4, 0.4, 2)
        phi = rng.uniform(-0.4, 0.4)
        q = biped.q_from_parts([0.0, rng.normal(), 0.5],
                               [math.sin(phi / 2), 0.0, 0.0, math.cos(phi / 2)], q_a)
        v = np.zeros(model.nv)
        v[1:3] = rng.normal(size=2)   # base velocity in the body y–z plane (pure roll)
        w = rng.normal()
        v[3] = w
        dq_a = np.zeros(6)
        dq_a[[0, 3]] = rng.normal(0, 2, 2)
        v[biped.idx_v] = dq_a
        pin.forwardKinematics(model, data, q, v)
        pin.updateFramePlacements(model, data)
        A = data.oMf[biped.foot_frame[side]].translation
        A_sw = data.oMf[biped.foot_frame[sw]].translation
        H, H_sw = data.oMi[jst].translation, data.oMi[jsw].translation
        # line angles straight from positions (no offsets involved)
        up = H - A
        expect = np.array([math.atan2(-up[1], up[2]),
                           math.atan2((H_sw - H)[1], -(H_sw - H)[2]),
                           math.atan2((A_sw - H_sw)[1], -(A_sw - H_sw)[2])])
        q_f = pl.frontal_from_actuated(view, q_a, phi)
        assert np.allclose(q_f, expect, atol=1e-12)
        back = pl.actuated_from_frontal(view, q_f)
        assert np.allclose(back[[0, 3]], q_a[[0, 3]], atol=1e-12)
        assert np.allclose(back[[1, 2, 4, 5]], 0.0)
        dq_f = pl.frontal_from_actuated(view, dq_a, w, velocity=True)
        assert np.allclose(view.selection @ dq_f, dq_a, atol=1e-12)
        v_A = pin.getFrameVelocity(model, data, biped.foot_frame[side], _LWA).linear
        R = view.foot_radius
        qq = np.r_[q_f, A[1], A[2] - R]
        dqq = np.r_[dq_f, v_A[1], v_A[2]]
        P = pl.points(front, qq)
        pin.centerOfMass(model, data, q)
        assert np.allclose(P["com"], data.com[0][[1, 2]], atol=1e-12)
        assert np.allclose(P["hip_swing"], H_sw[[1, 2]], atol=1e-12)
        assert np.allclose(P["arc_swing"], A_sw[[1, 2]], atol=1e-12)
        T, V = pl.energy(front, qq, dqq)
        assert T == pytest.approx(pin.computeKineticEnergy(model, data, q, v), rel=1e-10)
        assert V == pytest.approx(pin.computePotentialEnergy(model, data, q), rel=1e-10)


def test_torque_maps_preserve_power(models):
    rng = np.random.default_rng(8)
    sag_j, abd_j = [1, 2, 4, 5], [0, 3]
    for side in SIDES:
        sag, front = models[side]
        for _ in range(20):
            tau_a, dq_a = rng.normal(0, 5, 6), rng.normal(0, 3, 6)
            wp, wr = rng.normal(size=2)
            dqs = pl.sagittal_from_actuated(sag.view, dq_a, wp)
            dqf = pl.frontal_from_actuated(front.view, dq_a, wr, velocity=True)
            tau_s = pl.sagittal_torques(sag.view, tau_a)
            tau_f = pl.frontal_torques(front.view, tau_a)
            P_sag = tau_a[sag_j] @ dq_a[sag_j]
            P_abd = tau_a[abd_j] @ dq_a[abd_j]
            assert tau_s @ dqs == pytest.approx(P_sag, abs=1e-12)
            assert tau_f @ dqf == pytest.approx(P_abd, abs=1e-12)
            # the paper's B_s = [I4 0]ᵀ drops the trunk reaction −(τ_pitch,L + τ_pitch,R)
            assert tau_s[4] == pytest.approx(-(tau_a[1] + tau_a[4]))
            p_paper = (sag.B_paper @ tau_s[:4]) @ np.r_[dqs, 0, 0]
            assert p_paper == pytest.approx(P_sag - tau_s[4] * wp, abs=1e-12)
            # the paper's frontal torques: τ2f = −(τ_st + τ_sw), τ3f = τ_sw (our signs)
            st, sw = (0, 3) if side == "left" else (3, 0)
            assert np.allclose(tau_f, [tau_a[st], -(tau_a[st] + tau_a[sw]), tau_a[sw]])


# ----------------------------------------------------------------------------- vs 3-D dynamics
def _planar_pinocchio(biped, plane):
    """The URDF on a planar root (PX, PZ, RY sagittal / PY, PZ, RX frontal) with the
    out-of-plane joints locked (abduction at 0 / pitch and knee at the standing pose)."""
    root = pin.JointModelComposite()
    for j in ((pin.JointModelPX(), pin.JointModelPZ(), pin.JointModelRY()) if plane == "xz"
              else (pin.JointModelPY(), pin.JointModelPZ(), pin.JointModelRX())):
        root.addJoint(j)
    full = pin.buildModelFromUrdf(str(biped.config.urdf_path), root)
    q_ref = pin.neutral(full)
    names = biped.joint_names
    locked = ([n for n in names if n.endswith("_abd")] if plane == "xz"
              else [n for n in names if not n.endswith("_abd")])
    for n in locked:
        jid = full.getJointId(n)
        q_ref[full.idx_qs[jid]] = 0.0 if plane == "xz" else biped.config.standing_joints[
            names.index(n)]
    return pin.buildReducedModel(full, [full.getJointId(n) for n in locked], q_ref)


def _rk4_pinocchio(model, q0, v0, tau, dt, n):
    data = model.createData()

    def f(x):
        return np.concatenate([x[model.nq:], pin.aba(model, data, x[:model.nq],
                                                     x[model.nq:], tau)])
    X = [np.concatenate([q0, v0])]
    for _ in range(n):
        x = X[-1]
        k1 = f(x)
        k2 = f(x + 0.5 * dt * k1)
        k3 = f(x + 0.5 * dt * k2)
        k4 = f(x + dt * k3)
        X.append(x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4))
    return np.array(X)


@pytest.mark.parametrize("side", SIDES)
def test_sagittal_motion_of_3d_model_matches_planar_model(biped, models, side):
    sag = models[side][0]
    view = sag.view
    red = _planar_pinocchio(biped, "xz")
    assert red.nq == red.nv == 7
    data = red.createData()
    rng = np.random.default_rng(9 if side == "left" else 10)
    act = [n for n in biped.joint_names if not n.endswith("_abd")]
    iq = [red.idx_qs[red.getJointId(n)] for n in act]
    q0 = np.zeros(7)
    q0[1], q0[2] = 0.5, rng.uniform(-0.3, 0.3)
    q0[iq] = np.array(biped.config.standing_joints)[[1, 2, 4, 5]] + rng.uniform(-0.4, 0.4, 4)
    v0 = rng.uniform(-1.0, 1.0, 7)
    tau_j = rng.uniform(-1.0, 1.0, 4)
    tau = np.zeros(7)
    tau[iq] = tau_j
    dt, n = 5e-4, 600                                    # 0.3 s
    X = _rk4_pinocchio(red, q0, v0, tau, dt, n)
    sw = view.swing
    order = (f"{sw}_thigh", f"{sw}_calf", f"{side}_thigh", f"{side}_calf", "trunk")
    fids = [red.getFrameId(f) for f in order]
    ffoot = red.getFrameId(f"{side}_foot")
    R = view.foot_radius

    def to_planar(x):
        q, v = x[:7], x[7:]
        pin.forwardKinematics(red, data, q, v)
        pin.updateFramePlacements(red, data)
        ang = [_pitch(data.oMf[f].rotation) for f in fids]
        w = [pin.getFrameVelocity(red, data, f, _LWA).angular[1] for f in fids]
        p = data.oMf[ffoot].translation
        vf = pin.getFrameVelocity(red, data, ffoot, _LWA).linear
        return np.r_[ang, p[0], p[2] - R, w, vf[0], vf[2]]

    Q = np.array([to_planar(x) for x in X])
    Q[:, :5] = np.unwrap(Q[:, :5], axis=0)
    tau_a = np.zeros(6)
    tau_a[[biped.joint_names.index(a) for a in act]] = tau_j
    Y = pl.simulate_rk4(sag, Q[0, :7], Q[0, 7:], pl.sagittal_torques(view, tau_a),
                        dt=dt, n_steps=n)
    assert np.abs(Y[:, :5] - Q[:, :5]).max() < 1e-4
    assert np.abs(Y[:, 5:7] - Q[:, 5:7]).max() < 1e-5
    assert np.abs(Y[:, 7:] - Q[:, 7:]).max() < 1e-3
    # the comparison has teeth: the links moved by far more than the tolerance, and the
    # paper's B_s (no trunk reaction torque) gives a visibly different trunk motion
    assert np.ptp(Q[:, :5], axis=0).min() > 0.05
    tau_paper = pl.sagittal_torques(view, tau_a)
    tau_paper[4] = 0.0
    Yp = pl.simulate_rk4(sag, Q[0, :7], Q[0, 7:], tau_paper, dt=dt, n_steps=n)
    assert np.abs(Yp[:, 4] - Q[:, 4]).max() > 5e-3


@pytest.mark.parametrize("side", SIDES)
def test_frontal_motion_of_3d_model_matches_planar_model(biped, models, side):
    front = models[side][1]
    view = front.view
    red = _planar_pinocchio(biped, "yz")
    assert red.nq == red.nv == 5
    data = red.createData()
    rng = np.random.default_rng(11 if side == "left" else 12)
    act = [n for n in biped.joint_names if n.endswith("_abd")]
    iq = [red.idx_qs[red.getJointId(n)] for n in act]
    q0 = np.zeros(5)
    q0[1], q0[2] = 0.5, rng.uniform(-0.3, 0.3)
    q0[iq] = rng.uniform(-0.3, 0.3, 2)
    v0 = rng.uniform(-1.0, 1.0, 5)
    tau_j = rng.uniform(-2.0, 2.0, 2)
    tau = np.zeros(5)
    tau[iq] = tau_j
    dt, n = 5e-4, 600
    X = _rk4_pinocchio(red, q0, v0, tau, dt, n)
    sw = view.swing
    links = (f"{side}_hip", "trunk", f"{sw}_hip")
    offs = (view.offset_stance, view.offset_trunk, view.offset_swing)
    fids = [red.getFrameId(f) for f in links]
    ffoot = red.getFrameId(f"{side}_foot")
    R = view.foot_radius

    def to_planar(x):
        q, v = x[:5], x[5:]
        pin.forwardKinematics(red, data, q, v)
        pin.updateFramePlacements(red, data)
        ang = [_roll(data.oMf[f].rotation) + o for f, o in zip(fids, offs)]
        w = [pin.getFrameVelocity(red, data, f, _LWA).angular[0] for f in fids]
        p = data.oMf[ffoot].translation
        vf = pin.getFrameVelocity(red, data, ffoot, _LWA).linear
        return np.r_[ang, p[1], p[2] - R, w, vf[1], vf[2]]

    Q = np.array([to_planar(x) for x in X])
    Q[:, :3] = np.unwrap(Q[:, :3], axis=0)
    tau_a = np.zeros(6)
    tau_a[[biped.joint_names.index(a) for a in act]] = tau_j
    Y = pl.simulate_rk4(front, Q[0, :5], Q[0, 5:], pl.frontal_torques(view, tau_a),
                        dt=dt, n_steps=n)
    assert np.abs(Y[:, :3] - Q[:, :3]).max() < 1e-4
    assert np.abs(Y[:, 3:5] - Q[:, 3:5]).max() < 1e-5
    assert np.ptp(Q[:, :3], axis=0).min() > 0.05


# ----------------------------------------------------------------------------- paper rows
def _d2_sin(k, th, dth, ddth):
    """d²/dt² (k sin θ)."""
    return k * (np.cos(th) * ddth - np.sin(th) * dth ** 2)


def _d2_cos(k, th, dth, ddth):
    """d²/dt² (k cos θ)."""
    return -k * (np.sin(th) * ddth + np.cos(th) * dth ** 2)


def test_paper_sagittal_rows_are_the_swing_leg_and_trunk_momentum(models):
    sag = models["left"][0]
    v = sag.view
    rng = np.random.default_rng(13)
    # hand derivation below assumes: both hips at one sagittal point, trunk COM above it,
    # thigh COMs on the thigh axes (true for this robot)
    assert np.allclose(v.hip_stance, v.hip_swing) and v.trunk_com_from_hip[0] == 0.0
    assert v.thigh_stance.com_across == v.thigh_swing.com_across == 0.0
    M = v.total_mass
    m_ts, m_cs, m_cw = v.thigh_stance.mass, v.calf_stance.mass, v.calf_swing.mass
    l_c, a_c, e_s = v.calf_stance.length, v.calf_stance.com_along, v.calf_stance.com_across
    l_t, a_t = v.thigh_stance.length, v.thigh_stance.com_along
    e_w = v.calf_swing.com_across
    k4 = m_cs * (l_c - a_c) + (M - m_cs) * l_c     # stance calf carries everything above
    k3 = m_ts * (l_t - a_t) + (M - m_ts - m_cs) * l_t
    gaps = []
    for _ in range(50):
        q, dq, ddq = _sag_state(rng)
        full = pl.inverse_dynamics(sag, q, dq, ddq)[5:]
        paper = pl.paper_sagittal_rows(v, q, dq, ddq)
        a = (q[3], dq[3], ddq[3]), (q[2], dq[2], ddq[2]), (q[1], dq[1], ddq[1])
        omit_x = ((m_ts + m_cs) * ddq[5] + _d2_sin(k4, *a[0]) + _d2_sin(k3, *a[1])
                  + _d2_cos(m_cs * e_s, *a[0]) + _d2_cos(m_cw * e_w, *a[2]))
        omit_z = ((m_ts + m_cs) * (ddq[6] + v.gravity) + _d2_cos(k4, *a[0])
                  + _d2_cos(k3, *a[1]) - _d2_sin(m_cs * e_s, *a[0])
                  - _d2_sin(m_cw * e_w, *a[2]))
        assert np.allclose(full, paper + [omit_x, omit_z], atol=1e-9)
        gaps.append(np.abs(full - paper))
    # the omitted terms are not small
    assert np.mean(gaps) > 10.0
    # at rest the paper's z row carries only M_s g, not the whole weight
    q = np.r_[-0.6, 0.6, -0.6, 0.6, 0.0, 0.0, 0.0]
    z = np.zeros(7)
    assert pl.paper_sagittal_rows(v, q, z, z)[1] == pytest.approx(
        (M - m_ts - m_cs) * v.gravity)
    assert pl.inverse_dynamics(sag, q, z, z)[6] == pytest.approx(M * v.gravity)
    # …and they are exactly the rows of a model whose stance leg is massless and does not
    # rotate, with the swing-calf COM put on its axis
    ideal = dataclasses.replace(
        v, thigh_stance=dataclasses.replace(v.thigh_stance, mass=0.0, inertia=0.0),
        calf_stance=dataclasses.replace(v.calf_stance, mass=0.0, inertia=0.0),
        calf_swing=dataclasses.replace(v.calf_swing, com=(0.0, -v.calf_swing.com_along)))
    sag_i = pl.sagittal_model(ideal)
    for _ in range(20):
        q, dq, ddq = _sag_state(rng)
        dq[2:4] = ddq[2:4] = 0.0
        assert np.allclose(pl.inverse_dynamics(sag_i, q, dq, ddq)[5:],
                           pl.paper_sagittal_rows(ideal, q, dq, ddq), atol=1e-9)


@pytest.mark.parametrize("side", SIDES)
def test_paper_frontal_row_is_exact_for_on_line_coms(models, side):
    front = models[side][1]
    v = front.view
    rng = np.random.default_rng(14)
    assert v.hip_stance[1] == v.hip_swing[1]          # hip line along ±y in B
    along, h = v.trunk_com_from_hip
    e1, e2 = v.leg_stance.com_across, v.leg_swing.com_across
    m_b, m1, m2 = v.trunk.mass, v.leg_stance.mass, v.leg_swing.mass
    for _ in range(50):
        q, dq, ddq = _front_state(rng, v)
        full = pl.inverse_dynamics(front, q, dq, ddq)[3]
        paper = pl.paper_frontal_y_row(v, q, dq, ddq)
        phi_b = (q[1] - v.offset_trunk, dq[1], ddq[1])
        omit = (_d2_cos(m1 * e1, q[0], dq[0], ddq[0]) + _d2_cos(m2 * e2, q[2], dq[2], ddq[2])
                - _d2_sin(m_b * h, *phi_b)
                + _d2_sin(m_b * (along - v.hip_width / 2), q[1], dq[1], ddq[1]))
        assert full == pytest.approx(paper + omit, abs=1e-9)
    assert abs(m_b * h) > 0.1           # the trunk COM height is a real omission here
    mid = tuple((np.asarray(v.hip_stance) + np.asarray(v.hip_swing)) / 2)

    def on_line(lk):
        return dataclasses.replace(lk, com=tuple(lk.com_along * lk.axis))

    ideal = dataclasses.replace(v, trunk=dataclasses.replace(v.trunk, com=mid),
                                leg_stance=on_line(v.leg_stance), leg_swing=on_line(v.leg_swing))
    front_i = pl.frontal_model(ideal)
    for _ in range(20):
        q, dq, ddq = _front_state(rng, ideal)
        assert pl.inverse_dynamics(front_i, q, dq, ddq)[3] == pytest.approx(
            pl.paper_frontal_y_row(ideal, q, dq, ddq), abs=1e-9)


def test_contact_on_sole(biped, models):
    view = models["left"][0].view
    q_a = np.array(biped.config.standing_joints)
    q_s = np.r_[pl.sagittal_from_actuated(view, q_a, 0.0), 0.0, 0.0]
    # standing pose: sole level (foot frame pitch 0 in Pinocchio)
    data = biped.create_data()
    pin.framesForwardKinematics(biped.model, data, biped.standing_configuration())
    assert pl.stance_foot_pitch(view, q_s) == pytest.approx(
        _pitch(data.oMf[biped.foot_frame["left"]].rotation), abs=1e-12)
    assert pl.contact_on_sole(view, q_s)
    q_s[3] += view.foot_half_angle + 0.1
    assert not pl.contact_on_sole(view, q_s)


# ----------------------------------------------------------------------------- decoupled CoT
def _log(rng, n=400):
    t = np.linspace(0.0, 2.0, n)
    q_a = rng.normal(0, 0.5, (n, 6))
    dq_a = np.column_stack([np.sin((k + 1) * 3.0 * t + k) * (k + 1) for k in range(6)])
    tau_a = np.column_stack([np.cos((k + 2) * 2.0 * t - k) * 4.0 for k in range(6)])
    pitch = 0.1 * np.sin(5.0 * t)
    roll = 0.05 * np.cos(4.0 * t)
    stance = np.where((t // 0.2) % 2 == 0, "left", "right")
    return t, q_a, dq_a, tau_a, pitch, roll, stance


def test_cot_decoupled_exact_is_sum_of_plane_works(biped):
    rng = np.random.default_rng(15)
    t, q_a, dq_a, tau_a, pitch, roll, stance = _log(rng)
    W, d = biped.weight, 0.7
    sag, abd = [1, 2, 4, 5], [0, 3]
    E_s = trapezoid(np.abs(np.sum(tau_a[:, sag] * dq_a[:, sag], axis=1)), t)
    E_f = trapezoid(np.abs(np.sum(tau_a[:, abd] * dq_a[:, abd], axis=1)), t)
    cot = cot_decoupled(t, q_a, dq_a, tau_a, pitch, roll, stance, W, d, biped=biped)
    assert cot == pytest.approx((E_s + E_f) / (W * d), rel=1e-12)
    E_full = trapezoid(np.abs(np.sum(tau_a * dq_a, axis=1)), t)
    assert cot >= E_full / (W * d)
    # constant power: E = |P| T exactly
    n = t.size
    c = cot_decoupled(t, q_a, np.ones((n, 6)), np.full((n, 6), 2.0), pitch, roll, "left",
                      W, d)
    assert c == pytest.approx((4 * 2.0 + 2 * 2.0) * 2.0 / (W * d), rel=1e-12)
    assert math.isnan(cot_decoupled(t, q_a, dq_a, tau_a, pitch, roll, stance, W, 0.0))


def test_cot_decoupled_paper_drops_trunk_and_stance_leg_terms(biped):
    rng = np.random.default_rng(16)
    t, q_a, dq_a, tau_a, pitch, roll, stance = _log(rng)
    dp, dr = 0.5 * np.cos(5.0 * t), -0.2 * np.sin(4.0 * t)
    P_s, P_f = decoupled_power(q_a, dq_a, tau_a, dp, dr, stance, biped=biped,
                               actuation="paper")
    sag, abd = [1, 2, 4, 5], [0, 3]
    st = np.where(stance == "left", 0, 3)
    rows = np.arange(t.size)
    expect_s = np.sum(tau_a[:, sag] * dq_a[:, sag], axis=1) + (tau_a[:, 1] + tau_a[:, 4]) * dp
    expect_f = (np.sum(tau_a[:, abd] * dq_a[:, abd], axis=1)
                - tau_a[rows, st] * (dr + dq_a[rows, st]))
    assert np.allclose(P_s, expect_s, atol=1e-12)
    assert np.allclose(P_f, expect_f, atol=1e-12)
    e = decoupled_energy(t, q_a, dq_a, tau_a, pitch, roll, stance, biped=biped,
                         dtrunk_pitch=dp, dtrunk_roll=dr, actuation="paper")
    assert e.sagittal_J == pytest.approx(trapezoid(np.abs(expect_s), t), rel=1e-12)
    assert e.frontal_J == pytest.approx(trapezoid(np.abs(expect_f), t), rel=1e-12)


def test_cot_decoupled_rejects_bad_input(biped):
    rng = np.random.default_rng(17)
    t, q_a, dq_a, tau_a, pitch, roll, stance = _log(rng, 50)
    W = biped.weight
    none = stance.copy()
    none[3] = "none"
    # 'none' is fine for the exact form (stance-independent), not for the paper's
    assert np.isfinite(cot_decoupled(t, q_a, dq_a, tau_a, pitch, roll, none, W, 1.0))
    with pytest.raises(ConfigError):
        cot_decoupled(t, q_a, dq_a, tau_a, pitch, roll, none, W, 1.0, actuation="paper")
    with pytest.raises(ConfigError):
        cot_decoupled(t, q_a, dq_a, tau_a, pitch, roll, "middle", W, 1.0)
    with pytest.raises(ConfigError):
        cot_decoupled(t, q_a[:, :5], dq_a, tau_a, pitch, roll, stance, W, 1.0)
    with pytest.raises(ConfigError):
        cot_decoupled(t[::-1], q_a, dq_a, tau_a, pitch, roll, stance, W, 1.0)
    with pytest.raises(ConfigError):
        cot_decoupled(t, q_a, dq_a, tau_a, pitch, roll, stance, -1.0, 1.0)
    with pytest.raises(ConfigError):
        cot_decoupled(t, q_a, dq_a, tau_a, pitch, roll, stance, W, 1.0, actuation="full")
