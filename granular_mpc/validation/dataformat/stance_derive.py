"""Stance labels for trials that have none: from foot force, or from leg kinematics.

The ``stance`` column is optional in a data set that declares its ``channels``. When it is
missing the loader derives the labels, in this order of preference, and records how in
:class:`StanceDerivation` (``Dataset.stance_source`` / ``Dataset.stance_derivations``):

1. **force, per foot** — extra columns ``left_grf_z`` and ``right_grf_z`` [N, W] (a force
   sensor in each foot, as :mod:`granular_mpc.importers` writes them): a foot is on the
   ground while its vertical force exceeds ``fraction`` × the robot's weight m g (default
   5 %, :data:`granular_mpc.analysis.stances.DEFAULT_FORCE_FRACTION`); each foot's mask is
   debounced (:func:`granular_mpc.analysis.stances.debounce`: gaps and runs up to
   :data:`BOUNCE_S` = 20 ms are chatter) and runs shorter than ``min_samples`` are dropped.
2. **force, stance foot** — the ``foot_force`` group (``grf_z`` on *a* foot) says when a
   foot is loaded but not which: the side comes from the kinematics below, the timing
   from ``grf_z`` > threshold. Needs the kinematics' channels too.
3. **kinematics** — needs ``joint_angles`` and ``trunk_orientation`` (trunk position and
   velocities are not needed): each foot frame's height relative to the trunk in W,
   z_F = [R_WB p_B_F(q_leg)]_z, from the robot's leg kinematics
   (:func:`granular_mpc.robot.kinematics.leg_fk`). The swing foot is the higher one. With
   A the 95th percentile of |z_left − z_right| (the swing clearance), the other foot
   *lifts* when it rises more than 0.5 A above the stance foot and *touches down* when,
   after lifting, it descends (relative vertical velocity ż_o − ż_s < 0) to within
   0.05 A of the stance foot, or stops descending below 0.5 A (|ż_o − ż_s| under 0.1 × its
   95th percentile: it landed higher, e.g. on sand that the stance foot sank into); it
   then becomes the stance foot. The first stance foot is
   the lower one at the first row where the feet are 0.5 A apart (the rows before it get
   the same label). Kinematic labels are never
   ``none`` (without the trunk height the ground is unknown, and walking has no flight).

Labels follow the convention of :mod:`granular_mpc.validation.synth`: the **leading
foot**, i.e. among the feet on the ground the one that touched down last; ``none`` when
no foot is on the ground.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Mapping

import numpy as np

from ...analysis.stances import DEFAULT_FORCE_FRACTION, DEFAULT_MIN_SAMPLES, debounce, true_runs
from ...columns import BASE_QUATERNION, FOOT_SIDES, TIME, foot_column, joint_columns
from ...robot.kinematics import leg_fk
from .channels import ChannelGroup, ChannelSet
from .robot_facts import RobotFacts

StanceSource = Literal["measured", "force", "kinematics"]
"""Where a data set's stance labels come from."""
LIFT_FRACTION = 0.5
"""The other foot has lifted when it is this fraction of the swing clearance higher [-]."""
TOUCH_FRACTION = 0.05
"""A lifted foot touches down within this fraction of the clearance of the stance foot [-]."""
BOUNCE_S = 0.02
"""Force masks: off-ground gaps and on-ground runs this short [s] are chatter (a bounce, a
scuff) and removed (:func:`granular_mpc.analysis.stances.debounce`)."""
STOP_FRACTION = 0.1
"""… or when, below half the clearance, its descent slows to this fraction of the typical
(95th percentile) relative vertical speed [-]: it stopped on the ground."""


@dataclass(frozen=True)
class StanceDerivation:
    """How the stance labels of one trial were derived.

    Attributes:
        source: ``"force"`` or ``"kinematics"``.
        method: the columns and the rule used, one sentence.
        threshold: force threshold [N] (force) or touchdown height margin [m] (kinematics).
        rows: number of rows labelled ``left``, ``right``, ``none``.
        touchdowns: number of touchdowns found (label changes to a foot).
    """

    source: StanceSource
    method: str
    threshold: float
    rows: Mapping[str, int]
    touchdowns: int

    def __str__(self) -> str:
        unit = "N" if self.source == "force" else "m"
        counts = ", ".join(f"{k} {v}" for k, v in self.rows.items())
        return (f"stance from {self.source}: {self.method} (threshold {self.threshold:.4g} "
                f"{unit}); {self.touchdowns} touchdowns; rows: {counts}")


def leading_foot(on_left: np.ndarray, on_right: np.ndarray) -> np.ndarray:
    """``left`` / ``right`` for the foot on the ground that touched down last, else ``none``."""
    n = len(on_left)
    out = np.full(n, "none", dtype=object)
    last = {"left": -1, "right": -1}
    prev = {"left": False, "right": False}
    for k in range(n):
        now = {"left": bool(on_left[k]), "right": bool(on_right[k])}
        for side in FOOT_SIDES:
            if now[side] and not prev[side]:
                last[side] = k
        prev = now
        if now["left"] and now["right"]:
            out[k] = "left" if last["left"] >= last["right"] else "right"
        elif now["left"]:
            out[k] = "left"
        elif now["right"]:
            out[k] = "right"
    return out


def _clean_mask(mask: np.ndarray, min_samples: int, bounce: int) -> np.ndarray:
    m = debounce(mask, bounce)
    for a, b in true_runs(m):
        if b - a < min_samples:
            m[a:b] = False
    return m


def foot_heights(values: Mapping[str, np.ndarray], facts: RobotFacts) -> dict[str, np.ndarray]:
    """Height of each foot frame origin relative to the trunk origin, along world z [m].

    z_F = [R_WB p_B_F(q_leg)]_z with R_WB from ``base_q*`` (w, x, y, z) and p_B_F from the
    closed-form leg kinematics of the robot (legs in actuator order: left, then right).
    """
    w, x, y, z = (np.asarray(values[c], dtype=float) for c in BASE_QUATERNION)
    norm = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    row_z = np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
    q = np.column_stack([values[c] for c in joint_columns(facts.joints, "q")])
    out = {}
    for k, side in enumerate(FOOT_SIDES):
        geom = facts.legs[side]
        p_B = np.array([leg_fk(geom, row) for row in q[:, 3 * k: 3 * k + 3]])
        out[side] = np.einsum("ij,ij->i", row_z, p_B)
    return out


def kinematic_labels(heights: Mapping[str, np.ndarray],
                     time: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Leading-foot labels from the feet's relative heights (module docstring, rule 3).

    Returns:
        (labels, touchdown margin [m]), or None if the feet never separate by 1 mm.
    """
    zl, zr = heights["left"], heights["right"]
    clearance = float(np.percentile(np.abs(zl - zr), 95))
    if clearance < 1e-3:
        return None
    lift, touch = LIFT_FRACTION * clearance, TOUCH_FRACTION * clearance
    rate = np.gradient(zl - zr, time)                 # d(z_left − z_right)/dt
    stopped = STOP_FRACTION * float(np.percentile(np.abs(rate), 95))
    # the first clear separation tells the first stance foot (rows before it share it)
    first = int(np.argmax(np.abs(zl - zr) > lift))
    current = "left" if zl[first] <= zr[first] else "right"
    armed = True
    out = np.empty(len(zl), dtype=object)
    out[:first] = current
    for k in range(first, len(zl)):
        d = (zr[k] - zl[k]) if current == "left" else (zl[k] - zr[k])
        d_rate = -rate[k] if current == "left" else rate[k]
        if not armed and d > lift:
            armed = True
        elif armed and ((d < touch and d_rate < 0) or (d < lift and abs(d_rate) < stopped)):
            current = "right" if current == "left" else "left"
            armed = False
        out[k] = current
    return out, touch


def derive_stance(values: Mapping[str, np.ndarray], facts: RobotFacts | None,
                  channels: ChannelSet, *,
                  fraction: float = DEFAULT_FORCE_FRACTION,
                  min_samples: int = DEFAULT_MIN_SAMPLES) -> tuple[np.ndarray, StanceDerivation] | str:
    """Stance labels of one trial without a ``stance`` column.

    Args:
        values: column → float64 values of the trial (format columns and the per-foot
            force extras ``left_grf_z`` / ``right_grf_z`` when present), all finite.
        facts: the robot (weight, leg kinematics); None: unknown.
        channels: the measured groups.
        fraction: force threshold as a fraction of the robot's weight [-].
        min_samples: shortest on-ground run kept by the force rules.

    Returns:
        (labels, derivation), or why no labels can be derived (a sentence).
    """
    if facts is None:
        return "the robot is unknown"
    time = np.asarray(values[TIME], dtype=float)
    threshold = fraction * facts.weight
    bounce = max(1, int(round(BOUNCE_S / float(np.median(np.diff(time)))))) if len(time) > 1 else 1
    per_foot = [foot_column(s, "grf_z") for s in FOOT_SIDES]
    kinematic = channels.has(ChannelGroup.JOINT_ANGLES, ChannelGroup.TRUNK_ORIENTATION) \
        and bool(facts.legs)
    if all(c in values for c in per_foot):
        masks = [_clean_mask(np.asarray(values[c]) > threshold, min_samples, bounce) for c in per_foot]
        labels = leading_foot(*masks)
        method = (f"{per_foot[0]} / {per_foot[1]} above {fraction:g} × the robot's weight, "
                  "debounced; leading foot")
        return labels, _report("force", method, threshold, labels)
    if not kinematic:
        what = ("grf_z says when a foot is loaded but not which one"
                if channels.has(ChannelGroup.FOOT_FORCE) else "no foot force was measured")
        return (f"{what}; deriving stance labels needs per-foot forces ({per_foot[0]}, "
                f"{per_foot[1]}) or the channel groups joint_angles and trunk_orientation "
                "(leg kinematics)")
    found = kinematic_labels(foot_heights(values, facts), time)
    if found is None:
        return "the feet never separate by more than 1 mm in height: no steps to segment"
    side, margin = found
    if channels.has(ChannelGroup.FOOT_FORCE):
        loaded = _clean_mask(np.asarray(values["grf_z"]) > threshold, min_samples, bounce)
        labels = np.where(loaded, side, "none").astype(object)
        method = (f"grf_z above {fraction:g} × the robot's weight (debounced) for the timing, "
                  f"the side from leg kinematics (touchdown margin {margin:.3g} m)")
        return labels, _report("force", method, threshold, labels)
    method = ("foot heights from joint angles and trunk orientation (leg kinematics): the "
              "lower foot, switching when the lifted foot descends to the stance foot")
    return side, _report("kinematics", method, margin, side)


def _report(source: StanceSource, method: str, threshold: float,
            labels: np.ndarray) -> StanceDerivation:
    rows = {lab: int(np.sum(labels == lab)) for lab in ("left", "right", "none")}
    starts = sum(1 for k in range(1, len(labels))
                 if labels[k] != labels[k - 1] and labels[k] != "none")
    return StanceDerivation(source, method, float(threshold), rows, starts)


__all__ = ["StanceSource", "StanceDerivation", "LIFT_FRACTION", "TOUCH_FRACTION",
           "BOUNCE_S", "STOP_FRACTION", "leading_foot", "foot_heights", "kinematic_labels", "derive_stance"]
