"""FastPlant (granular_mpc.dynamics.fast_plant): the reference Plant's interface on the
compiled step — a guide-rig drop onto sand (callable trunk wrench, a torque that changes
every step, feet first clear of the sand, then touchdown and sinkage) gives the same
states and the same read-outs as the reference plant."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from granular_mpc.config import DropConfig, GuideRigConfig, SimConfig
from granular_mpc.dynamics import Plant
from granular_mpc.dynamics.plant import READOUT_FOOT_PARTS, readout_offsets
from granular_mpc.dynamics.fast_plant import FastPlant

DROP, RIG = DropConfig(), GuideRigConfig()


def _rig(q0):
    p0 = q0[0:3].copy()

    def wrench(q, v):
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        f = np.zeros(3)
        f[0:2] = -RIG.stiffness * (q[0:2] - p0[0:2]) - RIG.damping * (R @ v[0:3])[0:2]
        return np.concatenate([f, -RIG.rot_stiffness * pin.log3(R)
                               - RIG.rot_damping * (R @ v[3:6])])
    return wrench


@pytest.mark.parametrize("integrator", ["verlet", "semi_implicit_euler"])
def test_rig_drop_matches_reference(biped, sand, integrator):
    """400 steps (0.2 s) of a 1 cm drop on the rig, PD torques recomputed every step:
    q, v and every read-out of the run log agree with the reference plant."""
    plant = Plant(biped, sand, SimConfig(integrator=integrator))
    fast = FastPlant(plant)
    assert fast.dt == plant.dt and fast.terrain is sand
    q0 = biped.standing_configuration(0.01)
    d_ref, d = plant.new_data(q0), fast.new_data(q0)
    d_ref.base_wrench = d.base_wrench = _rig(q0)
    q_hold = biped.actuated(q0)
    touched = False
    for k in range(400):
        tau = DROP.kp * (q_hold - d_ref.q[biped.idx_q]) - DROP.kd * d_ref.v[biped.idx_v]
        plant.step(d_ref, tau)
        fast.step(d, tau)
        touched |= d_ref.foot_in_contact(0)
        if k % 50 == 49:
            np.testing.assert_allclose(d.q, d_ref.q, atol=1e-10)
            np.testing.assert_allclose(d.v, d_ref.v, atol=1e-7)
            for foot in (0, 1):
                assert d.foot_in_contact(foot) == d_ref.foot_in_contact(foot)
                np.testing.assert_allclose(d.foot_force(foot), d_ref.foot_force(foot),
                                           rtol=1e-7, atol=1e-6)
                np.testing.assert_allclose(d.foot_diag(foot), d_ref.foot_diag(foot),
                                           rtol=1e-7, atol=1e-9)
                np.testing.assert_allclose(d.foot_point(foot), d_ref.foot_point(foot),
                                           atol=1e-10)
    assert touched and d_ref.foot_diag(0)[0] > 0.003       # landed and sank in the sand
    assert d.t == pytest.approx(d_ref.t) and d.steps == d_ref.steps == 400
    np.testing.assert_allclose(d.tau_a, d_ref.tau_a)
    np.testing.assert_allclose(fast.energy(d), plant.energy(d_ref), rtol=1e-8)


@pytest.mark.parametrize("wrench", [None, np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])])
def test_step_n_equals_single_steps(biped, sand, wrench):
    """``step_n(d, n)`` is ``n`` calls of ``step``: a 1 cm drop onto sand (feet clear, then
    touchdown), torques held for 4 or 7 steps at a time, gives the same state, time, step
    count and read-outs bit for bit (foot points included: the last evaluated point of
    each foot is kept per step, not per call)."""
    fast = FastPlant(Plant(biped, sand, SimConfig()))
    q0 = biped.standing_configuration(0.01)
    d1, dn = fast.new_data(q0), fast.new_data(q0)
    d1.base_wrench = dn.base_wrench = wrench
    q_hold = biped.actuated(q0)
    fast.step(d1)
    fast.step(dn)              # started (the Verlet start call is made by step)
    touched = False
    for n in [4, 7] * 30:
        tau = DROP.kp * (q_hold - d1.q[biped.idx_q]) - DROP.kd * d1.v[biped.idx_v]
        d1.set_torque(tau)
        dn.set_torque(tau)
        for _ in range(n):
            fast.step(d1)
        fast.step_n(dn, n)
        touched |= d1.foot_in_contact(0)
        assert np.array_equal(dn.q, d1.q) and np.array_equal(dn.v, d1.v)
        assert dn.t == d1.t and dn.steps == d1.steps
        for foot in (0, 1):
            assert np.array_equal(dn.foot_point(foot), d1.foot_point(foot))
            assert np.array_equal(dn.foot_force(foot), d1.foot_force(foot))
            assert np.array_equal(dn.foot_diag(foot), d1.foot_diag(foot))
            assert dn.foot_in_contact(foot) == d1.foot_in_contact(foot)
    assert touched and dn.steps == 1 + 330


def test_readout_is_the_read_outs_on_both_plants(biped, sand):
    """``readout()`` of the reference and of the compiled plant data is, at the documented
    offsets, exactly q, v, τ_a, per foot the force, point and diagnostics, and the contact
    flags — one foot on the ground, the other in the air."""
    reference = Plant(biped, sand, SimConfig())
    q0 = biped.standing_configuration(-0.004)
    q0[biped.idx_q[biped.joint_names.index("right_knee")]] += 0.5
    nq, nv, na = biped.model.nq, biped.model.nv, len(biped.joint_names)
    off = readout_offsets(nq, nv, na)
    for plant in (reference, FastPlant(reference)):
        d = plant.new_data(q0)
        for _ in range(6):
            plant.step(d, np.linspace(0.3, -0.3, na))
        r = d.readout()
        assert r.shape == (off["size"],)
        assert np.array_equal(r[off["q"]:off["q"] + nq], d.q)
        assert np.array_equal(r[off["v"]:off["v"] + nv], d.v)
        assert np.array_equal(r[off["tau_a"]:off["tau_a"] + na], d.tau_a)
        reads = {"force": d.foot_force, "point": d.foot_point, "diag": d.foot_diag}
        for foot in (0, 1):
            for part, n in READOUT_FOOT_PARTS:
                assert np.array_equal(r[off[foot, part]:off[foot, part] + n], reads[part](foot))
        flags = [d.foot_in_contact(0), d.foot_in_contact(1)]
        assert flags == [True, False]
        assert r[off["contact"]:off["contact"] + 2].tolist() == [1.0, 0.0]
