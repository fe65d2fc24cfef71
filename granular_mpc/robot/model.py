"""The biped as a Pinocchio model plus what the URDF cannot express (the sole geometry).

Notation (see docs/notation.md): ``W`` world (x forward, y left, z up), ``B`` trunk,
``F`` foot frame at the centre of the sole arc. ``q`` is Pinocchio's configuration
``[p_W_B (3), quat_W_B (x, y, z, w), q_a (6)]``; ``v`` is ``[v_B (3), ω_B (3), q̇_a (6)]``
with the base twist expressed in the trunk frame (Pinocchio's free-flyer convention).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pinocchio as pin

from ..config import FootGeometry, RobotConfig, load_robot
from ..exceptions import ModelError, ModelFileError

SIDES = ("left", "right")


@dataclass(frozen=True)
class Biped:
    """Immutable robot model. Build with :meth:`from_config` or :func:`load_biped`.

    Attributes:
        config: the validated robot config.
        model: Pinocchio model with a free-flyer root (nq = 13, nv = 12).
        visual_model: Pinocchio geometry model of the visual primitives (for Meshcat).
        joint_names: actuated joints in actuator order (left abd, pitch, knee, right …).
        idx_q, idx_v: index of each actuated joint in q and v.
        foot_frame: Pinocchio frame id of each foot frame ``F``.
        foot_joint: Pinocchio joint id carrying each foot (the calf joint).
    """

    config: RobotConfig
    model: pin.Model
    visual_model: pin.GeometryModel | None
    joint_names: tuple[str, ...]
    idx_q: np.ndarray
    idx_v: np.ndarray
    foot_frame: dict[str, int]
    foot_joint: dict[str, int]
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # ---------------------------------------------------------------- construction
    @classmethod
    def from_config(cls, config: RobotConfig, *, with_visuals: bool = True) -> "Biped":
        urdf = config.urdf_path
        if not urdf.is_file():
            raise ModelFileError(f"URDF not found: {urdf}", key="robot.urdf", value=config.urdf)
        _check_inertials(urdf)
        try:
            model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
            visual = (pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.VISUAL)
                      if with_visuals else None)
        except Exception as exc:  # pinocchio raises plain RuntimeError/ValueError
            raise ModelError(f"cannot build a model from {urdf}: {exc}") from exc
        names = tuple(config.joints)
        idx_q, idx_v = [], []
        for name in names:
            if not model.existJointName(name):
                raise ModelError(f"robot.joints: joint {name!r} is not in {urdf.name} "
                                 f"(joints: {list(model.names)[2:]})")
            jid = model.getJointId(name)
            if model.nqs[jid] != 1:
                raise ModelError(f"joint {name!r} must be a 1-DoF revolute joint")
            idx_q.append(model.idx_qs[jid])
            idx_v.append(model.idx_vs[jid])
        foot_frame, foot_joint = {}, {}
        for side in SIDES:
            fname = config.feet[side].frame
            if not model.existFrame(fname):
                raise ModelError(f"robot.feet.{side}.frame: frame {fname!r} is not in {urdf.name}")
            fid = model.getFrameId(fname)
            foot_frame[side] = fid
            foot_joint[side] = model.frames[fid].parentJoint
        return cls(config=config, model=model, visual_model=visual, joint_names=names,
                   idx_q=np.array(idx_q), idx_v=np.array(idx_v), foot_frame=foot_frame,
                   foot_joint=foot_joint)

    def create_data(self) -> pin.Data:
        """A fresh Pinocchio data object (all computed values live there)."""
        return self.model.createData()

    # ---------------------------------------------------------------- physical facts
    @cached_property
    def mass(self) -> float:
        """Total mass [kg]."""
        return float(sum(i.mass for i in self.model.inertias))

    @property
    def weight(self) -> float:
        """Total weight W_r = m g [N]."""
        return self.mass * self.gravity

    @property
    def gravity(self) -> float:
        return float(-self.model.gravity.linear[2])

    @property
    def foot_geometry(self) -> FootGeometry:
        return self.config.foot

    @cached_property
    def slice_offsets(self) -> np.ndarray:
        """Lateral positions y of the contact slices in the foot frame [m] and their widths."""
        n = self.config.foot.slices
        w = self.config.foot.width
        return (np.arange(n) + 0.5) * (w / n) - w / 2.0

    @cached_property
    def torque_limits(self) -> np.ndarray:
        """Actuator torque limits from the URDF [N·m], actuator order."""
        return np.array(self.model.effortLimit[self.idx_v], dtype=float)

    @cached_property
    def torque_limits_v(self) -> np.ndarray:
        """The same limits [N·m] in the order of the actuated joints' velocity rows
        (v[6:]), the order the whole-body controller computes its torques in."""
        return np.array(self.model.effortLimit[6:], dtype=float)

    @cached_property
    def position_limits(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array(self.model.lowerPositionLimit[self.idx_q]),
                np.array(self.model.upperPositionLimit[self.idx_q]))

    @cached_property
    def velocity_limits(self) -> np.ndarray:
        return np.array(self.model.velocityLimit[self.idx_v], dtype=float)

    @cached_property
    def q_names(self) -> tuple[str, ...]:
        """Name of each entry of q: ``base_x, base_y, base_z`` (p_W_B [m]),
        ``base_qx, base_qy, base_qz, base_qw`` (Pinocchio's quaternion order), ``q_<joint>``."""
        names = ["base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw"]
        names += [""] * (self.model.nq - len(names))
        for j, i in zip(self.joint_names, self.idx_q):
            names[int(i)] = f"q_{j}"
        return tuple(names)

    @cached_property
    def v_names(self) -> tuple[str, ...]:
        """Name of each entry of v: ``base_vx_B..vz_B``, ``base_wx_B..wz_B`` (both in the trunk frame
        B, Pinocchio's free-flyer convention), ``dq_<joint>``."""
        names = ["base_vx_B", "base_vy_B", "base_vz_B", "base_wx_B", "base_wy_B", "base_wz_B"]
        names += [""] * (self.model.nv - len(names))
        for j, i in zip(self.joint_names, self.idx_v):
            names[int(i)] = f"dq_{j}"
        return tuple(names)

    # ---------------------------------------------------------------- configurations
    def q_from_parts(self, p_W_B, quat_xyzw, q_a) -> np.ndarray:
        q = pin.neutral(self.model)
        q[0:3] = p_W_B
        q[3:7] = quat_xyzw
        q[self.idx_q] = q_a
        return q

    def actuated(self, q_or_v: np.ndarray, *, velocity: bool = False) -> np.ndarray:
        """The actuated-joint part of a configuration (or velocity if ``velocity``)."""
        return np.asarray(q_or_v)[self.idx_v if velocity else self.idx_q]

    def lowest_sole_point(self, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """World z of the lowest point of each sole arc at configuration q [m]."""
        data = data or self.create_data()
        pin.framesForwardKinematics(self.model, data, q)
        out = []
        R = self.config.foot.radius
        for side in SIDES:
            oMf = data.oMf[self.foot_frame[side]]
            out.append(oMf.translation[2] - R)  # the arc bottom, if within the arc span
        return np.array(out)

    def standing_configuration(self, clearance: float = 0.0, q_a=None) -> np.ndarray:
        """Standing pose with the lowest sole point ``clearance`` [m] above z = 0."""
        q_a = np.asarray(self.config.standing_joints if q_a is None else q_a, dtype=float)
        q = self.q_from_parts([0.0, 0.0, 0.0], [0, 0, 0, 1], q_a)
        low = self.lowest_sole_point(q).min()
        q[2] = clearance - low
        return q

    def com(self, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """Whole-body centre of mass in W [m]."""
        data = data or self.create_data()
        return np.array(pin.centerOfMass(self.model, data, q))


def _check_inertials(urdf) -> None:
    """Reject non-physical ``<inertial>`` blocks, naming the link (Pinocchio accepts them).

    Each link's mass and inertia diagonal must be finite and ≥ 0 (zero-mass dummy links
    are allowed; a massless body on a moving joint shows up as a singular mass matrix).
    Off-diagonal inertia terms and the triangle inequality are not checked here.

    Raises:
        ModelError: naming the link, the offending value and the file.
    """
    import math
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(str(urdf)).getroot()
    except ET.ParseError as exc:
        raise ModelError(f"cannot parse {urdf}: {exc}") from None
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        name = link.get("name", "?")
        mass = inertial.find("mass")
        raw = mass.get("value") if mass is not None else None
        try:
            m = float(raw)
        except (TypeError, ValueError):
            m = math.nan
        if not (math.isfinite(m) and m >= 0.0):
            raise ModelError(f"{urdf.name}: link {name!r} has mass {raw!r}; "
                             "a link mass must be a finite number ≥ 0 kg")
        inertia = inertial.find("inertia")
        if inertia is not None:
            for key in ("ixx", "iyy", "izz"):
                try:
                    val = float(inertia.get(key, "0"))
                except ValueError:
                    val = math.nan
                if not (math.isfinite(val) and val >= 0.0):
                    raise ModelError(f"{urdf.name}: link {name!r} has inertia {key} = "
                                     f"{inertia.get(key)!r}; must be a finite number ≥ 0 kg·m²")


def load_biped(name_or_path: str = "yobogo10s", *, with_visuals: bool = True) -> Biped:
    """Load a robot by name (``models/<name>.yaml``) or path and build its model."""
    return Biped.from_config(load_robot(name_or_path), with_visuals=with_visuals)


__all__ = ["Biped", "load_biped", "SIDES"]

