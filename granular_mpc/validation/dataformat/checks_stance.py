"""Check of measured stance labels against the foot kinematics: left and right swapped.

A data set whose ``stance`` labels name the wrong foot passes every other check (the
labels are valid words, the force is positive) but every replay then starts the wrong leg
in contact and the model error quadruples. The leg kinematics say which foot is the lower
one (:func:`.stance_derive.kinematic_labels`, from the joint angles and the trunk
orientation); if the labelled foot is the *higher* one on most stance rows while the other
foot is the lower one, the labels are reported as swapped.

Thresholds: labels are reported when at most :data:`MAX_AGREEMENT` of the labelled stance
rows agree with the kinematic labels and at least :data:`MIN_SWAPPED` agree with the
swapped ones. Correct labels from walking agree on 95–99.5 % of rows (measured on
simulated walks, docs/import.md); random labels agree on about half; so 0.2 / 0.8 leave a
wide margin on both sides and a real trial is never flagged.
"""

from __future__ import annotations

import numpy as np

from ...columns import BASE_QUATERNION, STANCE, TIME, joint_columns
from .robot_facts import RobotFacts
from .stance_derive import foot_heights, kinematic_labels
from .trial_check import TrialCheck

MAX_AGREEMENT = 0.2
"""At most this share of stance rows agreeing with the kinematics: suspicious."""
MIN_SWAPPED = 0.8
"""At least this share agreeing with left ↔ right swapped: reported."""
MIN_ROWS = 20
"""Labelled stance rows needed to judge."""


def check_stance_sides(t: TrialCheck, labels: np.ndarray | None,
                       facts: RobotFacts | None) -> None:
    """Report stance labels whose left/right look swapped (see the module docstring)."""
    if labels is None or facts is None:
        return
    needed = [TIME, *BASE_QUATERNION, *joint_columns(facts.joints, "q")]
    if not all(c in t.values and t.ok(c) for c in needed):
        return
    stance = np.isin(labels, ("left", "right"))
    if stance.sum() < MIN_ROWS:
        return
    found = kinematic_labels(foot_heights(t.values, facts), t.values[TIME])
    if found is None:
        return
    kin = found[0].astype(str)
    agree = float(np.mean(kin[stance] == labels[stance]))
    swapped = np.where(labels == "left", "right", np.where(labels == "right", "left", labels))
    agree_swapped = float(np.mean(kin[stance] == swapped[stance]))
    if agree <= MAX_AGREEMENT and agree_swapped >= MIN_SWAPPED:
        t.add(f"stance labels look swapped (left ↔ right): the labelled foot is the higher "
              f"one on {100 * (1 - agree):.0f} % of stance rows, while the other foot is the "
              f"lower one on {100 * agree_swapped:.0f} % (from the joint angles and the trunk "
              "orientation); check the joint-name or side mapping", STANCE)


__all__ = ["check_stance_sides", "MAX_AGREEMENT", "MIN_SWAPPED", "MIN_ROWS"]
