"""Foot forces and touchdowns from the joint torques (no foot sensor).

A lab without force sensors in the feet still measures the joint torques (motor
currents). The rigid-body dynamics of each leg then tell the force on its foot: for the
free-flyer model with generalized coordinates (base, joints),

    M(q) a + h(q, v) = Sᵀ τ + Σ_feet J_C(q)ᵀ F,

and the rows of one leg's three joints involve only that leg's foot force F (applied at
its contact point C, the mean lowest sole point of :func:`~.foot_geometry.patch_points`):

    J_C,legᵀ F = [RNEA(q, v, a)]_leg − τ_leg          (3 × 3, solved for F in W).

Inputs per sample: the joint angles (encoders), the trunk orientation and angular
velocity (IMU), the measured joint torques. The joint rates and accelerations are
Savitzky–Golay derivatives of the angles (cubic, ``window`` samples); the trunk's angular
acceleration the derivative of the gyro. **Not measured, neglected:** the trunk's linear
velocity (it does not enter: a uniform translation changes no joint torque) and its
linear acceleration (it does: the leg's mass × the trunk's acceleration, ≈ 2 kg × 1–2
m/s² ≈ a few N on the synthetic walk). The estimate is therefore an **estimate**, never a
measured ``foot_force`` channel: the reports say so (``touchdown_source``).

Touchdowns (:func:`force_touchdown`): the landing foot's estimated normal force, averaged
over two samples, crosses a threshold set from its own noise level in swing
(:data:`THRESHOLD_SIGMAS` robust standard deviations above the swing median, at least
:data:`MIN_THRESHOLD_N`). It does not wait for the foot to stop, so the surface height at
the touchdown is not biased by the sinking that follows, which depends on the terrain
(the kinematic detector :func:`~.estimation.landing`). Errors measured on the synthetic
data: ``docs/import.md`` and ``tests/test_contact_estimation.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.signal import savgol_filter

from ..robot.model import SIDES, Biped
from ..rotations import xyzw_from_wxyz
from .estimation import Landing, landing
from .foot_geometry import patch_points

#: Savitzky–Golay window of the joint-angle derivatives [samples] (cubic fit)
FORCE_WINDOW = 7
#: the touchdown threshold: this many robust standard deviations (of the mean of
#: :data:`MEAN_ROWS` samples) above the swing median …
THRESHOLD_SIGMAS = 4.0
#: … and at least this [N]
MIN_THRESHOLD_N = 3.0
#: the detector compares the mean of this many consecutive samples with the threshold
MEAN_ROWS = 2
#: rows searched before / after the kinematic label change; swing rows used for the
#: noise level, ending where the search window starts [samples]
FORCE_SEARCH = (16, 8)
SWING_ROWS = 40
#: a detection where the landing foot is still this high above where it stops is a
#: false alarm (a force spike in swing) [m]
MAX_HEIGHT_ABOVE_STOP_M = 0.012


@dataclass(frozen=True)
class FootForces:
    """Foot forces estimated from the joint torques of one trial (an estimate, not a
    measured channel).

    Attributes:
        force: side → force of the ground on the foot at its contact point [N] (W),
            shape (n, 3).
    """

    force: dict

    def normal(self, side: str) -> np.ndarray:
        """The vertical force on foot ``side`` [N], shape (n,)."""
        return self.force[side][:, 2]


def estimate_foot_forces(biped: Biped, quat_wxyz: np.ndarray, q_a: np.ndarray,
                         tau: np.ndarray, w_B: np.ndarray, sample_rate_hz: float, *,
                         window: int = FORCE_WINDOW) -> FootForces:
    """Each foot's ground force from the leg dynamics and the measured joint torques.

    Args:
        biped: the robot (its inertias and 3-joint legs).
        quat_wxyz: trunk orientation (w, x, y, z) per sample (IMU), shape (n, 4).
        q_a: joint angles [rad] (actuator order), shape (n, n_joints).
        tau: measured joint torques [N m], shape (n, n_joints).
        w_B: trunk angular velocity in B [rad/s] (gyro), shape (n, 3).
        sample_rate_hz: sample rate [Hz].
        window: Savitzky–Golay window of the angle derivatives [samples].

    Returns:
        :class:`FootForces` (see the module docstring for the model and what it neglects).
    """
    quat = np.asarray(quat_wxyz, dtype=float)
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    q_a = np.asarray(q_a, dtype=float)
    tau = np.asarray(tau, dtype=float)
    n = q_a.shape[0]
    dt = 1.0 / sample_rate_hz
    w = min(window, n if n % 2 == 1 else n - 1)
    if w >= 5:
        qs = savgol_filter(q_a, w, 3, axis=0, mode="interp")
        dq = savgol_filter(q_a, w, 3, deriv=1, delta=dt, axis=0, mode="interp")
        ddq = savgol_filter(q_a, w, 3, deriv=2, delta=dt, axis=0, mode="interp")
        dw = savgol_filter(np.asarray(w_B, float), w, 3, deriv=1, delta=dt, axis=0,
                           mode="interp")
    else:
        qs, dq = q_a, np.gradient(q_a, dt, axis=0) if n > 1 else np.zeros_like(q_a)
        ddq = np.gradient(dq, dt, axis=0) if n > 1 else np.zeros_like(q_a)
        dw = np.gradient(np.asarray(w_B, float), dt, axis=0) if n > 1 else np.zeros((n, 3))
    model, data = biped.model, biped.create_data()
    legs = {s: biped.idx_v[[k for k, j in enumerate(biped.joint_names) if j.startswith(s + "_")]]
            for s in SIDES}
    cols = {s: [k for k, j in enumerate(biped.joint_names) if j.startswith(s + "_")]
            for s in SIDES}
    out = {s: np.zeros((n, 3)) for s in SIDES}
    v = np.zeros(model.nv)
    a = np.zeros(model.nv)
    for k in range(n):
        q = biped.q_from_parts(np.zeros(3), xyzw_from_wxyz(quat[k]), qs[k])
        v[:] = 0.0
        a[:] = 0.0
        v[3:6] = w_B[k]
        v[biped.idx_v] = dq[k]
        a[3:6] = dw[k]
        a[biped.idx_v] = ddq[k]
        rnea = pin.rnea(model, data, q, v, a)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for s in SIDES:
            fid = biped.foot_frame[s]
            oMf = data.oMf[fid]
            c = patch_points(biped, oMf).mean(axis=0)
            jac = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            jc = jac[:3] - pin.skew(c - oMf.translation) @ jac[3:]
            out[s][k] = np.linalg.solve(jc[:, legs[s]].T, rnea[legs[s]] - tau[k, cols[s]])
    return FootForces(out)


@dataclass(frozen=True)
class ForceTouchdown:
    """A touchdown found from a foot's estimated normal force.

    Attributes:
        row: the first row of the touchdown: the mean of the force over rows
            [row, row + :data:`MEAN_ROWS`) is above the threshold.
        threshold: the force threshold above the swing median [N].
        sigma: the robust standard deviation of the force in swing [N] (one sample).
    """

    row: int
    threshold: float
    sigma: float


def force_touchdown(fz: np.ndarray, label_row: int, *, height: np.ndarray | None = None,
                    max_height: float = MAX_HEIGHT_ABOVE_STOP_M,
                    search: tuple[int, int] = FORCE_SEARCH, swing_rows: int = SWING_ROWS,
                    sigmas: float = THRESHOLD_SIGMAS, mean_rows: int = MEAN_ROWS,
                    min_threshold: float = MIN_THRESHOLD_N) -> ForceTouchdown | None:
    """The touchdown of a landing foot near its kinematic stance-label change.

    The swing level and noise are the median and the robust standard deviation σ (1.4826 ×
    MAD) of the foot's force over the ``swing_rows`` rows before the search window (the
    foot in the air); the touchdown is the first row j of the search window where the
    mean of ``mean_rows`` samples from j exceeds the swing level by
    max(``sigmas`` σ / √``mean_rows``, ``min_threshold``) — a false alarm rate of ≈ 3e-5
    per row for Gaussian noise — and the foot's ``height`` (if given) is at most
    ``max_height``.

    Args:
        fz: the landing foot's estimated vertical force per sample [N].
        label_row: the first row labelled with the landing foot (kinematic labels: late
            on sand, by 0–24 ms on the synthetic data).
        height: the foot's height above where it stops [m] per sample (leg kinematics),
            to reject force spikes in swing; None: not checked.
        max_height: see ``height`` [m].
        search: rows searched before / after ``label_row``.
        swing_rows: rows before the search window giving the swing level and noise.
        sigmas, mean_rows, min_threshold: the threshold (above).

    Returns:
        :class:`ForceTouchdown`, or None when the swing rows do not fit in the trial or
        no row qualifies (the caller keeps its kinematic touchdown).
    """
    fz = np.asarray(fz, dtype=float)
    lo = label_row - search[0]
    hi = min(label_row + search[1] + 1, fz.size - mean_rows + 1)
    if lo - swing_rows < 0 or hi <= lo:
        return None
    swing = fz[lo - swing_rows:lo]
    base = float(np.median(swing))
    sigma = 1.4826 * float(np.median(np.abs(swing - base)))
    thr = max(sigmas * sigma / np.sqrt(mean_rows), min_threshold)
    for j in range(lo, hi):
        if float(np.mean(fz[j:j + mean_rows])) - base > thr and (
                height is None or height[j] <= max_height):
            return ForceTouchdown(j, thr, sigma)
    return None


def refined_landing(fz: np.ndarray, dz: np.ndarray, label_row: int,
                    sample_rate_hz: float) -> tuple[Landing, str]:
    """Where a landing foot meets the ground, for a stance phase with a kinematic label.

    From the joint torques when the estimated force finds it (:func:`force_touchdown`;
    the window starts at the touchdown row, the surface is the foot's height there),
    else from the leg kinematics (:func:`~.estimation.landing`: the foot's stop).

    Args:
        fz: the landing foot's estimated vertical force per sample [N].
        dz: landing-foot minus stance-foot contact-point height per sample [m].
        label_row: the first row labelled with the landing foot.
        sample_rate_hz: sample rate [Hz].

    Returns:
        (:class:`~.estimation.Landing`, source: ``"joint torques"`` or ``"leg kinematics"``).
    """
    kin = landing(dz, label_row, sample_rate_hz)
    td = force_touchdown(fz, label_row, height=dz - dz[kin.stop])
    if td is None:
        return kin, "leg kinematics"
    return Landing(td.row, td.row), "joint torques"


__all__ = ["FootForces", "estimate_foot_forces", "ForceTouchdown", "force_touchdown",
           "refined_landing",
           "FORCE_WINDOW", "THRESHOLD_SIGMAS", "MIN_THRESHOLD_N", "MEAN_ROWS", "FORCE_SEARCH",
           "SWING_ROWS", "MAX_HEIGHT_ABOVE_STOP_M"]
