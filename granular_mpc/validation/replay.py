"""Replay every stance from its measured touchdown state (multiple shooting) and score it.

``validate(DATA, model=…)`` replays each complete stance phase of a measurement data set
(:mod:`.prepare`: one :class:`~.prepare.StanceWindow` per stance) from its measured first
sample with the measured joint torques held over each sample, and compares the predicted
joint angles, ground reaction force and intrusion of the stance foot with the measured
ones: RMSE by channel × stance-phase bin × commanded speed with intervals from resampling
whole trials (:func:`granular_mpc.analysis.rmse_table`), ``report.json`` and figures.

Models (``--model``):

* ``granular`` — the 3-D plant (:class:`~granular_mpc.dynamics.Plant`) with the terrain
  model (RFT closed form, elastic–plastic contact, bulldozing, added mass), both feet in
  contact as measured at the window start; extra effects of every kind can be added;
* ``rigid`` — the paper's rigid-ground model (Sec. IV): non-slip, non-sinkage; the stance
  foot's contact point is pinned with its Jacobian J₀ frozen at touchdown; the GRF is the
  constraint force of M v̇ + h = S τ + J₀ᵀ λ, J₀ v̇ = −k J₀ v (inverse dynamics of the
  constrained motion); intrusion ≡ 0; single stance (the other foot is free);
* ``planar`` — the paper's decoupled planar model: sagittal 7-DoF and frontal 5-DoF
  (:mod:`granular_mpc.dynamics.planar`) driven by the mapped torques, the stance foot's
  force from the same terrain law evaluated on the planar foot kinematics (the x and z
  forces go to the sagittal model, y and z to the frontal one); single stance.

Speed: one stance (≈ 0.2 s, 400 plant steps) replays in ≈ 40 ms (granular); windows are
spread over a process pool (``workers``).
"""

from __future__ import annotations

import json
import math
import os
import time as _time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import pandas as pd
import pinocchio as pin

from ..config import EffectSpec, SimConfig, load_terrain
from ..exceptions import ConfigError, GranularMpcError, PlantDivergedError
from ..output import json_safe, make_output_folder
from ..robot.model import SIDES, Biped
from ..runner import trunk_roll_pitch
from ..terrain.effects_library import (EffectInfo, SensorContext, apply_sensor_effects,
                                       effect_info, joint_torque_function)
from .prepare import (AXES, StanceWindow, channel_names, channel_unit, patch_points,
                      stance_windows, windows_frame)

MODELS = ("granular", "rigid", "planar")
#: replay parameters that are not terrain θ: ``touchdown_depth`` [m] is the depth of the
#: measured touchdown point below the free surface (touchdown is detected one step late:
#: every foot's surface is raised by it)
REPLAY_PARAMS = ("touchdown_depth",)
#: θ names of the terrain that the calibration may change (see diagnose)
TERRAIN_THETA_CONFIG = {"zeta": "zeta", "phi_s": "phi_s_deg",
                        "bulldozing_length": "bulldozing_length",
                        "sole_shear_alpha": "sole_shear_alpha",
                        "added_mass_scale": "added_mass_scale", "layer_depth": "layer_depth"}


# ======================================================================================
# Model and variants
# ======================================================================================


@dataclass(frozen=True)
class Variant:
    """One setting of the replayed model.

    Attributes:
        theta: terrain θ values by name (``zeta``, ``phi_s`` [rad], ``cohesion.suction``,
            ``surface_slope_x`` …) overriding the model's; effect parameters included.
        joints: joint effects ``(EffectInfo, params)``.
        sensors: sensor effects ``(EffectInfo, params)`` (applied to the outputs).
        label: a name for reports.
    """

    theta: Mapping[str, float] = field(default_factory=dict)
    joints: tuple = ()
    sensors: tuple = ()
    label: str = ""

    def with_theta(self, **updates: float) -> "Variant":
        th = dict(self.theta)
        th.update(updates)
        return Variant(th, self.joints, self.sensors, self.label)


@dataclass(frozen=True, eq=False)
class ReplayModel:
    """What the replays share: robot, terrain (with every effect that may be switched on
    compiled in), plant step and sample period.

    Attributes:
        biped: robot.
        terrain: terrain model; its θ holds ``<effect>.<param>`` for each compiled effect.
        sim: plant settings (``dt``, integrator).
        steps_per_sample: plant steps per measurement sample.
        terrain_effects: names of the compiled terrain-force effects.
    """

    biped: Biped
    terrain: Any
    sim: SimConfig
    steps_per_sample: int
    terrain_effects: tuple = ()

    @property
    def dt(self) -> float:
        return self.sim.dt

    @property
    def contact_stiffness(self) -> float:
        return float(self.terrain.config.contact_stiffness)

    def theta_vector(self, theta: Mapping[str, float]) -> np.ndarray:
        names = self.terrain.param_names
        vec = self.terrain.param_values
        for k, v in theta.items():
            if k in REPLAY_PARAMS:
                continue
            if k not in names:
                raise ConfigError(f"unknown terrain parameter {k!r} for the replay", key="params",
                                  allowed=", ".join(names))
            vec[names.index(k)] = float(v)
        return vec


def build_replay_model(biped: Biped, terrain_cfg, *, sample_rate_hz: float,
                       sim: SimConfig | None = None,
                       terrain_effects: Sequence[str] = ()) -> ReplayModel:
    """Compile the terrain with the terrain-force effects ``terrain_effects`` (all at their
    neutral values: switch them on through :class:`Variant` θ)."""
    from ..terrain import build_terrain

    sim = sim or SimConfig()
    names = []
    for n in terrain_effects:
        if n not in names and effect_info(n).kind == "terrain_force":
            names.append(n)
    specs = [EffectSpec(name=n, params=effect_info(n).neutral_params()) for n in names]
    already = {e.name for e in terrain_cfg.effects}
    specs = [s for s in specs if s.name not in already]
    terrain = build_terrain(terrain_cfg, biped.config, extra_effects=specs)
    sps = max(1, int(round(1.0 / (sample_rate_hz * sim.dt))))
    return ReplayModel(biped, terrain, sim, sps,
                       tuple(list(already) + [s.name for s in specs]))


def effect_variant(specs: Sequence[tuple[EffectInfo, Mapping[str, float]]],
                   base: Variant | None = None, label: str = "") -> Variant:
    """``base`` plus the effects ``specs`` (terrain-force and geometry as θ, joint and
    sensor as callables)."""
    base = base or Variant()
    theta = dict(base.theta)
    joints = list(base.joints)
    sensors = list(base.sensors)
    for info, p in specs:
        if info.kind == "terrain_force":
            for k, v in p.items():
                theta[f"{info.name}.{k}"] = float(v)
        elif info.kind == "geometry":
            theta.update({k: float(v) for k, v in info.fn(dict(p)).items()})
        elif info.kind == "joint":
            joints.append((info, dict(p)))
        elif info.kind == "sensor":
            sensors.append((info, dict(p)))
    return Variant(theta, tuple(joints), tuple(sensors), label or base.label)


# ======================================================================================
# Granular replay (the 3-D plant)
# ======================================================================================


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
    from ..dynamics import Plant

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
            _set_foot_state(buf, fi, _patch_velocity(biped, d.pin, side, pts))
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
    return _outputs(qa, grf, intr, other, diverged, variant, w, J)


def _apply_sensors(out: dict, variant: Variant | None, w: StanceWindow, J) -> dict:
    if variant is None or not variant.sensors:
        return out
    ctx = SensorContext(np.full(w.n, w.side, dtype=object), w.time, tuple(J))
    return apply_sensor_effects(out, list(variant.sensors), ctx)


# ======================================================================================
# Rigid-ground replay (paper Sec. IV: non-slip, non-sinkage, J frozen at touchdown)
# ======================================================================================


def replay_rigid(model: ReplayModel, w: StanceWindow, variant: Variant | None = None, *,
                 stabilisation: float = 50.0) -> dict:
    """Constrained replay under the paper's rigid-ground assumptions (no slip, no sinkage).

    The stance foot's contact point is pinned with its Jacobian J₀ frozen at touchdown;
    the other foot, if it starts in contact, is pinned likewise (frozen J₁) until its
    constraint force would pull (λ_z < 0: lift-off). The initial velocity is projected onto
    the constraints (a plastic impact); then, per plant step, the KKT system
    [M −Jᵀ; J 0][v̇; λ] = [Sτ − h; −k J v] gives the acceleration and the ground forces λ
    (world axes, on the feet: the inverse dynamics of the constrained motion);
    semi-implicit Euler on the manifold. The intrusion is 0 by assumption.
    """
    biped = model.biped
    mdl = biped.model
    data = mdl.createData()
    q = w.q0.copy()
    v = w.v0.copy()
    pin.forwardKinematics(mdl, data, q, v)
    pin.updateFramePlacements(mdl, data)
    pin.computeJointJacobians(mdl, data, q)

    def point_jacobian(side):
        fid = biped.foot_frame[side]
        JF = pin.getFrameJacobian(mdl, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        p_c = patch_points(biped, data.oMf[fid]).mean(axis=0)
        return JF[0:3] - pin.skew(p_c - data.oMf[fid].translation) @ JF[3:6]

    Js = [point_jacobian(w.side)]
    other = w.feet[1 - w.foot]
    if other.in_contact:
        Js.append(point_jacobian(SIDES[1 - w.foot]))
    nv = mdl.nv
    M = pin.crba(mdl, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    Jc = np.vstack(Js)
    MiJt = np.linalg.solve(M, Jc.T)
    v = v - MiJt @ np.linalg.lstsq(Jc @ MiJt, Jc @ v, rcond=None)[0]
    J = biped.joint_names
    n = w.n
    qa = np.full((n, len(J)), np.nan)
    lam_out = np.full((n, 3), np.nan)
    dt = model.dt
    iv, iq = biped.idx_v, biped.idx_q
    lo, hi = biped.position_limits
    lam = np.zeros(3 * len(Js))
    diverged = False
    try:
        for k in range(n):
            tau_a = w.tau[k]
            for _ in range(model.steps_per_sample):
                Jc = np.vstack(Js)
                nc = Jc.shape[0]
                M = pin.crba(mdl, data, q)
                M = np.triu(M) + np.triu(M, 1).T
                h = pin.nonLinearEffects(mdl, data, q, v)
                tau = np.zeros(nv)
                tau[iv] = tau_a
                over = np.maximum(q[iq] - hi, 0.0) + np.minimum(q[iq] - lo, 0.0)
                if over.any():
                    tau[iv] += np.where(over != 0.0, -500.0 * over - 5.0 * v[iv], 0.0)
                K = np.zeros((nv + nc, nv + nc))
                K[:nv, :nv] = M
                K[:nv, nv:] = -Jc.T
                K[nv:, :nv] = Jc
                rhs = np.concatenate([tau - h, -stabilisation * (Jc @ v)])
                sol = np.linalg.solve(K, rhs)
                a, lam = sol[:nv], sol[nv:]
                if len(Js) > 1 and lam[5] < 0.0:       # the other foot lets go
                    Js = Js[:1]
                    continue_step = True
                else:
                    continue_step = False
                if continue_step:
                    Jc = Js[0]
                    K = np.zeros((nv + 3, nv + 3))
                    K[:nv, :nv] = M
                    K[:nv, nv:] = -Jc.T
                    K[nv:, :nv] = Jc
                    sol = np.linalg.solve(K, np.concatenate([tau - h, -stabilisation * (Jc @ v)]))
                    a, lam = sol[:nv], sol[nv:]
                v = v + dt * a
                q = pin.integrate(mdl, q, v * dt)
                if not (np.all(np.isfinite(q)) and np.abs(v).max() < 200.0):
                    raise FloatingPointError
            qa[k] = q[iq]
            lam_out[k] = lam[0:3]
    except (FloatingPointError, np.linalg.LinAlgError):
        diverged = True
    intr = np.where(np.isnan(qa[:, :1]), np.nan, np.zeros((n, 3)))    # pinned: no intrusion
    return _outputs(qa, lam_out, intr, np.zeros(n), diverged, variant, w, J)


# ======================================================================================
# Planar decoupled replay (paper Sec. II: sagittal 7-DoF + frontal 5-DoF)
# ======================================================================================


_PLANAR_CACHE: dict = {}


def _planar(biped: Biped, side: str):
    key = (id(biped), side)
    if key not in _PLANAR_CACHE:
        from ..dynamics.planar import build_planar_models
        from ..robot.planar import frontal_view, sagittal_view

        sag, fro = build_planar_models(biped, side)
        _PLANAR_CACHE[key] = (sag, fro, sagittal_view(biped, side), frontal_view(biped, side))
    return _PLANAR_CACHE[key]


def _outputs(qa, grf, intr, other_grf_z, diverged, variant, w, J) -> dict:
    """A replay's predicted channels (format v1 names, through the variant's sensor
    effects), the other foot's vertical force and the divergence flag."""
    out = {f"q_{j}": qa[:, c] for c, j in enumerate(J)}
    for c, ax in enumerate(AXES):
        out[f"grf_{ax}"] = grf[:, c]
        out[f"intrusion_{ax}"] = intr[:, c]
    out = _apply_sensors(out, variant, w, J)
    out["other_grf_z"] = other_grf_z
    out["diverged"] = diverged
    return out


def _set_foot_state(buf, fi, vel) -> None:
    st = buf.state
    st[:, 0:3] = fi.e
    st[:, 3:6] = fi.c0
    st[:, 6] = 1.0
    st[:, 7:10] = vel
    st[:, 10] = fi.depth_max
    st[:, 11] = fi.t_stance


def _planar_kin(kin, x, y, z, pitch, vx, vy, vz, wy, R) -> None:
    c, s_ = math.cos(pitch), math.sin(pitch)
    kin[0:3] = (x, y, z + R)
    kin[3:12] = (c, 0.0, -s_, 0.0, 1.0, 0.0, s_, 0.0, c)     # R_y(pitch), column-major
    kin[12:15] = (vx, vy, vz)
    kin[15:18] = (0.0, wy, 0.0)


def replay_planar(model: ReplayModel, w: StanceWindow, variant: Variant | None = None) -> dict:
    """Replay on the paper's decoupled sagittal + frontal models.

    Both feet use the terrain law of the 3-D model evaluated on their planar kinematics:
    the stance foot at C1 = (x_s, y_s, z_s), the other (swing) foot at the planar models'
    swing contact point, pitch = calf angle + mount pitch, velocities from the contact
    Jacobians. The x and z forces act on the sagittal model, y and z on the frontal one
    (decoupled: each plane sees the same vertical force); the swing foot's force enters
    through the swing contact Jacobian. Semi-implicit Euler at the plant step.
    """
    from ..dynamics.planar import (actuated_from_frontal, actuated_from_sagittal,
                                   contact_jacobian, coriolis_matrix, frontal_from_actuated,
                                   frontal_torques, gravity_vector, mass_matrix, points,
                                   sagittal_from_actuated, sagittal_torques,
                                   swing_contact_jacobian)

    variant = variant or Variant()
    biped = model.biped
    side, i = w.side, w.foot
    o = 1 - i
    sag, fro, sv, fv = _planar(biped, side)
    mdl = biped.model
    data = mdl.createData()
    q3, v3 = w.q0, w.v0
    pin.forwardKinematics(mdl, data, q3, v3)
    pin.updateFramePlacements(mdl, data)
    R_B = pin.Quaternion(q3[6], q3[3], q3[4], q3[5]).matrix()
    w_W = R_B @ v3[3:6]
    roll, pitch = trunk_roll_pitch(q3)
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
            _set_foot_state(cd.feet[k_], fi, vel.linear if k_ == i else vel_o.linear)
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

    def foot_force(k_, x, y, z, ptch, vx, vy, vz, wy):
        buf = cd.feet[k_]
        if z - w.feet[k_].surface - dz > 0.005 and buf.state[:, 6].max() < 0.5:
            cd.skip(k_)
            return np.zeros(3)
        _planar_kin(buf.kin, x, y, z, ptch, vx, vy, vz, wy, R)
        cd.evaluate(k_)
        return buf.force.sum(axis=0)

    try:
        for k in range(n):
            ts = sagittal_torques(sv, w.tau[k])
            tf = frontal_torques(fv, w.tau[k])
            for _ in range(model.steps_per_sample):
                # stance foot at C1
                f = foot_force(i, qs[5], qf[3], qs[6], qs[3] + sv.foot_mount_pitch,
                               dqs[5], dqf[3], dqs[6], dqs[3])
                # swing foot at the planar swing contact point
                ps, pf = points(sag, qs), points(fro, qf)
                Jsw_s, Jsw_f = swing_contact_jacobian(sag, qs), swing_contact_jacobian(fro, qf)
                vs, vf = Jsw_s @ dqs, Jsw_f @ dqf
                f_o = foot_force(o, ps["contact_swing"][0], pf["contact_swing"][0],
                                 ps["contact_swing"][1], qs[1] + sv.foot_mount_pitch,
                                 vs[0], vf[0], vs[1], dqs[1])
                gs = (Bs @ ts + contact_jacobian(sag, qs).T @ np.array([f[0], f[2]])
                      + Jsw_s.T @ np.array([f_o[0], f_o[2]])
                      - coriolis_matrix(sag, qs, dqs) @ dqs - gravity_vector(sag, qs))
                gf = (Bf @ tf + contact_jacobian(fro, qf).T @ np.array([f[1], f[2]])
                      + Jsw_f.T @ np.array([f_o[1], f_o[2]])
                      - coriolis_matrix(fro, qf, dqf) @ dqf - gravity_vector(fro, qf))
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
            buf = cd.feet[i]
            intr[k] = buf.diag[:, 2:5].mean(axis=0) if buf.state[:, 6].max() > 0.5 else 0.0
    except (FloatingPointError, np.linalg.LinAlgError):
        diverged = True
    return _outputs(qa, grf, intr, np.zeros(n), diverged, variant, w, J)


REPLAYERS: dict[str, Callable] = {"granular": replay_granular, "rigid": replay_rigid,
                                  "planar": replay_planar}


# ======================================================================================
# Running many replays (process pool over windows)
# ======================================================================================

_SHARED: dict = {}


def _worker_init() -> None:
    from threadpoolctl import threadpool_limits

    _SHARED["limits"] = threadpool_limits(limits=1)


def _run_chunk(task: tuple) -> list:
    kind, vkey, indices = task
    model = _SHARED["model"]
    windows = _SHARED["windows"]
    variant = _SHARED["variants"][vkey]
    fn = REPLAYERS[kind]
    return [(vkey, i, fn(model, windows[i], variant)) for i in indices]


class ReplayPool:
    """Replays of many (model kind, variant) pairs over the same windows.

    Forks ``workers`` processes that share the model and the windows (set before the
    fork); each task is one variant × a chunk of windows. With ``workers=1`` everything
    runs in this process.
    """

    def __init__(self, model: ReplayModel, windows: Sequence[StanceWindow], *,
                 workers: int | None = None) -> None:
        self.model = model
        self.windows = list(windows)
        n_cpu = os.cpu_count() or 1
        self.workers = max(1, min(n_cpu if workers is None else int(workers), len(self.windows)))
        self._pool: ProcessPoolExecutor | None = None
        self.n_replays = 0
        self.replay_time_s = 0.0

    def __enter__(self) -> "ReplayPool":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def run(self, variants: Mapping[Any, Variant], kind: str = "granular") -> dict:
        """``{variant key: [per-window output dict]}`` for every variant."""
        t0 = _time.perf_counter()
        variants = dict(variants)
        idx = list(range(len(self.windows)))
        results: dict = {k: [None] * len(idx) for k in variants}
        if self.workers <= 1 or len(idx) < 4:
            for k, var in variants.items():
                fn = REPLAYERS[kind]
                for i in idx:
                    results[k][i] = fn(self.model, self.windows[i], var)
        else:
            # windows are sorted by cost (length) and dealt round-robin
            order = sorted(idx, key=lambda i: -self.windows[i].n)
            n_chunks = self.workers * 2
            chunks = [order[c::n_chunks] for c in range(n_chunks)]
            _SHARED.update(model=self.model, windows=self.windows, variants=variants)
            # a fresh pool per call: the workers inherit the current variants by fork
            with ProcessPoolExecutor(max_workers=self.workers, initializer=_worker_init) as ex:
                tasks = [(kind, k, ch) for k in variants for ch in chunks if ch]
                for part in ex.map(_run_chunk, tasks):
                    for vkey, i, res in part:
                        results[vkey][i] = res
        self.n_replays += len(variants) * len(idx)
        self.replay_time_s += _time.perf_counter() - t0
        return results


# ======================================================================================
# Scoring
# ======================================================================================


def role_channels(w: StanceWindow, values: Mapping[str, np.ndarray],
                  joint_names: Sequence[str]) -> dict:
    """Channels renamed into stance/swing roles (``q_stance_knee``, ``q_swing_hip_pitch``)."""
    out = {}
    for j in joint_names:
        side, _, rest = j.partition("_")
        if side in SIDES:
            role = "stance" if side == w.side else "swing"
            out[f"q_{role}_{rest}"] = values[f"q_{j}"]
        else:
            out[f"q_{j}"] = values[f"q_{j}"]
    for c in ("grf", "intrusion"):
        for ax in AXES:
            out[f"{c}_{ax}"] = values[f"{c}_{ax}"]
    return out


def rmse_tables(windows: Sequence[StanceWindow], predictions: Sequence[dict],
                channels: Sequence[str], *, phase_bins: int = 10, n_boot: int = 1000,
                seed: int = 0) -> dict[str, pd.DataFrame]:
    """RMSE tables of one model: ``by_speed_phase`` (speed × channel × phase bin),
    ``by_speed`` (whole stance, Fig. 5), ``by_phase`` (all speeds pooled), ``overall``.

    The interval unit is the trial when every speed has at least two trials, else the
    stance (``interval_unit`` column)."""
    from ..analysis.metrics import rmse_table

    meas = windows_frame(windows, None, channels)
    pred = windows_frame(windows, list(predictions), channels)
    per_speed = meas.groupby("commanded_speed_mps")["trial"].nunique()
    unit = "trial" if len(per_speed) and per_speed.min() >= 2 else "stance_id"
    meas["unit"] = meas[unit].astype(str)
    pred["unit"] = meas["unit"]
    kw = dict(trial_col="unit", n_boot=n_boot, seed=seed)
    out = {
        "by_speed_phase": rmse_table(pred, meas, channels, phase_bins=phase_bins, **kw),
        "by_speed": rmse_table(pred, meas, channels, phase_bins=None, **kw),
        "by_phase": rmse_table(pred, meas, channels, group_cols=(), phase_bins=phase_bins, **kw),
        "overall": rmse_table(pred, meas, channels, group_cols=(), phase_bins=None, **kw),
    }
    for t in out.values():
        t["interval_unit"] = "trial" if unit == "trial" else "stance"
    return out


def _records(df: pd.DataFrame) -> list[dict]:
    return json.loads(df.to_json(orient="records", double_precision=10))


# ======================================================================================
# Terrain and effects for validate
# ======================================================================================


def model_terrain(terrain: str | Mapping | Any = "dry_sand",
                  params: Mapping[str, float] | None = None):
    """The model's terrain config: a terrain name/path or config, with calibrated θ
    (``zeta``, ``phi_s`` [rad] …) applied."""
    from ..config import terrain_from_dict

    if isinstance(terrain, (str, Path)):
        cfg = load_terrain(str(terrain))
    elif isinstance(terrain, Mapping):
        cfg = terrain_from_dict(terrain)
    else:
        cfg = terrain
    if params:
        upd = {}
        for k, v in params.items():
            if k == "phi_s":
                upd["phi_s_deg"] = math.degrees(float(v))
            elif k in TERRAIN_THETA_CONFIG:
                upd[TERRAIN_THETA_CONFIG[k]] = float(v)
            elif k in ("surface_slope_x", "surface_slope_y", "surface_height") or k in REPLAY_PARAMS:
                continue        # geometry is per stance in the replay; replay parameters
            else:
                raise ConfigError(f"unknown calibrated parameter {k!r}", key="params",
                                  allowed=", ".join(TERRAIN_THETA_CONFIG))
        cfg = cfg.model_copy(update=upd)
    return cfg


def load_fitted(params: str | Path | Mapping | None) -> tuple[dict, dict]:
    """(calibrated terrain θ, fitted effect parameters by effect name) from a mapping or a
    ``diagnosis.json`` file (keys ``calibration.values`` and ``fitted_effects``)."""
    if params is None:
        return {}, {}
    if isinstance(params, (str, Path)):
        p = Path(params)
        if p.is_dir():
            p = p / "diagnosis.json"
        try:
            params = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise ConfigError(f"cannot read fitted parameters from {p}: {exc}",
                              key="--params") from None
    params = dict(params)
    if "calibration" in params or "fitted_effects" in params:
        cal = dict((params.get("calibration") or {}).get("values", {}))
        eff = {k: dict(v) for k, v in (params.get("fitted_effects") or {}).items()}
        return cal, eff
    return {k: float(v) for k, v in params.items() if not isinstance(v, Mapping)}, \
        {k: dict(v) for k, v in params.items() if isinstance(v, Mapping)}


def resolve_effect_specs(effects: Sequence[Any], fitted: Mapping[str, Mapping] | None = None
                         ) -> list[tuple[EffectInfo, dict[str, float]]]:
    """(EffectInfo, parameters) per effect: explicit values win, then fitted values, then
    the registered defaults."""
    out = []
    for e in effects or ():
        spec = e if isinstance(e, EffectSpec) else EffectSpec.model_validate(e)
        info = effect_info(spec.name)
        given = dict((fitted or {}).get(spec.name, {}))
        given = {k: v for k, v in given.items() if k in info.params}
        given.update(spec.params)
        out.append((info, info.resolve_params(given)))
    return out


# ======================================================================================
# validate
# ======================================================================================


@dataclass(frozen=True)
class ValidationReport:
    """What :func:`validate` computed and wrote.

    Attributes:
        report: the content of ``report.json``.
        tables: model label → RMSE tables (:func:`rmse_tables`).
        windows: the replayed stance windows.
        predictions: model label → per-window outputs.
        out_dir: where the report was written (or None).
        figures: written figure paths.
    """

    report: dict
    tables: dict
    windows: list
    predictions: dict
    out_dir: Path | None
    figures: tuple = ()

    def rmse(self, label: str, channel: str) -> float:
        """Whole-data RMSE of one channel for one model label."""
        t = self.tables[label]["overall"]
        return float(t.loc[t["channel"] == channel, "rmse"].iloc[0])


def validate(data_dir: str | Path, out_dir: str | Path | None = None, *,
             model: str = "granular", effects: Sequence[Any] = (),
             params: str | Path | Mapping | None = None, terrain: Any = "dry_sand",
             sim: SimConfig | None = None, phase_bins: int = 10, n_boot: int = 1000,
             workers: int | None = None, figures: bool = True, seed: int = 0,
             effect_files: Sequence[str | Path] = ()) -> ValidationReport:
    """Replay every complete stance of a data set and score the model against it.

    Args:
        data_dir: measurement data set (format v1).
        out_dir: report folder (``report.json`` + figures); None: nothing written.
        model: ``granular``, ``rigid`` or ``planar`` (see the module docstring).
        effects: effects to add (``"name:k=v"``, mappings or EffectSpec); with effects
            the report holds the model *before* (``<model>``) and *after*
            (``<model>+effects``) and the change of every RMSE.
        params: calibrated terrain parameters and fitted effect parameters: a mapping or
            a ``diagnosis.json`` (or its folder). Effects given without values take the
            fitted ones.
        terrain: the model's terrain (name/path in ``models/terrain`` or a config).
        sim: plant settings for the replay (default: ``SimConfig()``, dt = 0.5 ms).
        phase_bins: stance-phase bins of the tables.
        n_boot: bootstrap replicates of the intervals.
        workers: processes for the replays (default: all CPUs).
        figures: write the figures.
        seed: bootstrap seed.
        effect_files: user Python files registering effects (imported first).

    Returns:
        :class:`ValidationReport`.
    """
    from ..robot.model import load_biped
    from ..terrain.effects import load_effect_file
    from .dataformat import load_dataset

    t0 = _time.perf_counter()
    if model not in MODELS:
        raise ConfigError(f"unknown model {model!r}", key="model", allowed=", ".join(MODELS))
    for f in effect_files:
        load_effect_file(str(f))
    ds = load_dataset(data_dir)
    # checked before the replays, so that a bad folder does not cost the computation
    out = make_output_folder(out_dir) if out_dir is not None else None
    biped = load_biped(ds.meta.robot, with_visuals=False)
    cal, fitted = load_fitted(params)
    cfg = model_terrain(terrain, cal)
    specs = resolve_effect_specs(effects, fitted)
    terrain_names = [i.name for i, _ in specs if i.kind == "terrain_force"]
    rm = build_replay_model(biped, cfg, sample_rate_hz=ds.meta.sample_rate_hz, sim=sim,
                            terrain_effects=terrain_names)
    windows = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness)
    if not windows:
        raise GranularMpcError(f"{data_dir}: no complete stance phase to replay")
    J = list(ds.joint_names)
    channels = channel_names(J)
    base = Variant(theta={k: float(v) for k, v in cal.items() if k in REPLAY_PARAMS},
                   label=model)
    variants = {model: base}
    if specs:
        if model == "rigid" and any(i.kind != "sensor" for i, _ in specs):
            raise ConfigError("the rigid-ground model takes sensor effects only", key="--effect")
        variants[f"{model}+effects"] = effect_variant(specs, base, f"{model}+effects")
    t_rep = _time.perf_counter()
    with ReplayPool(rm, windows, workers=workers) as pool:
        preds = {k: v for k, v in pool.run(variants, kind=model).items()}
    t_rep = _time.perf_counter() - t_rep
    tables = {k: rmse_tables(windows, preds[k], channels, phase_bins=phase_bins,
                             n_boot=n_boot, seed=seed) for k in variants}
    n_div = {k: int(sum(bool(p["diverged"]) for p in preds[k])) for k in variants}
    report: dict[str, Any] = {
        "data": str(data_dir), "model": model, "robot": ds.meta.robot,
        "terrain": getattr(cfg, "name", str(terrain)),
        "calibrated_params": cal,
        "effects": [{"name": i.name, "kind": i.kind, "params": p} for i, p in specs],
        "n_trials": len(ds.trials), "n_stances": len(windows),
        "speeds_mps": sorted({w.speed for w in windows}),
        "channels": channels, "units": {c: channel_unit(c) for c in channels},
        "phase_bins": phase_bins,
        "interval": {"ci": 0.95, "n_boot": n_boot,
                     "unit": tables[model]["overall"]["interval_unit"].iloc[0]},
        "diverged_stances": n_div,
        "models": {k: {name: _records(t) for name, t in tb.items()} for k, tb in tables.items()},
        "overall_rmse": {k: dict(zip(tb["overall"]["channel"], tb["overall"]["rmse"]))
                         for k, tb in tables.items()},
    }
    if specs:
        b = report["overall_rmse"][model]
        a = report["overall_rmse"][f"{model}+effects"]
        report["before_after"] = {c: {"before": b[c], "after": a[c],
                                      "change_pct": 100.0 * (a[c] - b[c]) / b[c] if b[c] else None}
                                  for c in channels}
    figs: list[Path] = []
    if out is not None:
        if figures:
            figs = _figures(out, windows, preds, tables, J, model)
        report["figures"] = [str(p.name) for p in figs]
    report["timing_s"] = {"replay": t_rep, "total": _time.perf_counter() - t0}
    if out is not None:
        (out / "report.json").write_text(json.dumps(json_safe(report), indent=1),
                                         encoding="utf-8")
    return ValidationReport(report, tables, windows, preds, out, tuple(figs))


# ======================================================================================
# Figures
# ======================================================================================


def _figures(out: Path, windows, preds: dict, tables: dict, J, model: str) -> list[Path]:
    from ..analysis.metrics import phase_bands, resample_by_phase
    from ..viz.plots import plot_model_vs_measurement, plot_residual_heatmap, plot_rmse_vs_speed

    paths = []
    role_meas = [role_channels(w, w.meas, J) for w in windows]
    role_chans = list(role_meas[0].keys())
    frames = []
    for label, src in [("measurement", role_meas)] + [
            (k, [role_channels(w, p, J) for w, p in zip(windows, preds[k])]) for k in preds]:
        f = windows_frame(windows, src, role_chans)
        for c in role_chans:
            if c.startswith("intrusion"):
                f[c] = 1e3 * f[c]
        f["source"] = label
        frames.append(f)
    long = pd.concat(frames, ignore_index=True)
    long["_id"] = long["source"] + ":" + long["stance_id"].astype(str)
    res = resample_by_phase(long, role_chans, id_col="_id", n_phase=51, keep=["source"])
    bands = phase_bands(res, role_chans, by=["source"])
    units = {c: ("rad" if c.startswith("q_") else "N" if c.startswith("grf") else "mm")
             for c in role_chans}
    paths.append(plot_model_vs_measurement(bands, out / "bands.png", units=units).path)
    speed_tables = []
    for k, tb in tables.items():
        t = tb["by_speed"].copy()
        t["model"] = k
        speed_tables.append(t)
    st = pd.concat(speed_tables, ignore_index=True)
    paths.append(plot_rmse_vs_speed(st, out / "rmse_vs_speed.png",
                                    units={c: channel_unit(c) for c in st["channel"].unique()}).path)
    for k, tb in tables.items():
        safe = k.replace("+", "_plus_")
        paths.append(plot_residual_heatmap(tb["by_phase"], out / f"heatmap_{safe}.png",
                                           title=f"{k}: RMSE by channel and stance phase").path)
    return [p for p in paths if p is not None]


__all__ = ["validate", "ValidationReport", "Variant", "ReplayModel", "ReplayPool",
           "build_replay_model", "effect_variant", "replay_granular", "replay_rigid",
           "replay_planar", "rmse_tables", "model_terrain", "load_fitted",
           "resolve_effect_specs", "role_channels", "MODELS"]
