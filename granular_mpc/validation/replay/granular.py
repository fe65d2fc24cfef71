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

The plant stepped is the compiled one (:meth:`~.model.ReplayModel.replay_plant`: each foot
its own terrain θ, joint-effect parameters in θ, one compiled model for every variant)
unless the model asks for the reference plant or the compiled one does not model the
variant (then the reference :class:`~granular_mpc.dynamics.Plant`, named in the choice);
both read and write the same per-foot contact buffers (``d.contact.feet[i]``).
``tests/test_fast_path.py`` checks that both give the same replay.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

from ...dynamics import FastPlant
from ...dynamics.step_sx import aux_foot
from ...exceptions import PlantDivergedError
from ...robot.model import SIDES, Biped
from ..prepare import FootInit, StanceWindow, patch_points
from .measurement import true_window
from .model import ReplayModel, Variant
from .outputs import replay_outputs, set_foot_state


def _patch_velocity(biped: Biped, data: pin.Data, side: str, pts: np.ndarray) -> np.ndarray:
    fid = biped.foot_frame[side]
    vel = pin.getFrameVelocity(biped.model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    p_F = data.oMf[fid].translation
    return vel.linear + np.cross(vel.angular, pts - p_F)   # rows: the products one by one


def _in_world(fi: FootInit, origin: np.ndarray) -> FootInit:
    """A foot's initial contact state moved by ``origin`` (x, y: to the world's)."""
    return replace(fi, surface=float(fi.surface + origin[2]), point=fi.point + origin,
                   c0=fi.c0 + origin)


def segment_windows(w: StanceWindow) -> list[StanceWindow]:
    """``w`` cut at its restarts (:mod:`~..restarts`): one window per replay segment, each
    with its own first state and the samples, torques and columns of its part; ``[w]``
    without restarts."""
    if not w.restarts:
        return [w]
    cuts = [0, *(r.start for r in w.restarts), w.n]
    firsts = [(w.q0, w.v0, w.feet), *((r.q0, r.v0, r.feet) for r in w.restarts)]
    out = []
    for (a, b), (q0, v0, feet) in zip(zip(cuts[:-1], cuts[1:]), firsts):
        sl = slice(a, b)
        out.append(replace(w, q0=q0, v0=v0, feet=feet, tau=w.tau[sl], time=w.time[sl],
                           phase=w.phase[sl], meas={c: v[sl] for c, v in w.meas.items()},
                           features={c: v[sl] for c, v in w.features.items()},
                           columns={c: v[sl] for c, v in w.columns.items()}, restarts=()))
    return out


def replay_granular(model: ReplayModel, w: StanceWindow, variant: Variant) -> dict:
    """Replay one window on the 3-D plant with the measured torques (segment by segment
    when the window has restarts: :func:`segment_windows`).

    Returns:
        ``{channel: (n,) array}`` for :func:`~.prepare.channel_names` plus ``other_grf_z``
        (the other foot's vertical force) and ``diverged`` (bool: some segment diverged).
        Sensor effects of the variant are applied to the outputs.
    """
    parts = [_replay_segment(model, seg, variant) for seg in segment_windows(w)]
    qa, grf, intr, other = (np.concatenate([p[k] for p in parts]) for k in range(4))
    diverged = any(p[4] for p in parts)
    return replay_outputs(qa, grf, intr, other, diverged, variant, w, model.biped.joint_names)


def _replay_segment(model: ReplayModel, w: StanceWindow, variant: Variant) -> tuple:
    """One replay from the window's first state: (q_a, stance-foot force, intrusion, other
    foot's vertical force, diverged), one row per sample."""
    biped = model.biped
    w = true_window(biped, w, variant)
    origin = np.array([w.origin[0], w.origin[1], 0.0])
    q0 = w.q0.copy()
    q0[0:3] += origin                        # local frame → the world's x, y
    plant, _choice = model.replay_plant(variant)
    fast = isinstance(plant, FastPlant)
    # the compiled plant's reusable data, reset (same start as a new one, no rebuild)
    d = plant.scratch_data(q0, w.v0) if fast else plant.new_data(q0, w.v0)
    if fast:                                 # the variant's joint-effect parameters
        set_joint_params(plant, d, variant)
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
    run = _run_compiled if fast else _run_reference
    return run(plant, d, w, model.steps_per_sample)


def _run_reference(plant, d, w: StanceWindow, sps: int) -> tuple:
    """Step the reference plant through the window: (q_a, stance-foot force, intrusion,
    other foot's vertical force, diverged), one row per sample (NaN after a divergence)."""
    biped = plant.biped
    n = w.n
    qa = np.full((n, len(biped.idx_q)), np.nan)
    grf = np.full((n, 3), np.nan)
    intr = np.full((n, 3), np.nan)
    other = np.full(n, np.nan)
    i, o = w.foot, 1 - w.foot
    try:
        for k in range(n):
            tau = w.tau[k]
            for _ in range(sps):
                plant.step(d, tau)
            qa[k] = d.q[biped.idx_q]
            if d.foot_in_contact(i):
                grf[k] = d.foot_force(i)
                intr[k] = d.foot_diag(i)[2:5]
            else:
                grf[k] = 0.0
                intr[k] = 0.0
            other[k] = d.foot_force(o)[2] if d.foot_in_contact(o) else 0.0
    except PlantDivergedError:
        return qa, grf, intr, other, True
    return qa, grf, intr, other, False


def _run_compiled(plant: FastPlant, d, w: StanceWindow, sps: int) -> tuple:
    """:func:`_run_reference` on the compiled plant: ``sps`` steps per compiled call
    (the replay's plant is built with ``chunk = steps_per_sample``), the state and the
    auxiliary output kept per sample, the channels computed from them at the end."""
    c = plant.compiled
    L = c.layout
    n = w.n
    X, A, done = c.advance_samples(d.data, w.tau[:n], sps)
    diverged = done < n
    i, o = w.foot, 1 - w.foot
    flags = X[:, L.contact].reshape(n, 2, L.n_patches, L.patch_state)[:, :, :, 6].max(axis=2)
    on_i, on_o = (flags[:, i] > 0.5)[:, None], flags[:, o] > 0.5
    qa = X[:, L.q][:, plant.biped.idx_q]
    grf = np.where(on_i, aux_foot(A, i, "force"), 0.0)
    intr = np.where(on_i, aux_foot(A, i, "diag")[:, 2:5], 0.0)
    other = np.where(on_o, aux_foot(A, o, "force")[:, 2], 0.0)
    for arr in (qa, grf, intr, other):
        arr[done:] = np.nan                  # as the reference: nothing after a divergence
    return qa, grf, intr, other, diverged


def set_joint_params(plant: FastPlant, d, variant: Variant) -> None:
    """Write the variant's joint-effect parameters into the compiled plant's θ (the
    compiled joint effects the variant does not use stay at their neutral values)."""
    c = plant.compiled
    k0 = c.layout.joint_theta.start
    given = {info.name: p for info, p in variant.joints}
    for info in c.joint_params:
        if info.name in given:
            p = given[info.name]
            d.data.theta[k0:k0 + len(info.params)] = [float(p[k]) for k in info.params]
        k0 += len(info.params)


__all__ = ["replay_granular", "segment_windows", "set_joint_params"]
