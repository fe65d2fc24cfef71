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
* ``force_sensor_gain`` — per world axis, ``grf_i`` reads (1 + g_i)·F_i (the bias is the
  library's ``force_sensor_bias``);
* ``torque_time_offset`` — ``tau_*`` is stamped d [s] late relative to the kinematics:
  measured τ(t) = τ_true(t − d) (linear interpolation, held at the ends).

Not here: a trunk-attitude bias (the base columns drive a replay as measured and are not
inverted, so a bias on them cannot be identified by replays).

**Opt-in.** Importing this module registers the family (:func:`register_measurement`,
idempotent); :mod:`granular_mpc.effects` does not import it, so the default candidates of
``diagnose`` (every registered effect) stay the library's seven — the family has 22
parameters, 19 of which change a replay's inputs and need replays of their own. Pass
``candidates=[…library…, *MEASUREMENT]`` (or ``--effect-file`` this module's path).

Parameters are named per joint of the biped (``yobogo10s``: :data:`JOINTS`); on a robot
with other joint names the per-joint effects change nothing (and are reported as
candidates without sensitivity).
"""

from __future__ import annotations

import numpy as np

from .api import register_sensor_effect
from .params import Param
from .registry import registered_names
from .state import SensorContext

#: the biped's actuated joints (models/yobogo10s.yaml), the per-joint parameters' suffixes
JOINTS = ("left_hip_abd", "left_hip_pitch", "left_knee", "right_hip_abd", "right_hip_pitch",
          "right_knee")
#: the family's effect names
MEASUREMENT = ("torque_gain", "torque_offset", "encoder_offset", "force_sensor_gain",
               "torque_time_offset")
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


def force_sensor_gain(cols, p, ctx: SensorContext):
    """Foot force-sensor gain error per world axis: grf_i reads (1 + g_i)·F_i."""
    return {f"grf_{a}": (1.0 + p[f"gain_{a}"]) * _col(cols, f"grf_{a}") for a in "xyz"}


def torque_time_offset(cols, p, ctx: SensorContext):
    """Torque stream stamped d late relative to the kinematics: τ_meas(t) = τ(t − d)."""
    t = np.asarray(ctx.time, dtype=float)
    d = float(p["delay"])
    return {f"tau_{j}": np.interp(t - d, t, _col(cols, f"tau_{j}"))
            for j in ctx.joint_names if f"tau_{j}" in cols}


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
        (force_sensor_gain, {f"gain_{a}": Param(0.05, -0.5, 0.5, "-",
                                                 f"force-sensor gain error on grf_{a}")
                             for a in "xyz"}, "gain_z",
         ("force-proportional error of grf_*",)),
        (torque_time_offset, {"delay": Param(0.005, -0.05, 0.05, "s",
                                             "torque stream lag behind the kinematics")},
         "delay", ("torque rate: fast torque changes at touchdown and lift-off", "tau_*")),
    )
    for fn, params, main, depends in specs:
        name = fn.__name__
        if name in have:
            continue
        register_sensor_effect(name, params=params, main=main or next(iter(params)),
                               neutral={k: 0.0 for k in params}, depends_on=depends,
                               tags=(TAG,))(fn)
    return MEASUREMENT


register_measurement()

__all__ = ["register_measurement", "MEASUREMENT", "JOINTS", "TAG", "torque_gain",
           "torque_offset", "encoder_offset", "force_sensor_gain", "torque_time_offset"]
