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
