"""What the checks need to know about the robot: joint names, URDF limits, weight."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...config import load_robot
from ...paths import resolve_file
from ...robot.kinematics import LegGeometry, leg_geometry
from ...robot.model import SIDES, Biped


@dataclass(frozen=True)
class RobotFacts:
    """Joint names, limits and weight of one robot.

    Attributes:
        name: the robot as named in ``meta.yaml``.
        joints: actuated joints, actuator order.
        q_lower, q_upper: URDF position limits per joint [rad] (may be ±inf).
        dq_max: URDF velocity limit per joint [rad/s].
        tau_max: URDF effort limit per joint [N·m].
        weight: m g [N].
        legs: leg geometry per side (``"left"``, ``"right"``), for the foot kinematics
            of stance derivation (empty: unknown).
    """

    name: str
    joints: tuple[str, ...]
    q_lower: dict[str, float]
    q_upper: dict[str, float]
    dq_max: dict[str, float]
    tau_max: dict[str, float]
    weight: float
    legs: dict[str, LegGeometry] = field(default_factory=dict)


def _file_stamp(path: Path) -> tuple[str, int, int]:
    st = path.stat()
    return str(path), st.st_mtime_ns, st.st_size


# (robot YAML stamp, name) -> (URDF stamp, facts); entries are re-validated on every use
_FACTS_CACHE: dict[tuple[tuple[str, int, int], str], tuple[tuple[str, int, int], RobotFacts]] = {}


def load_robot_facts(name: str, folder: Path | None) -> RobotFacts:
    """Joint names, limits and weight of robot ``name`` (a models/ name or a path).

    The facts are cached per robot file and reused only while neither the robot YAML
    nor its URDF has changed on disk (loading a data set stays cheap in a loop).

    Args:
        name: robot name in ``models/`` or path of a robot YAML file.
        folder: the data set folder (a relative path is looked up there first), or None.

    Raises:
        ConfigError, ModelError: the robot cannot be found, read or built.
    """
    path = resolve_file("robot", name, relative_to=folder, key="robot")
    key = (_file_stamp(path), name)
    cached = _FACTS_CACHE.get(key)
    if cached is not None:
        urdf_stamp, facts = cached
        try:
            if _file_stamp(Path(urdf_stamp[0])) == urdf_stamp:
                return facts
        except OSError:
            pass
    config = load_robot(str(path))
    biped = Biped.from_config(config, with_visuals=False)
    lo, hi = biped.position_limits
    joints = tuple(biped.joint_names)
    facts = RobotFacts(
        name=name, joints=joints,
        q_lower=dict(zip(joints, map(float, lo))), q_upper=dict(zip(joints, map(float, hi))),
        dq_max=dict(zip(joints, map(float, biped.velocity_limits))),
        tau_max=dict(zip(joints, map(float, biped.torque_limits))),
        weight=biped.weight, legs={side: leg_geometry(biped, side) for side in SIDES})
    _FACTS_CACHE[key] = (_file_stamp(config.urdf_path), facts)
    return facts


__all__ = ["RobotFacts", "load_robot_facts"]
