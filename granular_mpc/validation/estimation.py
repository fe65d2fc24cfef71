"""Trunk position and linear velocity from joint encoders and an IMU (leg odometry).

A lab without motion capture measures the joint angles and the trunk's orientation and
angular velocity (IMU); the replays (:mod:`.prepare`) also need the trunk's position and
linear velocity at each window start. They are estimated here from the **stance leg's
kinematics**: the stance foot is the anchor, fixed in the world while it carries the
robot, and the trunk hangs from it through the measured leg.

Model, per sample k (W: world, B: trunk):

* the stance side is the sample's ``stance`` label (``none``: the last stance side is kept);
* r_k = p_C − p_B: the stance foot's lowest sole point C relative to the trunk origin, from
  the forward kinematics of the measured joint angles with the measured orientation R_WB
  (:func:`~.foot_geometry.patch_points`, mean over the slices);
* the curved sole **rolls without slipping**: while the sole angle ψ (the arc angle of the
  lowest point) changes by Δψ, the contact point moves along the ground by R_foot Δψ in
  the foot's horizontal heading h;
* p_B,k = A + R_foot (ψ_k − ψ_A) h_k − r_k, with A the anchor (the contact point when the
  foot became the stance foot, ψ_A its sole angle then). At a change of stance foot the
  new anchor is placed where the estimate puts the new foot at that sample, so the
  estimated trajectory is continuous;
* the linear velocity: the stance sole's material point at C does not move, so
  v_W_B = −(velocity of that point for a trunk that only rotates), from the gyro and the
  joint rates (:func:`contact_velocities`); without them, the Savitzky–Golay derivative
  of the estimated position within each anchor run.

**Assumptions and their bias.** The anchor neither sinks nor slips. On sand it does both:
while the stance foot sinks by d (5–15 mm per stance on the synthetic dry sand) the
estimated trunk stays d too high, and the error carries over to the next anchor, so the
absolute height drifts by the sum of the sinkages (≈ 1 cm per step) and x, y by the
slips. The replays use the trunk state *relative to the stance foot's touchdown point*
(the local frame of :mod:`.prepare`), where the drift cancels; what remains is the
**velocity error**: the anchor's own velocity (its sinking and slip speed) at the
window start, which the estimate misses — late in the old stance, when a window starts,
the old foot has stopped sinking and is pulling out (measured on the synthetic data:
``tests/test_estimation.py``). The absolute x, y of the walk are unobservable: the first
anchor is put at the world origin on z = 0 (position-dependent terrain forces and the
``x_position`` feature therefore see the walk shifted).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pinocchio as pin

from ..robot.model import SIDES, Biped
from ..rotations import xyzw_from_wxyz
from .foot_geometry import patch_points, sole_angle


@dataclass(frozen=True)
class TrunkEstimate:
    """Estimated trunk position and velocity of one trial.

    Attributes:
        position: p_W_B per sample [m] (W; first anchor at the origin), shape (n, 3),
            not smoothed.
        velocity: v_W_B per sample [m/s] (W), shape (n, 3), Savitzky–Golay derivative.
        anchor: the stance side used as the anchor per sample (``left`` / ``right``).
    """

    position: np.ndarray
    velocity: np.ndarray
    anchor: np.ndarray


def contact_offsets(biped: Biped, quat_wxyz: np.ndarray, q_a: np.ndarray,
                    side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every sample: the foot's lowest sole point relative to the trunk origin in W
    [m] (n, 3), its sole angle ψ [rad] (n,) and the foot's horizontal heading (n, 2)."""
    data = biped.create_data()
    fid = biped.foot_frame[side]
    n = q_a.shape[0]
    r = np.empty((n, 3))
    psi = np.empty(n)
    head = np.empty((n, 2))
    for k in range(n):
        q = biped.q_from_parts(np.zeros(3), xyzw_from_wxyz(quat_wxyz[k]), q_a[k])
        pin.framesForwardKinematics(biped.model, data, q)
        oMf = data.oMf[fid]
        r[k] = patch_points(biped, oMf).mean(axis=0)
        psi[k] = sole_angle(biped, oMf)
        hx, hy = oMf.rotation[0, 0], oMf.rotation[1, 0]
        hn = float(np.hypot(hx, hy)) or 1.0
        head[k] = hx / hn, hy / hn
    return r, psi, head


def anchor_sides(labels: Sequence[str]) -> np.ndarray:
    """The anchor side per sample: the stance label, ``none`` replaced by the last stance
    side (by the first one before any stance). All ``none``: ``left``."""
    labels = np.asarray(labels, dtype=object)
    known = [s for s in labels if s in SIDES]
    cur = known[0] if known else SIDES[0]
    out = np.empty(labels.size, dtype=object)
    for k, s in enumerate(labels):
        if s in SIDES:
            cur = s
        out[k] = cur
    return out


def estimate_trunk(biped: Biped, quat_wxyz: np.ndarray, q_a: np.ndarray,
                   labels: Sequence[str], sample_rate_hz: float, *,
                   dq_a: np.ndarray | None = None, w_B: np.ndarray | None = None,
                   smooth_window: int = 15) -> TrunkEstimate:
    """Trunk position and linear velocity from joint angles, IMU orientation and stance
    labels (leg odometry on the stance foot; see the module docstring).

    Args:
        biped: the robot.
        quat_wxyz: trunk orientation (w, x, y, z) per sample, shape (n, 4) (smoothed
            values give a smoother estimate).
        q_a: joint angles [rad] (actuator order), shape (n, n_joints).
        labels: stance label per sample (``left`` / ``right`` / ``none``).
        sample_rate_hz: sample rate [Hz].
        dq_a: joint rates [rad/s], (n, n_joints); with ``w_B`` the velocity is the
            kinematic one (below), else the derivative of the estimated position.
        w_B: trunk angular velocity in B [rad/s] (gyro), shape (n, 3).
        smooth_window: Savitzky–Golay window of the position derivative [samples].

    Returns:
        :class:`TrunkEstimate`. The velocity with ``dq_a`` and ``w_B``:
        v_W_B = −(v_F + ω_F × (p_C − p_F)) for the stance foot frame F and its contact
        point C computed with a trunk at rest in translation — the sole's material point
        at C does not move (rolling without slipping). A derivative of the position would
        amplify the orientation noise by the lever arm of the leg (0.5° of IMU noise ×
        0.5 m ≈ 4 mm per sample, ≈ 0.1 m/s after a 15-sample derivative); here the gyro
        and the encoder rates carry it.
    """
    quat = np.asarray(quat_wxyz, dtype=float)
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    q_a = np.asarray(q_a, dtype=float)
    n = q_a.shape[0]
    sides = anchor_sides(labels)
    geo = {s: contact_offsets(biped, quat, q_a, s) for s in SIDES if (sides == s).any()}
    radius = biped.config.foot.radius
    p = np.empty((n, 3))
    anchor, psi_a = np.zeros(3), 0.0
    for k in range(n):
        r, psi, head = (g[k] for g in geo[sides[k]])
        if k == 0:
            anchor, psi_a = np.zeros(3), psi           # the first contact point: origin
        elif sides[k] != sides[k - 1]:
            # continuity: the old anchor gives p at k, the new foot is put where p puts it
            r_o, psi_o, head_o = (g[k] for g in geo[sides[k - 1]])
            p_k = anchor + radius * (psi_o - psi_a) * np.r_[head_o, 0.0] - r_o
            anchor, psi_a = p_k + r, psi
        p[k] = anchor + radius * (psi - psi_a) * np.r_[head, 0.0] - r
    if dq_a is not None and w_B is not None:
        v = -contact_velocities(biped, quat, q_a, np.asarray(dq_a, float),
                                np.asarray(w_B, float), sides)
    else:
        # the derivative within each anchor run: the new stance foot sinks fast after its
        # touchdown, which a window across the change would smear into the samples before
        v = np.zeros_like(p)
        change = np.flatnonzero(sides[1:] != sides[:-1]) + 1
        for a, b in zip(np.r_[0, change], np.r_[change, n]):
            v[a:b] = _derivative(p[a:b], smooth_window, 1.0 / sample_rate_hz)
    return TrunkEstimate(p, v, sides)


def contact_velocities(biped: Biped, quat_wxyz: np.ndarray, q_a: np.ndarray,
                       dq_a: np.ndarray, w_B: np.ndarray, sides: Sequence[str]) -> np.ndarray:
    """Per sample, the velocity in W [m/s] of the sole's material point at the contact
    point of foot ``sides[k]`` for a trunk that rotates (``w_B``) but does not translate,
    shape (n, 3)."""
    data = biped.create_data()
    n = q_a.shape[0]
    out = np.empty((n, 3))
    v = np.zeros(biped.model.nv)
    for k in range(n):
        q = biped.q_from_parts(np.zeros(3), xyzw_from_wxyz(quat_wxyz[k]), q_a[k])
        v[:] = 0.0
        v[3:6] = w_B[k]
        v[biped.idx_v] = dq_a[k]
        fid = biped.foot_frame[sides[k]]
        pin.forwardKinematics(biped.model, data, q, v)
        oMf = pin.updateFramePlacement(biped.model, data, fid)
        vel = pin.getFrameVelocity(biped.model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        c = patch_points(biped, oMf).mean(axis=0)
        out[k] = vel.linear + np.cross(vel.angular, c - oMf.translation)
    return out


def _derivative(x: np.ndarray, window: int, dt: float) -> np.ndarray:
    """Savitzky–Golay derivative (quadratic; shorter windows for short runs)."""
    from scipy.signal import savgol_filter

    n = x.shape[0]
    w = min(window, n if n % 2 == 1 else n - 1)
    if w >= 3:
        return savgol_filter(x, w, min(2, w - 1), deriv=1, delta=dt, axis=0, mode="interp")
    return np.gradient(x, dt, axis=0) if n > 1 else np.zeros_like(x)


#: touchdown search (:func:`touchdown_row`): rows before / after the label change, and the
#: rows before / after a candidate kink in the two-segment fit [samples]
TOUCHDOWN_SEARCH = (20, 3)
TOUCHDOWN_FIT = (20, 6)


def touchdown_row(dz: np.ndarray, label_row: int, *, search: tuple[int, int] = TOUCHDOWN_SEARCH,
                  fit: tuple[int, int] = TOUCHDOWN_FIT) -> int:
    """The touchdown sample of a landing foot near a kinematic stance label change.

    Kinematic stance labels (:mod:`.dataformat.stance_derive`) switch when the landing foot
    has come down to the stance foot's level; on sand the stance foot has sunk, so the
    switch comes late (0–15 samples at 500 Hz on the synthetic dry sand). The impact
    shows as a kink in the landing foot's height above the stance foot, dz = z_new − z_old
    (leg kinematics only): it descends fast before, slowly after (it starts to sink). For
    every candidate row j in [label_row − search[0], label_row + search[1]], dz over
    [j − fit[0], j + fit[1]) is fitted by two line segments joined at j; the touchdown is
    the j whose increase of slope has the largest t-statistic. Measured on the synthetic
    data of ``tests/test_estimation.py`` (noise level 1): 1.5 samples mean absolute error,
    ≤ 5, against 2.6 and ≤ 15 for the label change itself.

    Args:
        dz: landing-foot minus stance-foot contact-point height per sample [m].
        label_row: the first row labelled with the landing foot.

    Returns:
        The first row with the landing foot on the ground (``label_row`` when no
        candidate fits).
    """
    best, row = -np.inf, int(label_row)
    pre, post = fit
    for j in range(label_row - search[0], label_row + search[1] + 1):
        lo, hi = j - pre, j + post
        if lo < 0 or hi > dz.size:
            continue
        t = np.arange(lo, hi, dtype=float) - j
        X = np.column_stack([np.ones_like(t), t, np.maximum(t, 0.0)])
        y = dz[lo:hi]
        beta = np.linalg.lstsq(X, y, rcond=None)[0]
        r = y - X @ beta
        var = float(r @ r) / (y.size - 3) * np.linalg.inv(X.T @ X)[2, 2]
        score = beta[2] / np.sqrt(var) if var > 0 else -np.inf
        if score > best:
            best, row = score, j
    return row


#: the rows searched for the landing foot's stop after its kinematic touchdown, and the
#: Savitzky–Golay window of its relative vertical velocity [samples]
STOP_SEARCH = 12
STOP_WINDOW = 9
START_BEFORE_STOP = 2


@dataclass(frozen=True)
class Landing:
    """Where a landing foot meets the ground, from the leg kinematics.

    Attributes:
        start: first row of the stance window (the foot still above the ground or just
            touching it): :func:`touchdown_row`, at most ``stop − 1``.
        stop: the row where the foot's descent relative to the stance foot stops
            (smallest |ż| of dz): its height there is the free surface (to within the
            few samples of sinking before the sand stops it, which the diagnosis's
            ``touchdown_depth`` absorbs) — insensitive to the timing, since ż ≈ 0 there.
    """

    start: int
    stop: int


def landing(dz: np.ndarray, label_row: int, sample_rate_hz: float) -> Landing:
    """:class:`Landing` of a foot whose kinematic stance label starts at ``label_row``.

    The fallback of :func:`~.contact_estimation.refined_landing`, which first looks for
    the touchdown in the foot force estimated from the joint torques (its surface is not
    biased by the sinking before the stop: ``docs/import.md``).

    Args:
        dz: landing-foot minus stance-foot contact-point height per sample [m].
        label_row: the first row labelled with the landing foot.
        sample_rate_hz: sample rate [Hz].
    """
    from scipy.signal import savgol_filter

    start = touchdown_row(dz, label_row)
    w = min(STOP_WINDOW, dz.size if dz.size % 2 == 1 else dz.size - 1)
    if w < 5:
        return Landing(start, start)
    v = savgol_filter(dz, w, 2, deriv=1, delta=1.0 / sample_rate_hz, mode="interp")
    lo = max(start, 0)
    hi = min(start + STOP_SEARCH + 1, dz.size)
    stop = lo + int(np.argmin(np.abs(v[lo:hi]))) if hi > lo else start
    return Landing(max(stop - START_BEFORE_STOP, 0), stop)


__all__ = ["TrunkEstimate", "estimate_trunk", "contact_offsets", "contact_velocities",
           "Landing", "landing", "STOP_SEARCH", "STOP_WINDOW",
           "anchor_sides",
           "touchdown_row", "TOUCHDOWN_SEARCH", "TOUCHDOWN_FIT"]
