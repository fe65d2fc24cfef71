"""The measurement model as candidates: sensing errors of a real robot, as sensor effects.

The most common discrepancies on a real robot are not terrain physics but sensing. This
module registers them as a family of ``sensor`` effects (tag ``measurement``), each a map
from the true columns to the measured ones (:mod:`.sensor`), so that a diagnosis
identifies them jointly with the physics candidates. Each has its own signature:

* ``torque_gain`` — per joint, ``tau_j`` reads (1 + g_j)·τ_j: the replay, driven by the
  measured torque, pushes too hard in proportion to the load (stance knees and hips);
* ``torque_offset`` — per joint, ``tau_j`` reads τ_j + o_j [N·m]: a constant push, seen in
  swing as much as in stance;
* ``encoder_offset`` — per joint, ``q_j`` reads q_j + δ_j [rad]: every replay starts from
  a wrong posture and its joint-angle outputs are shifted by δ_j (a replay inverts the
  map on its initial state, ``validation/replay/measurement.py``);
* ``encoder_gain`` — per joint, ``q_j`` and ``dq_j`` read (1 + g_j)·q_j, (1 + g_j)·q̇_j (a
  wrong gear ratio or encoder resolution): like an offset it changes every replay's
  initial posture, but in proportion to the angle — an offset and a gain are told apart
  by how the error varies with the angle over the gait;
* ``force_sensor_gain`` — per world axis, ``grf_i`` reads (1 + g_i)·F_i (the bias is the
  library's ``force_sensor_bias``);
* ``torque_time_offset`` — ``tau_*`` is stamped d [s] late relative to the kinematics:
  measured τ(t) = τ_true(t − d) (linear interpolation, held at the ends). The map mixes
  samples, so it carries its inverse (:func:`torque_time_offset_inverse`); the others
  are inverted sample by sample.

* ``trunk_attitude_bias`` — the trunk orientation estimate is off by a small roll and
  pitch: the measured ``base_q*`` is q ⊗ q_b, q_b = R_x(roll)·R_y(pitch) in the trunk
  frame (an IMU mounted or levelled askew, an estimator's attitude drift); every replay
  starts with the trunk tilted (a replay inverts the map on its initial orientation,
  ``validation/replay/measurement.py``), which shows in the horizontal foot forces and
  the hip angles. It carries its inverse (q_meas ⊗ q_b⁻¹).

**Opt-in.** Importing this module registers the family (:func:`register_measurement`,
idempotent); :mod:`granular_mpc.effects` does not import it, so the default candidates of
``diagnose`` (every registered effect) stay the library's seven — the family has 30
parameters, 27 of which change a replay's inputs and need replays of their own. Pass
``candidates=[…library…, *MEASUREMENT]`` (or ``--effect-file`` this module's path).

Parameters are named per joint of the biped (``yobogo10s``: :data:`JOINTS`); on a robot
with other joint names the per-joint effects change nothing (and are reported as
candidates without sensitivity).
"""

from __future__ import annotations

import numpy as np

from ..columns import BASE_QUATERNION
from ..rotations import quat_mul_rows_wxyz, quat_rows_wxyz_from_rotvec
from .api import register_sensor_effect
from .params import Param
from .registry import registered_names
from .state import SensorContext

#: the biped's actuated joints (models/yobogo10s.yaml), the per-joint parameters' suffixes
JOINTS = ("left_hip_abd", "left_hip_pitch", "left_knee", "right_hip_abd", "right_hip_pitch",
          "right_knee")
#: the family's effect names
MEASUREMENT = ("torque_gain", "torque_offset", "encoder_offset", "encoder_gain",
               "force_sensor_gain", "torque_time_offset", "trunk_attitude_bias")
TAG = "measurement"


def _per_joint(prefix: str, default: float, lo: float, hi: float, unit: str, doc: str
               ) -> dict[str, Param]:
    return {f"{prefix}_{j}": Param(default, lo, hi, unit, f"{doc} of {j}") for j in JOINTS}


def _col(cols, name: str) -> np.ndarray:
    return np.asarray(cols[name], dtype=float)


def torque_gain(cols, p, ctx: SensorContext):
    """Torque sensing gain error per joint: tau_j reads (1 + g_j)·τ_j."""
    return {f"tau_{j}": (1.0 + p[f"gain_{j}"]) * _col(cols, f"tau_{j}")
            for j in ctx.joint_names if f"gain_{j}" in p}


def torque_offset(cols, p, ctx: SensorContext):
    """Torque sensing offset per joint: tau_j reads τ_j + o_j [N·m]."""
    return {f"tau_{j}": _col(cols, f"tau_{j}") + p[f"offset_{j}"]
            for j in ctx.joint_names if f"offset_{j}" in p}


def encoder_offset(cols, p, ctx: SensorContext):
    """Encoder zero offset per joint: q_j reads q_j + δ_j [rad]."""
    return {f"q_{j}": _col(cols, f"q_{j}") + p[f"delta_{j}"]
            for j in ctx.joint_names if f"delta_{j}" in p}


def encoder_gain(cols, p, ctx: SensorContext):
    """Encoder gain error per joint: q_j reads (1 + g_j)·q_j and dq_j (1 + g_j)·q̇_j."""
    out = {}
    for j in ctx.joint_names:
        if f"scale_{j}" not in p:
            continue
        g = 1.0 + p[f"scale_{j}"]
        out[f"q_{j}"] = g * _col(cols, f"q_{j}")
        if f"dq_{j}" in cols:
            out[f"dq_{j}"] = g * _col(cols, f"dq_{j}")
    return out


def force_sensor_gain(cols, p, ctx: SensorContext):
    """Foot force-sensor gain error per world axis: grf_i reads (1 + g_i)·F_i."""
    return {f"grf_{a}": (1.0 + p[f"gain_{a}"]) * _col(cols, f"grf_{a}") for a in "xyz"}


def torque_time_offset(cols, p, ctx: SensorContext):
    """Torque stream stamped d late relative to the kinematics: τ_meas(t) = τ(t − d)."""
    t = np.asarray(ctx.time, dtype=float)
    d = float(p["delay"])
    return {f"tau_{j}": np.interp(t - d, t, _col(cols, f"tau_{j}"))
            for j in ctx.joint_names if f"tau_{j}" in cols}


#: refinement steps of a fractional shift's inverse (:func:`torque_time_offset_inverse`)
SHIFT_REFINEMENTS = 3


def torque_time_offset_inverse(cols, p, ctx: SensorContext):
    """The true torques under :func:`torque_time_offset`: τ(t) ≈ τ_meas(t + d), exact for a
    whole number of samples (away from the ends, where the stream is held); a fractional
    shift is refined by :data:`SHIFT_REFINEMENTS` steps x ← x − S₊(S₋x − m) (S₋ the delay,
    S₊ the advance)."""
    t = np.asarray(ctx.time, dtype=float)
    d = float(p["delay"])
    out = {}
    for j in ctx.joint_names:
        c = f"tau_{j}"
        if c not in cols:
            continue
        m = _col(cols, c)
        x = np.interp(t + d, t, m)
        for _ in range(SHIFT_REFINEMENTS):
            x = x - np.interp(t + d, t, np.interp(t - d, t, x) - m)
        out[c] = x
    return out



def _attitude(cols, p, inverse: bool) -> dict[str, np.ndarray]:
    """``base_q*`` (w, x, y, z) right-multiplied by q_b = R_x(roll)·R_y(pitch), or by its
    inverse."""
    qb = quat_mul_rows_wxyz(quat_rows_wxyz_from_rotvec([[p["roll"], 0.0, 0.0]]),
                            quat_rows_wxyz_from_rotvec([[0.0, p["pitch"], 0.0]]))
    if inverse:
        qb = qb * np.array([1.0, -1.0, -1.0, -1.0])
    q = np.column_stack([_col(cols, c) for c in BASE_QUATERNION])
    out = quat_mul_rows_wxyz(q, np.repeat(qb, len(q), axis=0))
    return {c: out[:, i] for i, c in enumerate(BASE_QUATERNION)}


def trunk_attitude_bias(cols, p, ctx: SensorContext):
    """Trunk attitude estimate off by a small roll and pitch: base_q reads q ⊗ q_b,
    q_b = R_x(roll)·R_y(pitch) (trunk frame)."""
    return _attitude(cols, p, inverse=False)


def trunk_attitude_bias_inverse(cols, p, ctx: SensorContext):
    """The true trunk orientation under :func:`trunk_attitude_bias`: q_meas ⊗ q_b⁻¹."""
    return _attitude(cols, p, inverse=True)


def register_measurement() -> tuple[str, ...]:
    """Register the family (those of its names not yet registered); returns its names."""
    have = set(registered_names())
    specs = (
        (torque_gain, _per_joint("gain", 0.05, -0.5, 0.5, "-", "torque gain error"), None,
         ("load-proportional torque error: stance joints", "tau_*")),
        (torque_offset, _per_joint("offset", 0.3, -5.0, 5.0, "N·m", "torque offset"), None,
         ("constant torque error in stance and swing", "tau_*")),
        (encoder_offset, _per_joint("delta", 0.01, -0.2, 0.2, "rad", "encoder zero offset"),
         None, ("constant joint-angle shift; the replay's initial posture", "q_*")),
        (encoder_gain, _per_joint("scale", 0.02, -0.3, 0.3, "-", "encoder gain error"),
         None, ("angle-proportional joint-angle error; the replay's initial posture",
                "q_*", "dq_*")),
        (force_sensor_gain, {f"gain_{a}": Param(0.05, -0.5, 0.5, "-",
                                                 f"force-sensor gain error on grf_{a}")
                             for a in "xyz"}, "gain_z",
         ("force-proportional error of grf_*",)),
        (torque_time_offset, {"delay": Param(0.005, -0.05, 0.05, "s",
                                             "torque stream lag behind the kinematics")},
         "delay", ("torque rate: fast torque changes at touchdown and lift-off", "tau_*")),
        (trunk_attitude_bias, {"roll": Param(0.01, -0.1, 0.1, "rad", "trunk roll bias"),
                               "pitch": Param(0.01, -0.1, 0.1, "rad", "trunk pitch bias")},
         "pitch", ("the replay's initial trunk tilt: horizontal foot forces, hip angles",
                   "base_q*")),
    )
    inverses = {"torque_time_offset": torque_time_offset_inverse,
                "trunk_attitude_bias": trunk_attitude_bias_inverse}
    for fn, params, main, depends in specs:
        name = fn.__name__
        if name in have:
            continue
        register_sensor_effect(name, params=params, main=main or next(iter(params)),
                               neutral={k: 0.0 for k in params}, depends_on=depends,
                               tags=(TAG,), inverse=inverses.get(name))(fn)
    return MEASUREMENT


register_measurement()

__all__ = ["register_measurement", "MEASUREMENT", "JOINTS", "TAG", "torque_gain",
           "torque_offset", "encoder_offset", "force_sensor_gain", "torque_time_offset",
           "torque_time_offset_inverse", "SHIFT_REFINEMENTS", "trunk_attitude_bias",
           "trunk_attitude_bias_inverse", "encoder_gain"]
