"""Shared vocabulary: data-format columns and run-folder file names.

One place for every name that two layers must agree on. Measurement data format v1
(``docs/data-format.md``) and the run log (``docs/log-format.md``, a superset of v1) both
use these columns; the runner, the viewer, the workbench and the tests import them from
here. This module sits at the bottom of the import stack: it imports nothing from the
package.

Units are SI, frames as in ``docs/notation.md``: world ``W`` (x forward, y left, z up),
trunk ``B``.
"""

from __future__ import annotations

from typing import Literal, Sequence

# --------------------------------------------------------------------------------------
# Data format v1 columns
# --------------------------------------------------------------------------------------

TIME = "time"
"""Time since the start of the trial [s]."""
STANCE = "stance"
"""Stance label of the row: one of :data:`STANCE_LABELS`."""
STANCE_LABELS = ("left", "right", "none")

JointKind = Literal["q", "dq", "tau"]
JOINT_KINDS: tuple[JointKind, ...] = ("q", "dq", "tau")
"""Joint angle [rad], velocity [rad/s], torque [N·m]."""
JOINT_PREFIXES = tuple(f"{k}_" for k in JOINT_KINDS)

BASE_POSITION = ("base_x", "base_y", "base_z")
"""Trunk position p_W_B [m]."""
BASE_QUATERNION = ("base_qw", "base_qx", "base_qy", "base_qz")
"""Trunk orientation of B in W, unit quaternion in (w, x, y, z) order."""
BASE_LINEAR_VELOCITY = ("base_vx", "base_vy", "base_vz")
"""Trunk linear velocity in W [m/s]."""
BASE_ANGULAR_VELOCITY = ("base_wx", "base_wy", "base_wz")
"""Trunk angular velocity in B [rad/s]."""
BASE_COLUMNS = BASE_POSITION + BASE_QUATERNION + BASE_LINEAR_VELOCITY + BASE_ANGULAR_VELOCITY

AXES = ("x", "y", "z")
GRF_COLUMNS = ("grf_x", "grf_y", "grf_z")
"""Force of the ground on the stance foot, W [N]."""
INTRUSION_COLUMNS = ("intrusion_x", "intrusion_y", "intrusion_z")
"""Stance-foot contact point minus its touchdown point [m], z positive = deeper."""


def joint_columns(joint_names: Sequence[str], kind: JointKind = "q") -> list[str]:
    """Column names ``<kind>_<joint>`` in actuator order.

    Args:
        joint_names: actuated joints of the robot, actuator order.
        kind: ``"q"`` (angle, rad), ``"dq"`` (velocity, rad/s) or ``"tau"`` (torque, N·m).

    Raises:
        ValueError: ``kind`` is not one of :data:`JOINT_KINDS`.
    """
    if kind not in JOINT_KINDS:
        raise ValueError(f"kind must be 'q', 'dq' or 'tau', got {kind!r}")
    return [f"{kind}_{j}" for j in joint_names]


def all_joint_columns(joint_names: Sequence[str]) -> list[str]:
    """``q_*``, then ``dq_*``, then ``tau_*`` columns, each in actuator order."""
    cols: list[str] = []
    for kind in JOINT_KINDS:
        cols += joint_columns(joint_names, kind)
    return cols


def format_columns(joint_names: Sequence[str]) -> list[str]:
    """Every column format v1 requires, in the recommended order.

    Returns:
        ``time, stance, q_*, dq_*, tau_*, base_*, grf_*, intrusion_*``.
    """
    return ([TIME, STANCE] + all_joint_columns(joint_names) + list(BASE_COLUMNS)
            + list(GRF_COLUMNS) + list(INTRUSION_COLUMNS))


# --------------------------------------------------------------------------------------
# Run-log extras (per foot, whole body)
# --------------------------------------------------------------------------------------

FOOT_SIDES = ("left", "right")


def foot_column(side: str, name: str) -> str:
    """Per-foot run-log column ``<side>_<name>``, e.g. ``left_grf_z`` or ``right_depth``."""
    return f"{side}_{name}"


COM_POSITION = ("com_x", "com_y", "com_z")
"""Whole-body centre of mass in W [m]."""
COM_VELOCITY = ("com_vx", "com_vy", "com_vz")
"""Whole-body centre-of-mass velocity in W [m/s]."""
PLANNED_STANCE = "planned_stance"
"""The gait schedule's stance label (the measured/contact one is :data:`STANCE`)."""

# --------------------------------------------------------------------------------------
# Run folder (``granular-mpc run --out DIR``) and data-set folder names
# --------------------------------------------------------------------------------------

LOG_DIR = "log"
"""Folder of Parquet log parts ``part-00000.parquet`` …"""
PLOTS_DIR = "plots"
SUMMARY_FILE = "summary.json"
RESOLVED_FILE = "config.resolved.yaml"
HTML_FILE = "animation.html"
SWEEP_TABLE_FILE = "sweep.csv"
META_FILE = "meta.yaml"
"""A data set's meta file (``docs/data-format.md``)."""


def log_part_name(index: int) -> str:
    """File name of the ``index``-th log part."""
    return f"part-{index:05d}.parquet"


# Per-foot run-log names, used with :func:`foot_column` (``left_contact``, ``right_px`` …).
FOOT_CONTACT = "contact"
"""Per-foot contact flag: 1 while the foot touches the ground, else 0."""
FOOT_POINT = ("px", "py", "pz")
"""Per-foot contact point ``C`` in W [m]."""

STATUS_FILE = "status.json"
"""A run or sweep folder's live status: PID, host, start, heartbeat, end, state."""
LOCK_FILE = ".granular-mpc.lock"
"""The lock of an output folder while a command writes it (holds the writer's PID)."""
