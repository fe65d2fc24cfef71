"""The measurement model inside a replay: from measured to true inputs and initial state.

A sensor effect maps the true columns of a trial to the measured ones (``effects.sensor``).
A replay is *driven* by measured columns — its initial joint angles and rates come from
``q_*`` (and ``dq_*``), its torques from ``tau_*`` — and *scored* on measured columns. With
a sensor effect in the variant, the replay therefore

1. inverts the map on its inputs (:func:`true_window`): the window's initial joint angles
   and rates and its torques are replaced by the true values whose image under the
   variant's sensor effects is the measurement
   (:func:`~granular_mpc.effects.sensor.invert_sensor_effects`); each foot's initial contact
   state (free surface, touchdown points, contact point), which ``prepare`` derived from
   the forward kinematics of the measured angles, moves with the foot by the difference of
   the forward kinematics of the true and the measured angles, so the foot starts at the
   same depth in the same sand;
2. applies the map to its outputs (:func:`~.outputs.replay_outputs`).

An encoder zero offset at its true value then leaves the replay exactly as the plant ran.
The trunk's initial orientation (``base_q*``) is inverted too (a trunk-attitude bias,
:func:`~granular_mpc.effects.measurement.trunk_attitude_bias`); the feet move with it as
with the joint angles. Not inverted: the trunk's position and twist (they drive the state
as measured) and the initial force/intrusion of a buried foot (its elastic displacement
is F/(nK), micrometres per newton).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

from typing import Mapping, Sequence

from ...columns import BASE_QUATERNION, joint_columns
from ...effects import EffectInfo, SensorContext, check_sensor_effect, invert_sensor_effects
from ...robot.model import SIDES, Biped
from ...rotations import matrix_from_quat_xyzw, wxyz_from_xyzw, xyzw_from_wxyz
from ..prepare import SURFACE_SAMPLES, FootInit, StanceWindow, patch_points
from .model import Variant


def _sample_period(w: StanceWindow) -> float:
    return float(w.time[1] - w.time[0]) if w.n > 1 else 0.0


def _moved_foot(fi: FootInit, delta: np.ndarray, surface_shift: float | None = None
                ) -> FootInit:
    """``fi`` with its geometry moved by the per-patch displacement ``delta`` (n, 3) [m];
    its free surface by ``surface_shift`` [m] (None: with the foot)."""
    mean = delta.mean(axis=0)
    dz = mean[2] if surface_shift is None else surface_shift
    return replace(fi, surface=float(fi.surface + dz), point=fi.point + mean,
                   c0=fi.c0 + delta)


def _touchdown_surface_shift(biped: Biped, w: StanceWindow, specs,
                             J: list[str]) -> float | None:
    """How prepare's free surface of a touchdown window's stance foot moves when the poses
    it was estimated from are replaced by their true values: the mean, over the phase's
    first :data:`~..prepare.SURFACE_SAMPLES` rows (the window's first scored rows), of the
    foot's patch height through the forward kinematics of the raw pose, true minus
    measured [m]. (The start sample's displacement alone is off where the pose changes
    over those rows: 41 µm for a 1.5° trunk tilt.) None where prepare estimated the surface
    otherwise (no measured intrusion) or the rows lack a pose column: the foot's own
    displacement then."""
    m = min(SURFACE_SAMPLES, w.n)
    q_cols = joint_columns(J, "q")
    rows = {c: np.asarray(v, dtype=float)[:m] for c, v in window_columns(w).items()}
    if m == 0 or "intrusion_z" not in w.meas or any(
            c not in rows for c in (*q_cols, *BASE_QUATERNION)):
        return None
    ctx = SensorContext(np.full(m, w.side, dtype=object), w.time[:m], tuple(J))
    true = invert_sensor_effects(rows, specs, ctx, q_cols + list(BASE_QUATERNION), strict=False)
    data = biped.create_data()
    frame = biped.foot_frame[w.side]
    heights = []
    for cols in (rows, true):
        z = 0.0
        for k in range(m):
            quat = np.array([cols[c][k] for c in BASE_QUATERNION])
            quat = quat / np.linalg.norm(quat)
            q = biped.q_from_parts(np.zeros(3), xyzw_from_wxyz(quat),
                                   [cols[c][k] for c in q_cols])
            pin.framesForwardKinematics(biped.model, data, q)
            z += float(patch_points(biped, data.oMf[frame])[:, 2].mean())
        heights.append(z / m)
    return heights[1] - heights[0]


def true_window(biped: Biped, w: StanceWindow, variant: Variant | None) -> StanceWindow:
    """``w`` with its initial joint state, torques and feet set to the true values under the
    sensor effects of ``variant`` (``w`` itself when it has none). See the module docstring.
    """
    if variant is None or not variant.sensors:
        return w
    J = list(biped.joint_names)
    specs = list(variant.sensors)
    dt = _sample_period(w)
    q_cols, dq_cols, tau_cols = (joint_columns(J, k) for k in ("q", "dq", "tau"))
    # torques: tau[k] acts over the interval ending at scored sample k (rows k0 … b−2)
    cols = window_columns(w)
    cols.update({c: w.tau[:, j] for j, c in enumerate(tau_cols)})
    ctx = SensorContext(np.full(w.n, w.side, dtype=object), w.time - dt, tuple(J))
    tau_true = invert_sensor_effects(cols, specs, ctx, tau_cols, strict=False)
    tau = np.column_stack([tau_true[c] for c in tau_cols])
    # the initial joint state (one row, the window's start sample)
    row = {c: np.asarray(v, dtype=float)[:1] for c, v in w.columns.items()}
    row.update({c: np.array([w.q0[biped.idx_q[j]]]) for j, c in enumerate(q_cols)})
    row.update({c: np.array([w.v0[biped.idx_v[j]]]) for j, c in enumerate(dq_cols)})
    quat0 = wxyz_from_xyzw(w.q0[3:7])               # the window's (smoothed) trunk attitude
    row.update({c: quat0[i:i + 1] for i, c in enumerate(BASE_QUATERNION)})
    ctx0 = SensorContext(np.array([w.side], dtype=object), w.time[:1] - dt, tuple(J))
    start = invert_sensor_effects(row, specs, ctx0, q_cols + dq_cols + list(BASE_QUATERNION),
                                  strict=False)
    q0, v0 = w.q0.copy(), w.v0.copy()
    q0[biped.idx_q] = [start[c][0] for c in q_cols]
    v0[biped.idx_v] = [start[c][0] for c in dq_cols]
    quat = np.array([start[c][0] for c in BASE_QUATERNION])
    if not np.array_equal(quat, quat0):
        q0[3:7] = xyzw_from_wxyz(quat / np.linalg.norm(quat))
        # the trunk's linear velocity is the world velocity in the trunk frame (prepare):
        # the same world velocity in the true frame; the gyro's rates stay as measured
        R_meas, R_true = (matrix_from_quat_xyzw(q[3:7]) for q in (w.q0, q0))
        v0[0:3] = R_true.T @ (R_meas @ w.v0[0:3])
    if np.array_equal(q0, w.q0) and np.array_equal(v0, w.v0) and np.array_equal(tau, w.tau):
        return w
    feet = list(w.feet)
    if not np.array_equal(q0, w.q0):
        data = biped.create_data()
        pts = []
        for q in (w.q0, q0):
            pin.framesForwardKinematics(biped.model, data, q)
            pts.append([patch_points(biped, data.oMf[biped.foot_frame[s]]) for s in SIDES])
        lead = SIDES.index(w.side)
        shift = (None if w.feet[lead].in_contact
                 else _touchdown_surface_shift(biped, w, specs, J))
        feet = [_moved_foot(fi, pts[1][i] - pts[0][i], shift if i == lead else None)
                for i, fi in enumerate(w.feet)]
    return replace(w, q0=q0, v0=v0, tau=tau, feet=tuple(feet))


#: prefixes of the columns a replay reads (initial state, torques): a sensor effect that
#: changes one of them changes the replay itself, not only its outputs
REPLAY_INPUT_PREFIXES = ("q_", "dq_", "tau_", "base_")


def window_columns(w: StanceWindow) -> dict[str, np.ndarray]:
    """Every column of the data format on a window's scored rows, as measured."""
    cols = {c: np.asarray(v, dtype=float) for c, v in w.columns.items()}
    cols.update({c: np.asarray(v, dtype=float) for c, v in w.meas.items()})
    return cols


def check_sensor_specs(specs: Sequence[tuple[EffectInfo, Mapping[str, float]]],
                       w: StanceWindow, joint_names: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """Try each sensor effect of ``specs`` on window ``w``'s columns (before any replay).

    Returns:
        Effect name → the columns it changes.

    Raises:
        ConfigError: an effect reads a column the data do not have (naming the effect and
            the column), or returns one that is not a column of the format.
    """
    ctx = SensorContext(np.full(w.n, w.side, dtype=object), w.time, tuple(joint_names))
    cols = window_columns(w)
    return {info.name: check_sensor_effect(info, p, cols, ctx)
            for info, p in specs if info.kind == "sensor"}


def check_sensor_inversion(specs: Sequence[tuple[EffectInfo, Mapping[str, float]]],
                           w: StanceWindow, joint_names: Sequence[str]) -> None:
    """Invert the sensor effects of ``specs`` on window ``w``'s torques, as a replay does
    (:func:`true_window`), and raise if that cannot be done.

    Raises:
        ConfigError: an effect's map cannot be inverted sample by sample and has no
            ``inverse`` (a time shift of a sample or more; the error names the effect).
    """
    J = list(joint_names)
    tau_cols = joint_columns(J, "tau")
    cols = window_columns(w)
    cols.update({c: w.tau[:, j] for j, c in enumerate(tau_cols)})
    ctx = SensorContext(np.full(w.n, w.side, dtype=object), w.time - _sample_period(w), tuple(J))
    invert_sensor_effects(cols, specs, ctx, tau_cols)


def changes_replay(changed: Sequence[str]) -> bool:
    """Whether a sensor effect changing the columns ``changed`` changes what a replay reads
    (:data:`REPLAY_INPUT_PREFIXES`), so its effect needs a replay, not just its map."""
    return any(c.startswith(REPLAY_INPUT_PREFIXES) for c in changed)


__all__ = ["true_window", "window_columns", "check_sensor_specs", "check_sensor_inversion",
           "changes_replay", "REPLAY_INPUT_PREFIXES"]
