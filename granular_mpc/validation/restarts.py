"""Restarts within a stance: shorter replays from the measured state (multiple shooting).

A stance window is replayed open loop from its first sample under the measured torques,
and a biped under open-loop torques diverges: noise in the first state and the torques
grows over the stance, and a term that takes energy out of the joints is fitted larger
to slow it (``docs/validation.md`` §5.3.12, §6). A *restart* cuts the replay: from its
row on, the window is replayed again from the measured state there — the smoothed
configuration and velocity, the stance foot buried at its measured intrusion and loaded
with its measured force (:func:`~.foot_state.foot_init`), its deepest depth so far and
its time in stance.

A restart is placed only where its contact state is measured: with intrusion recorded,
the stance foot at least ``min_depth`` deep, and the other foot in the air (its contact
point :data:`SWING_CLEARANCE` above its own free surface by the leg kinematics: in double
support the other foot's force and depth are not recorded, format v1). A segment is at
least :data:`MIN_SEGMENT_SAMPLES` long.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigError
from ..robot.model import SIDES, Biped
from .foot_geometry import patch_points
from .foot_state import FootInit, foot_init

#: the other foot's contact point must be this far above its free surface [m]
SWING_CLEARANCE = 5e-3
#: shortest replay segment [samples]
MIN_SEGMENT_SAMPLES = 10
#: the joint rates at a restart: the derivative of a polynomial of this degree fitted to
#: the measured angles over :data:`RATE_WINDOW` samples centred on the row. Mid-stance the
#: swing leg is fast and the window's quadratic smoother (15 samples) reads its rates
#: 0.16 rad/s RMS low; a restart from them diverges within the segment (noise-free: the
#: second half's knee replay error 8 → 18 mrad against the whole stance's). On the restart
#: rows of a null plant run (``sand_walk``, 3 trials × 7 stances, 24 restarts) the rate
#: errors, noise-free / noise level 1, were: quadratic over 15 samples 0.164 / 0.164
#: rad/s; quartic over 15, 21, 25, 31: 0.004 / 0.072, 0.004 / 0.045, 0.006 / 0.037,
#: 0.013 / 0.032; the measured ``dq_*`` sample — / 0.19 (``docs/validation.md`` §5.3.14)
RATE_DEGREE = 4
RATE_WINDOW = 25


@dataclass(frozen=True)
class Restart:
    """The state a window's replay restarts from (local frame of the window).

    Attributes:
        start: the first scored sample of the segment (index into the window's samples);
            the state is the measured one a sample before it.
        q0, v0: configuration (13) and velocity (12), Pinocchio conventions.
        feet: contact state of (left, right).
    """

    start: int
    q0: np.ndarray
    v0: np.ndarray
    feet: tuple[FootInit, FootInit]


def check_segments(value: object, key: str = "replay_segments") -> int:
    """``value`` as a number of replay segments per stance (an integer ≥ 1).

    Raises:
        ConfigError: naming ``key``, the value and what is allowed.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ConfigError("not a number of replay segments per stance", key=key, value=value,
                          allowed="an integer ≥ 1 (1: one replay per stance)")
    return int(value)


def joint_rates(qa: np.ndarray, k: int, dt: float) -> np.ndarray:
    """The joint rates at row ``k`` [rad/s]: the derivative of a polynomial of degree
    :data:`RATE_DEGREE` fitted to the angles ``qa`` (rows × joints) over
    :data:`RATE_WINDOW` rows centred on ``k`` (fewer at a trial's ends)."""
    h = RATE_WINDOW // 2
    a, b = max(0, k - h), min(qa.shape[0], k + h + 1)
    t = (np.arange(a, b) - k) * dt
    return np.polyfit(t, qa[a:b], min(RATE_DEGREE, b - a - 2))[-2]


def stance_restarts(st: Any, biped: Biped, data: pin.Data, *, side: str, k0: int, stop: int,
                    origin: np.ndarray, trail: FootInit, K: float, segments: int,
                    min_depth: float) -> tuple[Restart, ...]:
    """Restarts that cut the window of rows (k0, stop) into ``segments`` about equal parts.

    Args:
        st: the trial's :class:`~.prepare.TrialStates`.
        data: Pinocchio data (its frame placements are overwritten).
        side: the stance foot; k0: the row of the window's first state; stop: its end.
        origin: the window's local-frame origin in W [m].
        trail: the other foot's state at the window's start (its free surface).
        K: contact stiffness per patch [N/m].
        segments: parts per stance (1: no restart).
        min_depth: the stance foot's shallowest measured depth at a restart [m].
    """
    if segments <= 1 or not st.has_intrusion:
        return ()
    i = SIDES.index(side)
    other = SIDES[1 - i]
    n = stop - k0 - 1
    out: list[Restart] = []
    last = 0
    for j in range(1, segments):
        s = int(round(j * n / segments))            # first scored sample of the segment
        if s - last < MIN_SEGMENT_SAMPLES or n - s < MIN_SEGMENT_SAMPLES:
            continue
        k = k0 + s                                  # the row of its first state
        depth = float(st.intr_s[k, 2])
        if depth < min_depth:
            continue
        q = st.q(k)
        pin.framesForwardKinematics(biped.model, data, q)
        lead_W = patch_points(biped, data.oMf[biped.foot_frame[side]]).mean(axis=0)
        swing_W = patch_points(biped, data.oMf[biped.foot_frame[other]]).mean(axis=0)
        # the other foot's free surface: its own footprint's, else the stance foot's
        surface_o = trail.surface + origin[2] if trail.in_contact else lead_W[2] + depth
        if swing_W[2] - surface_o < SWING_CLEARANCE:
            continue
        force = st.grf_s[k] if st.has_force else st.estimated_force(side, k)
        lead = foot_init(biped, data, side, depth=depth, intrusion=st.intr_s[k], force=force,
                         in_contact=True, depth_max=float(st.intr_s[k0 + 1:k + 1, 2].max()),
                         t_stance=float(st.time[k] - st.time[k0]), K=K, origin=origin)
        swing = foot_init(biped, data, other, depth=float(surface_o - swing_W[2]),
                          intrusion=np.zeros(3), force=np.zeros(3), in_contact=False,
                          depth_max=0.0, t_stance=0.0, K=K, origin=origin)
        feet = [None, None]
        feet[i], feet[1 - i] = lead, swing
        q_loc = q.copy()
        q_loc[0:3] -= origin
        out.append(Restart(s, q_loc, st.v(k, joint_rates(st.qa_raw, k, st.dt)),
                           (feet[0], feet[1])))
        last = s
    return tuple(out)


__all__ = ["Restart", "stance_restarts", "check_segments", "joint_rates", "RATE_DEGREE", "RATE_WINDOW", "SWING_CLEARANCE", "MIN_SEGMENT_SAMPLES"]
