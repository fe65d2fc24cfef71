"""Replay of one stance window on the 3-D plant (the ``granular`` model).

The augmented plant (:class:`~granular_mpc.dynamics.Plant`) with the terrain model (RFT
closed form, elastic–plastic contact, bulldozing, added mass) and the variant's joint
effects, driven by the measured torques; both feet start in contact as measured at the
window start (local frame of :mod:`..prepare`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ...dynamics import Plant
from ...exceptions import PlantDivergedError
from ...robot.model import SIDES, Biped
from ...effects import joint_torque_function
from ..prepare import StanceWindow, patch_points
from .model import ReplayModel, Variant
from .outputs import replay_outputs, set_foot_state


def _patch_velocity(biped: Biped, data: pin.Data, side: str, pts: np.ndarray) -> np.ndarray:
    fid = biped.foot_frame[side]
    vel = pin.getFrameVelocity(biped.model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    p_F = data.oMf[fid].translation
    return np.array([vel.linear + np.cross(vel.angular, p - p_F) for p in pts])


def replay_granular(model: ReplayModel, w: StanceWindow, variant: Variant) -> dict:
    """Replay one window on the 3-D plant with the measured torques.

    Returns:
        ``{channel: (n,) array}`` for :func:`~.prepare.channel_names` plus ``other_grf_z``
        (the other foot's vertical force) and ``diverged`` (bool). Sensor effects of the
        variant are applied to the outputs.
    """
    biped = model.biped
    jfn = joint_torque_function(list(variant.joints))
    plant = Plant(biped, model.terrain, model.sim, joint_effects=() if jfn is None else (jfn,))
    d = plant.new_data(w.q0, w.v0)
    cd = d.contact
    theta = model.theta_vector(variant.theta)
    names = model.terrain.param_names
    i_h = names.index("surface_height")
    sx = theta[names.index("surface_slope_x")]
    sy = theta[names.index("surface_slope_y")]
    pin.forwardKinematics(biped.model, d.pin, d.q, d.v)
    pin.updateFramePlacements(biped.model, d.pin)
    dz = float(variant.theta.get("touchdown_depth", 0.0))
    for i, fi in enumerate(w.feet):
        buf = cd.feet[i]
        buf.params[:] = theta
        buf.params[i_h] = fi.surface + dz - sx * fi.point[0] - sy * fi.point[1]
        if fi.in_contact:
            side = SIDES[i]
            pts = patch_points(biped, d.pin.oMf[biped.foot_frame[side]])
            set_foot_state(buf, fi, _patch_velocity(biped, d.pin, side, pts))
    J = biped.joint_names
    n = w.n
    qa = np.full((n, len(J)), np.nan)
    grf = np.full((n, 3), np.nan)
    intr = np.full((n, 3), np.nan)
    other = np.full(n, np.nan)
    i, o = w.foot, 1 - w.foot
    sps = model.steps_per_sample
    diverged = False

    def record(k):
        qa[k] = d.q[biped.idx_q]
        if d.foot_in_contact(i):
            grf[k] = d.foot_force(i)
            intr[k] = d.foot_diag(i)[2:5]
        else:
            grf[k] = 0.0
            intr[k] = 0.0
        other[k] = d.foot_force(o)[2] if d.foot_in_contact(o) else 0.0

    try:
        for k in range(n):
            tau = w.tau[k]
            for _ in range(sps):
                plant.step(d, tau)
            record(k)
    except PlantDivergedError:
        diverged = True
    return replay_outputs(qa, grf, intr, other, diverged, variant, w, J)


__all__ = ["replay_granular"]
