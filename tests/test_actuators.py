"""Joint losses and motor model of the plant (granular_mpc.dynamics.actuators, ``sim.actuators``):
config, bit-identical defaults, friction by energy dissipation and viscous decay, reflected
inertia, torque–speed clipping, Verlet's torque correction, electrical power."""
from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from granular_mpc.config import SimConfig, load_terrain, validate
from granular_mpc.config.scenario import ActuatorsConfig
from granular_mpc.dynamics import Plant
from granular_mpc.dynamics.actuators import ActuatorModel
from granular_mpc.exceptions import ConfigError
from granular_mpc.scenario import load_scenario
from granular_mpc.terrain import build_terrain

#: Mini-Cheetah-class defaults (docs/model.md §3.1), written out independently here
TAU_C, B_VISC, OMEGA_S = 0.2, 0.01, 0.1
GEAR = np.array([6.0, 6.0, 9.33] * 2)
J_ROTOR = 63e-6


def _sim(actuators: dict, **kw) -> SimConfig:
    return validate(SimConfig, {"actuators": actuators, **kw}, prefix="sim")


def _full(M):
    return np.triu(M) + np.triu(M, 1).T


def _friction(dq, tau_c=TAU_C, b=B_VISC, w=OMEGA_S):
    """τ_f = −τ_c tanh(q̇/ω_s) − b q̇, written out here (not the package's)."""
    return -tau_c * np.tanh(dq / w) - b * dq


@pytest.fixture(scope="module")
def far(robot_config):
    """Terrain 100 m below: the robot floats free (uniform gravity moves only the base)."""
    return build_terrain(load_terrain("rigid", surface_height=-100.0), robot_config)


# ------------------------------------------------------------------ config


def test_defaults_are_ideal_actuators(biped):
    """Off by default: no friction, no motor, no armature; the documented defaults."""
    sim = SimConfig()
    assert not sim.actuators.friction.enabled and not sim.actuators.motor.enabled
    act = ActuatorModel.from_config(sim.actuators, biped.torque_limits)
    assert not act.active and not act.armature.any()
    np.testing.assert_array_equal(act.coulomb, [TAU_C] * 6)
    np.testing.assert_array_equal(act.viscous, [B_VISC] * 6)
    np.testing.assert_array_equal(act.gear_ratio, GEAR)
    np.testing.assert_array_equal(act.peak_torque, [18, 18, 28, 18, 18, 28])  # the URDF
    assert act.velocity_scale == OMEGA_S


@pytest.mark.parametrize("override, key", [
    ("sim.actuators.friction.coulomb=-0.1", "sim.actuators.friction.coulomb"),
    ("sim.actuators.friction.viscous=[0.01, -0.02, 0.0]", "sim.actuators.friction.viscous"),
    ("sim.actuators.friction.velocity_scale=0", "sim.actuators.friction.velocity_scale"),
    ("sim.actuators.motor.gear_ratio=0", "sim.actuators.motor.gear_ratio"),
    ("sim.actuators.motor.rotor_inertia=-1e-6", "sim.actuators.motor.rotor_inertia"),
    ("sim.actuators.friction.coulomb=[0.1, 0.2]", "sim.actuators.friction.coulomb"),
])
def test_bad_values_rejected_naming_the_key(override, key):
    """Negative friction (and other out-of-range values, wrong list lengths) → ConfigError
    naming the dotted key."""
    with pytest.raises(ConfigError) as err:
        load_scenario("sand_walk", [override])
    assert err.value.key == key
    assert key in str(err.value)


def test_unknown_actuator_key_rejected_with_hint():
    with pytest.raises(ConfigError) as err:
        load_scenario("sand_walk", ["sim.actuators.motor.gear=6"])
    assert "gear" in err.value.key and "did you mean 'gear_ratio'" in str(err.value)


def test_per_joint_forms(biped):
    """One number → every joint; three → (abd, hip, knee) on both legs; six → as given."""
    cfg = validate(ActuatorsConfig, {"friction": {"coulomb": 0.3, "viscous": [0.1, 0.2, 0.3],
                                                  "enabled": True},
                                     "motor": {"gear_ratio": [1, 2, 3, 4, 5, 6]}})
    act = ActuatorModel.from_config(cfg, biped.torque_limits)
    np.testing.assert_array_equal(act.coulomb, [0.3] * 6)
    np.testing.assert_array_equal(act.viscous, [0.1, 0.2, 0.3, 0.1, 0.2, 0.3])
    np.testing.assert_array_equal(act.gear_ratio, [1, 2, 3, 4, 5, 6])


def test_too_stiff_friction_refused_at_plant_build(biped, far):
    """A tanh velocity scale so small that the explicit step would chatter is refused."""
    with pytest.raises(ConfigError) as err:
        Plant(biped, far, _sim({"friction": {"enabled": True, "velocity_scale": 0.01}}))
    assert err.value.key == "sim.actuators.friction.velocity_scale"
    Plant(biped, far, _sim({"friction": {"enabled": True, "velocity_scale": 0.01}}, dt=5e-5))


# ------------------------------------------------------------------ defaults: bit-identical


def _pd(biped, d, k):
    qs = np.asarray(biped.config.standing_joints)
    return 150.0 * (qs - d.q[biped.idx_q]) - 3.0 * d.v[biped.idx_v] + 0.5 * math.sin(0.01 * k)


def test_defaults_bit_identical_to_plain_pinocchio_verlet(biped, far):
    """With the default (ideal) actuators, the plant's step is exactly the plain Verlet
    step written here with Pinocchio alone (no contact: the ground is 100 m down):
    array_equal on q, v and a after 300 steps with a changing torque."""
    plant = Plant(biped, far, SimConfig())
    assert plant.model is biped.model
    model, data = biped.model, biped.model.createData()
    fext = pin.StdVec_Force()
    for _ in range(model.njoints):
        fext.append(pin.Force.Zero())
    v0 = np.zeros(model.nv)
    v0[biped.idx_v] = [0.3, -1.0, 2.0, 0.5, 0.0, -0.7]
    d = plant.new_data(biped.standing_configuration(), v0)
    q, v, dt = d.q.copy(), d.v.copy(), plant.dt
    tau, tau_prev, a = np.zeros(model.nv), np.zeros(model.nv), None
    for k in range(300):
        tau_a = _pd(biped, d, k)
        plant.step(d, tau_a)
        tau[biped.idx_v] = tau_a
        if a is None:
            pin.forwardKinematics(model, data, q, v)
            a = pin.aba(model, data, q, v, tau, fext).copy()
        else:
            a = a + pin.computeMinverse(model, data, q) @ (tau - tau_prev)
        v_half = v + 0.5 * dt * a
        q = pin.integrate(model, q, v_half * dt)
        pin.forwardKinematics(model, data, q, v_half)
        a = pin.aba(model, data, q, v_half + 0.5 * dt * a, tau, fext).copy()
        v = v_half + 0.5 * dt * a
        tau_prev = tau.copy()
        assert np.array_equal(d.q, q) and np.array_equal(d.v, v) and np.array_equal(d.a, a)


@pytest.mark.parametrize("integrator", ["verlet", "semi_implicit_euler"])
def test_switched_off_options_leave_the_plant_bit_identical(biped, sand, integrator):
    """On sand: SimConfig() and actuators explicitly off but with every parameter far from
    its default step the same state to identical bits (array_equal)."""
    off = _sim({"friction": {"enabled": False, "coulomb": 5.0, "viscous": 1.0},
                "motor": {"enabled": False, "gear_ratio": 50.0, "rotor_inertia": 1e-3,
                          "peak_torque": 1.0}}, integrator=integrator)
    plants = [Plant(biped, sand, SimConfig(integrator=integrator)), Plant(biped, sand, off)]
    datas = [p.new_data(biped.standing_configuration(-0.005)) for p in plants]
    for k in range(400):
        for p, d in zip(plants, datas):
            p.step(d, _pd(biped, d, k))
    for name in ("q", "v", "a"):
        assert np.array_equal(getattr(datas[0], name), getattr(datas[1], name)), name
    assert np.array_equal(datas[0].foot_force(0), datas[1].foot_force(0))
    assert np.array_equal(datas[1].tau_motor, datas[1].tau_a)       # ideal: delivered = command
    assert not datas[1].tau_friction.any()


# ------------------------------------------------------------------ friction


@pytest.mark.parametrize("motor", [False, True])
def test_friction_energy_lost_equals_friction_work(biped, far, motor):
    """Free-floating robot, zero command, joints released at 0.5–3 rad/s: the mechanical
    energy lost (KE + PE; with the motor, KE includes the rotors) equals −∫ τ_f·q̇ dt,
    integrated by brute force (trapezoid over every step) with τ_f written out here."""
    plant = Plant(biped, far, _sim({"friction": {"enabled": True},
                                    "motor": {"enabled": motor}}))
    v0 = np.zeros(12)
    v0[biped.idx_v] = [1.0, -2.0, 3.0, -0.5, 1.5, -2.5]
    d = plant.new_data(biped.standing_configuration(), v0)
    iv = biped.idx_v
    energy = [sum(plant.energy(d))]
    power = [_friction(d.v[iv]) @ d.v[iv]]
    for _ in range(600):                       # 0.3 s
        plant.step(d, np.zeros(6))
        energy.append(sum(plant.energy(d)))
        power.append(_friction(d.v[iv]) @ d.v[iv])
    energy, power = np.array(energy), np.array(power)
    work = np.concatenate([[0.0], np.cumsum(0.5 * plant.dt * (power[1:] + power[:-1]))])
    lo, hi = biped.position_limits
    assert np.all((d.q[biped.idx_q] > lo) & (d.q[biped.idx_q] < hi))   # no end stop touched
    assert work[-1] < -0.05                                  # a real loss …
    assert np.abs(d.v[iv]).max() < 0.01                     # … that stopped the joints
    np.testing.assert_allclose(energy[-1] - energy[0], work[-1], rtol=2e-3)
    assert np.abs(energy - energy[0] - work).max() < 1e-4    # along the whole path [J]


def test_energy_conserved_without_friction(biped, far):
    """The same release without friction keeps its energy (so the loss above is friction)."""
    plant = Plant(biped, far, SimConfig())
    v0 = np.zeros(12)
    v0[biped.idx_v] = [1.0, -2.0, 3.0, -0.5, 1.5, -2.5]
    d = plant.new_data(biped.standing_configuration(), v0)
    e0 = sum(plant.energy(d))
    for _ in range(600):
        plant.step(d, np.zeros(6))
    assert abs(sum(plant.energy(d)) - e0) < 1e-5


def test_viscous_decay_matches_exponential(biped, far):
    """Viscous friction b on the left knee only (τ_c = 0): the knee's rate decays as
    exp(−b t / I_eff), I_eff = 1/(M⁻¹)_kk its effective inertia with the rest of the
    free-floating robot free. Tiny rates (1e-4 rad/s): the configuration does not move and
    the velocity-product terms vanish. The fitted rate exceeds b/I_eff by the integrator's
    first-order bias, k dt / 2 (k = b/I_eff), and by nothing else."""
    b = 0.02
    plant = Plant(biped, far, _sim({"friction": {"enabled": True, "coulomb": 0.0,
                                                 "viscous": [0, 0, b, 0, 0, 0]}}))
    q0 = biped.standing_configuration()
    k = int(biped.idx_v[2])
    minv = _full(pin.computeMinverse(biped.model, biped.model.createData(), q0))
    i_eff = 1.0 / minv[k, k]
    rate0 = 1e-4
    v0 = np.zeros(12)
    v0[k] = rate0
    d = plant.new_data(q0, v0)
    t, rate = [0.0], [rate0]
    for _ in range(1000):                      # 0.5 s ≈ 2.6 time constants
        plant.step(d, np.zeros(6))
        t.append(d.t)
        rate.append(d.v[k])
    t, rate = np.array(t), np.array(rate)
    np.testing.assert_allclose(rate, rate0 * np.exp(-b * t / i_eff), rtol=5e-3, atol=0.0)
    fitted = -np.polyfit(t, np.log(rate), 1)[0]
    assert fitted == pytest.approx(b / i_eff, rel=2e-3)
    bias = 0.5 * (b / i_eff) * plant.dt
    assert fitted / (b / i_eff) - 1.0 == pytest.approx(bias, abs=5e-5)


@pytest.mark.parametrize("integrator", ["verlet", "semi_implicit_euler"])
def test_coulomb_friction_stops_joints_without_chatter(biped, far, integrator):
    """Default friction at dt = 0.5 ms, a knee released at 2 rad/s: every joint's rate
    settles without chatter — at most two sign changes of the rate and five reversals of
    its trend in 600 steps (a chattering regularised sign flips every step: with
    ω_s = 0.01 rad/s, which the plant refuses, semi-implicit Euler flips ≈ 500 times) —
    and ends below 1e-3 rad/s (what remains is the creep ω_s atanh(τ/τ_c) under the
    centrifugal load of the slowly tumbling robot)."""
    plant = Plant(biped, far, _sim({"friction": {"enabled": True}}, integrator=integrator))
    v0 = np.zeros(12)
    v0[int(biped.idx_v[2])] = 2.0
    d = plant.new_data(biped.standing_configuration(), v0)
    rates = []
    for _ in range(600):
        plant.step(d, np.zeros(6))
        rates.append(d.v[biped.idx_v].copy())
    rates = np.array(rates)
    sign_changes = (np.diff(np.sign(rates), axis=0) != 0).sum(axis=0)
    reversals = (np.diff(np.sign(np.diff(rates, axis=0)), axis=0) != 0).sum(axis=0)
    assert sign_changes.max() <= 2 and reversals.max() <= 5
    assert np.abs(rates[-1]).max() < 1e-3
    assert rates[0, 2] < 2.0 and rates[-1, 2] < 0.01 * rates[0, 2]     # the knee stopped


# ------------------------------------------------------------------ motor


def test_reflected_inertia_adds_n2_jr_to_the_knee(biped, far):
    """Rotor inertia on the left knee only: under a known knee torque at rest the knee's
    acceleration is τ/(I_eff + N² J_r), I_eff = τ/a from the plant without the motor."""
    tau_k = 2.0
    q0 = biped.standing_configuration()
    acc = []
    for motor in (False, True):
        plant = Plant(biped, far, _sim({"motor": {"enabled": motor, "torque_speed_limit": False,
                                                  "rotor_inertia": [0, 0, J_ROTOR, 0, 0, 0]}}))
        d = plant.new_data(q0)
        d.set_torque(np.zeros(6))
        a0 = plant.forward(d, d.q, d.v)[biped.idx_v[2]]    # ≈ 0 (free fall)
        d.set_torque([0, 0, tau_k, 0, 0, 0])
        acc.append(plant.forward(d, d.q, d.v)[biped.idx_v[2]] - a0)
    i_eff = tau_k / acc[0]
    assert acc[1] == pytest.approx(tau_k / (i_eff + 9.33 ** 2 * J_ROTOR), rel=1e-10)
    assert acc[1] < 0.5 * acc[0]                         # a large effect on the light calf


def test_armature_matches_independent_mass_matrix(biped, far):
    """Default motor (all joints): the plant's acceleration solves
    (M + diag(N² J_r)) a = S τ − h with M, h from the plain model (CRBA, RNEA) and the
    armature added here — Pinocchio's ABA honours ``model.armature``. The controller's model
    (``biped.model``) keeps no armature."""
    plant = Plant(biped, far, _sim({"motor": {"enabled": True}}))
    rng = np.random.default_rng(3)
    lo, hi = biped.position_limits
    model, data = biped.model, biped.model.createData()
    arm = np.zeros(12)
    arm[biped.idx_v] = GEAR ** 2 * J_ROTOR
    for _ in range(5):
        q = biped.q_from_parts([0, 0, 1.0], [0, 0, 0, 1], rng.uniform(lo, hi))
        v = rng.normal(size=12)
        tau_a = rng.uniform(-5, 5, 6)                    # inside every envelope
        d = plant.new_data(q, v)
        d.set_torque(tau_a)
        a = plant.forward(d, d.q, d.v)
        M = _full(pin.crba(model, data, q)) + np.diag(arm)
        h = pin.rnea(model, data, q, v, np.zeros(12))
        tau = np.zeros(12)
        tau[biped.idx_v] = tau_a
        np.testing.assert_allclose(a, np.linalg.solve(M, tau - h), rtol=1e-9, atol=1e-9)
    assert not biped.model.armature.any()
    assert plant.model is not biped.model


def test_torque_speed_envelope_values(biped):
    """τ_max(q̇) = min(τ_peak, τ_stall (1 − |q̇|/q̇_0)) motoring, τ_peak braking; worked
    values for the knee (τ_stall 97.1, q̇_0 25.7, τ_peak 28 N·m)."""
    act = ActuatorModel.from_config(
        validate(ActuatorsConfig, {"motor": {"enabled": True}}), biped.torque_limits)
    k = 2

    def delivered(tau, dq):
        cmd, rate = np.zeros(6), np.zeros(6)
        cmd[k], rate[k] = tau, dq
        return act.motor_torque(cmd, rate)[k]

    line = lambda dq: 97.1 * (1.0 - abs(dq) / 25.7)  # noqa: E731
    assert delivered(10.0, 5.0) == 10.0                  # inside: unchanged
    assert delivered(40.0, 0.0) == 28.0                  # peak at rest
    assert delivered(-40.0, 5.0) == -28.0                # braking: peak
    assert delivered(40.0, 20.0) == pytest.approx(line(20.0))       # 21.5 N·m on the line
    assert delivered(-40.0, -20.0) == pytest.approx(-line(20.0))
    assert delivered(40.0, -20.0) == 28.0                # braking at speed: peak
    assert delivered(5.0, 30.0) == 0.0                   # beyond no-load speed
    assert delivered(-5.0, 30.0) == -5.0
    off = ActuatorModel.from_config(ActuatorsConfig(), biped.torque_limits)
    assert off.motor_torque(np.full(6, 1e3), np.full(6, 30.0))[k] == 1e3   # ideal


def test_plant_applies_the_clipped_torque(biped, far):
    """A saturating command at a fast joint accelerates the plant exactly as the clipped
    torque does on a plant without the limit (same armature)."""
    limited = Plant(biped, far, _sim({"motor": {"enabled": True}}))
    free = Plant(biped, far, _sim({"motor": {"enabled": True, "torque_speed_limit": False}}))
    v = np.zeros(12)
    v[biped.idx_v] = [5.0, -25.0, 20.0, 0.0, 10.0, -1.0]
    q = biped.standing_configuration()
    cmd = np.array([30.0, -30.0, 30.0, -30.0, 30.0, 30.0])
    expected = [18.0, -min(18.0, 62.4 * (1 - 25 / 40)), 97.1 * (1 - 20 / 25.7), -18.0,
                18.0, 28.0]
    d1 = limited.new_data(q, v)
    d1.set_torque(cmd)
    d2 = free.new_data(q, v)
    d2.set_torque(expected)
    np.testing.assert_allclose(limited.forward(d1, d1.q, d1.v), free.forward(d2, d2.q, d2.v),
                               rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(d1.tau_motor, expected, rtol=1e-12)


def test_verlet_torque_correction_uses_the_delivered_torque(biped, far):
    """Verlet reuses the last acceleration and corrects it by M⁻¹Δτ when the command
    changes: with the envelope clipping, Δτ must be the change of the *delivered* torque.
    The acceleration actually used by a step (recovered from the half-step velocity)
    equals a fresh evaluation at the previous step's evaluation point with the new command."""
    acts = {"friction": {"enabled": True},
            "motor": {"enabled": True, "peak_torque": 40.0, "stall_torque": 10.0,
                      "no_load_speed": 5.0}}
    plant = Plant(biped, far, _sim(acts))
    dt = plant.dt
    sign = np.array([1, 1, 1, -1, 1, -1.0])
    d = plant.new_data(biped.standing_configuration())
    a_hist = []
    for k in range(40):
        plant.step(d, sign * (30.0 if k % 2 else 35.0))
        a_hist.append(d.a.copy())
    assert np.abs(d.v[biped.idx_v]).min() > 2.0          # fast: on the voltage line
    q_n, v_n, a_n, a_prev = d.q.copy(), d.v.copy(), a_hist[-1], a_hist[-2]
    v_half = v_n - 0.5 * dt * a_n                        # where a_n was evaluated
    v_dyn = v_half + 0.5 * dt * a_prev
    new_cmd = sign * 12.0
    fresh = plant.new_data(q_n, v_n)
    fresh.set_torque(new_cmd)
    expected = plant.forward(fresh, q_n, v_half, v_dyn)
    plant.step(d, new_cmd)
    used = (d.v - 0.5 * dt * d.a - v_n) * 2.0 / dt
    np.testing.assert_allclose(used, expected, rtol=1e-7, atol=1e-6)
    # correcting by the command's own change (last command: 30 N·m) would be far off
    minv = _full(pin.computeMinverse(plant.model, plant.model.createData(), q_n))
    naive = a_n + minv @ np.r_[np.zeros(6), new_cmd - sign * 30.0]
    assert np.abs(naive - expected).max() > 100.0


def test_electrical_power_worked_example(biped, far):
    """P = τ q̇ + R_w (τ/(k_t N))²: knee 10 N·m at 2 rad/s, N = 9.33, k_t = 0.075 N·m/A,
    R_w = 0.2595 Ω → i = 14.29 A, copper 53.0 W, total 73.0 W; at rest holding, copper only;
    back-driven (τ q̇ < 0) the mechanical part is negative."""
    act = ActuatorModel.from_config(ActuatorsConfig(), biped.torque_limits)
    tau = np.array([0, 0, 10.0, 0, 0, -10.0])
    dq = np.array([0, 0, 2.0, 0, 0, 2.0])
    p = act.electrical_power(tau, dq)
    i = 10.0 / (9.33 * 0.075)
    assert p[2] == pytest.approx(20.0 + 0.2595 * i ** 2, rel=1e-12)
    assert p[2] == pytest.approx(73.0, abs=0.1)
    assert p[5] == pytest.approx(-20.0 + 0.2595 * i ** 2, rel=1e-12)
    assert p[0] == 0.0
    # the per-step read-out uses the delivered torque and the current rates
    plant = Plant(biped, far, SimConfig())
    v = np.zeros(12)
    v[biped.idx_v] = dq
    d = plant.new_data(biped.standing_configuration(), v)
    d.set_torque(tau)
    np.testing.assert_allclose(d.electrical_power, p, rtol=1e-12)
