"""Replay of one stance window on the 3-D plant (the ``granular`` model).

The augmented plant (:class:`~granular_mpc.dynamics.Plant`) with the terrain model (RFT
closed form, elastic–plastic contact, bulldozing, added mass) and the variant's joint
effects, driven by the measured torques; both feet start in contact as measured at the
window start. The replay runs in the data set's horizontal world coordinates: the
window's local frame (:mod:`..prepare`, a translation by ``w.origin``) is moved back in x
and y, so a terrain-force effect reads the contact point ``PatchState.p_c`` at the same
world x, y as in ``synth`` (the dynamics do not depend on the translation). Heights stay
measured from the free surface under the stance foot's touchdown point, which is the
world z of ``synth`` (its sand surface is at z = 0) and, for lab data, the only height
the data define. With sensor effects, the initial state and the torques are the true
ones (:func:`~.measurement.true_window`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

from ...dynamics import Plant
from ...exceptions import PlantDivergedError
from ...robot.model import SIDES, Biped
from ...effects import joint_torque_function
from ..prepare import FootInit, StanceWindow, patch_points
from .measurement import true_window
from .model import ReplayModel, Variant
from .outputs import replay_outputs, set_foot_state


def _patch_velocity(biped: Biped, data: pin.Data, side: str, pts: np.ndarray) -> np.ndarray:
    fid = biped.foot_frame[side]
    vel = pin.getFrameVelocity(biped.model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    p_F = data.oMf[fid].translation
    return np.array([vel.linear + np.cross(vel.angular, p - p_F) for p in pts])


def _in_world(fi: FootInit, origin: np.ndarray) -> FootInit:
    """A foot's initial contact state moved by ``origin`` (x, y: to the world's)."""
    return replace(fi, surface=float(fi.surface + origin[2]), point=fi.point + origin,
                   c0=fi.c0 + origin)


def replay_granular(model: ReplayModel, w: StanceWindow, variant: Variant) -> dict:
    """Replay one window on the 3-D plant with the measured torques.

    Returns:
        ``{channel: (n,) array}`` for :func:`~.prepare.channel_names` plus ``other_grf_z``
        (the other foot's vertical force) and ``diverged`` (bool). Sensor effects of the
        variant are applied to the outputs.
    """
    biped = model.biped
    scored = w
    w = true_window(biped, w, variant)
    origin = np.array([w.origin[0], w.origin[1], 0.0])
    q0 = w.q0.copy()
    q0[0:3] += origin                        # local frame → the world's x, y
    jfn = joint_torque_function(list(variant.joints))
    plant = Plant(biped, model.terrain, model.sim, joint_effects=() if jfn is None else (jfn,))
    d = plant.new_data(q0, w.v0)
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
        fi = _in_world(fi, origin)
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
    return replay_outputs(qa, grf, intr, other, diverged, variant, scored, J)


__all__ = ["replay_granular"]
