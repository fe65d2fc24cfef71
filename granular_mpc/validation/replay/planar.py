"""Replay of one stance window on the paper's decoupled planar models (``planar``).

Paper Sec. II: sagittal 7-DoF and frontal 5-DoF (:mod:`granular_mpc.dynamics.planar`)
driven by the mapped torques; each foot's force from the 3-D terrain law evaluated on its
planar kinematics (x, z to the sagittal model; y, z to the frontal one).

Opt-in ablation (``bench/paper_gaps.py``; the default is the paper's model): ``frontal``
— what the terrain law sees of the stance foot's frontal-plane state: ``"model"`` (the
frontal model's lateral position and velocity, no foot roll), ``"measured"`` (the measured
3-D plant's lateral position, velocity and foot roll), ``"measured_roll"`` (only the
measured foot roll), ``"measured_lateral"`` (only the measured lateral position and
velocity); ``moment`` — ``"drop"`` (the paper's: the terrain force acts through the contact
coordinates only) or ``"apply"`` (also its moment about the sole-arc centre);
``swing_force`` — ``"terrain"`` or ``"off"`` (the other foot never loaded);
``diagnostics`` — also the sagittal model's COM height and vertical velocity, the other
foot's force and the sagittal state, for Newton's check (``bench/paper_planar.py``).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ...dynamics.planar import (actuated_from_frontal, actuated_from_sagittal,
                                build_planar_models, contact_jacobian, coriolis_matrix,
                                frontal_from_actuated, frontal_torques, gravity_vector,
                                mass_matrix, points, sagittal_from_actuated, sagittal_torques,
                                swing_contact_jacobian)
from ...robot.model import SIDES, Biped
from ...robot.planar import frontal_view, sagittal_view
from ...rotations import matrix_from_quat_xyzw, roll_pitch_from_quat_xyzw, rot_x, rot_y
from ..prepare import StanceWindow, patch_points
from .model import ReplayModel, Variant
from .measurement import true_window
from .outputs import replay_outputs, set_foot_state
from .rigid import measured_configurations, smoothed_path

#: the ``frontal`` options of :func:`replay_planar`
FRONTAL_MODES = ("model", "measured", "measured_roll", "measured_lateral")
#: the ``moment`` options of :func:`replay_planar` (``"drop"``: the paper's model)
MOMENT_MODES = ("drop", "apply")
#: the ``swing_force`` options of :func:`replay_planar`
SWING_FORCE_MODES = ("terrain", "off")


_PLANAR_CACHE: dict = {}


def _planar(biped: Biped, side: str):
    key = (id(biped), side)
    if key not in _PLANAR_CACHE:
        sag, fro = build_planar_models(biped, side)
        _PLANAR_CACHE[key] = (sag, fro, sagittal_view(biped, side), frontal_view(biped, side))
    return _PLANAR_CACHE[key]


def _planar_kin(kin, x, y, z, pitch, vx, vy, vz, wy, R, roll: float = 0.0) -> None:
    c, s_ = math.cos(pitch), math.sin(pitch)
    kin[0:3] = (x, y, z + R)
    if roll == 0.0:
        kin[3:12] = (c, 0.0, -s_, 0.0, 1.0, 0.0, s_, 0.0, c)     # R_y(pitch), column-major
    else:
        kin[3:12] = (rot_x(roll) @ rot_y(pitch)).flatten(order="F")
    kin[12:15] = (vx, vy, vz)
    kin[15:18] = (0.0, wy, 0.0)


def terrain_moment(buf) -> np.ndarray:
    """Moment of one foot's last evaluated terrain wrench about its sole-arc centre A, in
    W [N·m] (zero when the foot was skipped)."""
    return buf.kin[3:12].reshape(3, 3, order="F") @ buf.wrench_local[3:6]


def measured_frontal(biped: Biped, w: StanceWindow, dt_s: float):
    """The stance foot's measured frontal-plane state per scored sample: contact-point
    lateral position y [m] (local frame), its velocity [m/s] and the foot's roll [rad]."""
    data = biped.model.createData()
    fid = biped.foot_frame[w.side]
    y, roll = np.empty(w.n), np.empty(w.n)
    for k, q in enumerate(measured_configurations(biped, w)):
        pin.framesForwardKinematics(biped.model, data, q)
        Rf = data.oMf[fid].rotation
        y[k] = patch_points(biped, data.oMf[fid]).mean(axis=0)[1]
        roll[k] = math.atan2(Rf[2, 1], Rf[2, 2])
    ys, vys, _ = smoothed_path(y[:, None], dt_s)
    return ys[:, 0], vys[:, 0], roll


def replay_planar(model: ReplayModel, w: StanceWindow, variant: Variant | None = None, *,
                  frontal: str = "model", moment: str = "drop", swing_force: str = "terrain",
                  diagnostics: bool = False) -> dict:
    """Replay on the paper's decoupled sagittal + frontal models.

    Both feet use the terrain law of the 3-D model evaluated on their planar kinematics:
    the stance foot at C1 = (x_s, y_s, z_s), the other (swing) foot at the planar models'
    swing contact point, pitch = calf angle + mount pitch, velocities from the contact
    Jacobians. The x and z forces act on the sagittal model, y and z on the frontal one
    (decoupled: each plane sees the same vertical force); the swing foot's force enters
    through the swing contact Jacobian. Semi-implicit Euler at the plant step.
    ``frontal``: :data:`FRONTAL_MODES` (module docstring); ``"model"`` is the paper's.
    ``moment``: :data:`MOMENT_MODES` — ``"drop"`` (the paper's: each foot's terrain force
    acts through the contact coordinates only, i.e. at the sole-arc centre A) or ``"apply"``
    (also the terrain wrench's moment about A, on the calf angle in the sagittal model and
    on the leg line in the frontal one, as the 3-D model has it).
    ``swing_force``: :data:`SWING_FORCE_MODES` — ``"terrain"`` (default) or ``"off"`` (the
    other foot never loaded). ``diagnostics``: also return the sagittal model's whole-body
    COM height ``com_z`` [m] and vertical velocity ``com_vz`` [m/s] and the other foot's
    force ``other_force`` [N] and the sagittal state ``sagittal_q`` (n, 7) per scored sample.
    """
    if frontal not in FRONTAL_MODES:
        raise ValueError(f"frontal must be one of {FRONTAL_MODES}, got {frontal!r}")
    if moment not in MOMENT_MODES:
        raise ValueError(f"moment must be one of {MOMENT_MODES}, got {moment!r}")
    if swing_force not in SWING_FORCE_MODES:
        raise ValueError(f"swing_force must be one of {SWING_FORCE_MODES}, got {swing_force!r}")
    variant = variant or Variant()
    biped = model.biped
    scored = w
    w = true_window(biped, w, variant)         # with sensor effects: the true start, torques
    side, i = w.side, w.foot
    o = 1 - i
    sag, fro, sv, fv = _planar(biped, side)
    mdl = biped.model
    data = mdl.createData()
    q3, v3 = w.q0, w.v0
    pin.forwardKinematics(mdl, data, q3, v3)
    pin.updateFramePlacements(mdl, data)
    R_B = matrix_from_quat_xyzw(q3[3:7])
    w_W = R_B @ v3[3:6]
    roll, pitch = roll_pitch_from_quat_xyzw(q3[3:7])
    qa0, dqa0 = q3[biped.idx_q], v3[biped.idx_v]
    R = biped.config.foot.radius
    fid = biped.foot_frame[side]
    vel = pin.getFrameVelocity(mdl, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    c_W = data.oMf[fid].translation - np.array([0.0, 0.0, R])
    qs = np.concatenate([sagittal_from_actuated(sv, qa0, pitch), [c_W[0], c_W[2]]])
    dqs = np.concatenate([sagittal_from_actuated(sv, dqa0, w_W[1]), [vel.linear[0], vel.linear[2]]])
    qf = np.concatenate([frontal_from_actuated(fv, qa0, roll), [c_W[1], c_W[2]]])
    dqf = np.concatenate([frontal_from_actuated(fv, dqa0, w_W[0], velocity=True),
                          [vel.linear[1], vel.linear[2]]])
    fid_o = biped.foot_frame[SIDES[o]]
    vel_o = pin.getFrameVelocity(mdl, data, fid_o, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    cd = model.terrain.new_data(model.dt)
    theta = model.theta_vector(variant.theta)
    names = model.terrain.param_names
    dz = float(variant.theta.get("touchdown_depth", 0.0))
    for k_, fi in ((i, w.feet[i]), (o, w.feet[o])):
        cd.feet[k_].params[:] = theta
        cd.feet[k_].params[names.index("surface_height")] = fi.surface + dz
        if fi.in_contact:
            set_foot_state(cd.feet[k_], fi, vel.linear if k_ == i else vel_o.linear)
    J = biped.joint_names
    n = w.n
    qa = np.full((n, 6), np.nan)
    grf = np.full((n, 3), np.nan)
    intr = np.full((n, 3), np.nan)
    dt = model.dt
    diverged = False
    f = np.zeros(3)
    Bs = np.vstack([np.eye(5), np.zeros((2, 5))])
    Bf = np.vstack([np.eye(3), np.zeros((2, 3))])

    if frontal != "model":
        y_m, vy_m, roll_m = measured_frontal(biped, w, dt * model.steps_per_sample)
    use_lat = frontal in ("measured", "measured_lateral")
    use_roll = frontal in ("measured", "measured_roll")
    use_moment = moment == "apply"
    m_st = m_sw = np.zeros(3)
    com_z, com_vz = np.full(n, np.nan), np.full(n, np.nan)
    other = np.full((n, 3), np.nan)
    sag_q = np.full((n, 7), np.nan)

    def foot_force(k_, x, y, z, ptch, vx, vy, vz, wy, roll=0.0):
        buf = cd.feet[k_]
        if z - w.feet[k_].surface - dz > 0.005 and buf.state[:, 6].max() < 0.5:
            cd.skip(k_)
            return np.zeros(3)
        _planar_kin(buf.kin, x, y, z, ptch, vx, vy, vz, wy, R, roll)
        cd.evaluate(k_)
        return buf.force.sum(axis=0)

    try:
        for k in range(n):
            ts = sagittal_torques(sv, w.tau[k])
            tf = frontal_torques(fv, w.tau[k])
            for _ in range(model.steps_per_sample):
                # stance foot at C1
                f = foot_force(i, qs[5], y_m[k] if use_lat else qf[3], qs[6],
                               qs[3] + sv.foot_mount_pitch, dqs[5],
                               vy_m[k] if use_lat else dqf[3], dqs[6], dqs[3],
                               roll_m[k] if use_roll else 0.0)
                # swing foot at the planar swing contact point
                ps, pf = points(sag, qs), points(fro, qf)
                Jsw_s, Jsw_f = swing_contact_jacobian(sag, qs), swing_contact_jacobian(fro, qf)
                vs, vf = Jsw_s @ dqs, Jsw_f @ dqf
                f_o = foot_force(o, ps["contact_swing"][0], pf["contact_swing"][0],
                                 ps["contact_swing"][1], qs[1] + sv.foot_mount_pitch,
                                 vs[0], vf[0], vs[1], dqs[1])
                if swing_force == "off":
                    f_o = np.zeros(3)
                elif use_moment:
                    m_sw = terrain_moment(cd.feet[o])
                gs = (Bs @ ts + contact_jacobian(sag, qs).T @ np.array([f[0], f[2]])
                      + Jsw_s.T @ np.array([f_o[0], f_o[2]])
                      - coriolis_matrix(sag, qs, dqs) @ dqs - gravity_vector(sag, qs))
                gf = (Bf @ tf + contact_jacobian(fro, qf).T @ np.array([f[1], f[2]])
                      + Jsw_f.T @ np.array([f_o[1], f_o[2]])
                      - coriolis_matrix(fro, qf, dqf) @ dqf - gravity_vector(fro, qf))
                if use_moment:      # moments about the arc centres on the calf / leg angles
                    gs[3] += m_st[1]
                    gs[1] += m_sw[1]
                    gf[0] += m_st[0]
                    gf[2] += m_sw[0]
                dqs = dqs + dt * np.linalg.solve(mass_matrix(sag, qs), gs)
                dqf = dqf + dt * np.linalg.solve(mass_matrix(fro, qf), gf)
                qs = qs + dt * dqs
                qf = qf + dt * dqf
                cd.commit()
                if not (np.all(np.isfinite(qs)) and np.abs(dqs).max() < 200.0
                        and np.abs(dqf).max() < 200.0):
                    raise FloatingPointError
            qa[k] = actuated_from_sagittal(sv, qs[:5]) + actuated_from_frontal(fv, qf[:3])
            grf[k] = f
            if diagnostics:
                com_z[k] = points(sag, qs)["com"][1]
                sag_q[k] = qs
                other[k] = f_o
            buf = cd.feet[i]
            intr[k] = buf.diag[:, 2:5].mean(axis=0) if buf.state[:, 6].max() > 0.5 else 0.0
    except (FloatingPointError, np.linalg.LinAlgError):
        diverged = True
    out = replay_outputs(qa, grf, intr, np.zeros(n), diverged, variant, scored, J)
    if diagnostics:
        if n > 1:
            com_vz[1:] = np.diff(com_z) / (dt * model.steps_per_sample)
        out.update(com_z=com_z, com_vz=com_vz, other_force=other, sagittal_q=sag_q)
    return out


__all__ = ["replay_planar", "measured_frontal", "terrain_moment", "FRONTAL_MODES",
           "MOMENT_MODES", "SWING_FORCE_MODES"]
