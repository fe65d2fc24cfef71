"""Joint effects (granular_mpc.effects.joint): the library's joint friction through the
plant's joint-effect hook, against M⁻¹ S τ_f computed with Pinocchio."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from granular_mpc.config import SimConfig
from granular_mpc.dynamics import Plant
from granular_mpc.effects import effect_info, joint_torque_function


def test_joint_effect_hook_adds_its_torque_in_the_plant(biped, sand):
    """Plant.forward with a joint effect differs from the plain plant by M⁻¹ S τ_f."""
    info = effect_info("joint_friction")
    fn = joint_torque_function([(info, {"viscous": 0.5, "coulomb": 0.3, "smoothing": 0.2})])
    q = biped.standing_configuration(clearance=0.05)
    v = np.zeros(biped.model.nv)
    v[biped.idx_v] = [1.0, -2.0, 0.5, 0.0, 3.0, -1.0]
    accs = []
    for hook in ((), (fn,)):
        plant = Plant(biped, sand, SimConfig(), joint_effects=hook)
        d = plant.new_data(q, v)
        accs.append(plant.forward(d, d.q, d.v).copy())
    tau_f = np.zeros(biped.model.nv)
    dqa = v[biped.idx_v]
    tau_f[biped.idx_v] = -0.5 * dqa - 0.3 * np.tanh(dqa / 0.2)
    data = biped.create_data()
    M = pin.crba(biped.model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    np.testing.assert_allclose(accs[1] - accs[0], np.linalg.solve(M, tau_f), rtol=1e-8, atol=1e-9)
    assert Plant(biped, sand).joint_effects == ()             # off by default
