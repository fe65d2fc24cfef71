"""Planar views of the 3-D biped: the link parameters of the paper's sagittal (5-link) and
frontal (3-link) models, read from the Pinocchio model of :class:`~granular_mpc.robot.Biped`.

Nothing here is typed in by hand: masses, centres of mass (COM), rotational inertias and
joint offsets come from ``model.inertias`` and ``model.jointPlacements`` (Pinocchio has
already merged each fixed-joint body, e.g. the foot, into its parent joint's inertia); the
sole radius R from ``biped.config.foot``. See ``docs/planar-models.md`` for the table of
values of the shipped robot.

Conventions (docs/notation.md): world ``W`` x forward, y left, z up.

* **Sagittal view** (plane x–z, rotations about +y). Each link has a *link frame*: the
  frame of the Pinocchio joint that moves it (trunk: the free-flyer frame ``B``). A link's
  absolute angle θ is the pitch of its frame in ``W`` (rotation about +y), so a vector
  (b_x, b_z) of the link frame points in ``W`` along
  (b_x cos θ + b_z sin θ, −b_x sin θ + b_z cos θ). Thigh and calf axes run along −z of
  their frames, so θ is the angle of the link from the downward vertical, positive when
  the distal end swings back (−x) — the paper's "absolute angle from the vertical".
* **Frontal view** (plane y–z, rotations about +x): a vector (b_y, b_z) points along
  (b_y cos φ − b_z sin φ, b_y sin φ + b_z cos φ) for a link of roll φ.

Lumping of the hip abduction link (the body between the abduction and hip-pitch joints):

* sagittal: lumped into the **trunk**. The abduction axis is x, so in a sagittal motion
  (abduction held at 0) the hip link rotates with the trunk; trunk link = trunk + both hip
  links. This is exact for the sagittal motion of the 3-D model with abduction locked at 0.
* frontal: lumped into the **leg** (it rolls with the abduction joint); leg = hip link +
  thigh + calf + foot, taken rigid at reference hip-pitch and knee angles (by default the
  standing pose). Exact for the frontal motion of the 3-D model with hip pitch and knee
  locked at those angles and the trunk not pitched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigError, ModelError
from .model import SIDES, Biped

_TOL = 1e-9


# ------------------------------------------------------------------------------- types
@dataclass(frozen=True)
class PlanarLink:
    """One rigid link of a planar model, in its own link frame (in-plane coordinates).

    Attributes:
        name: what the link lumps (e.g. ``"left_calf+left_foot"``).
        mass: m [kg].
        com: COM in the link frame, in-plane coordinates [m] ((x, z) sagittal, (y, z)
            frontal), measured from the link frame origin (the proximal joint).
        inertia: rotational inertia about the plane normal through the COM [kg·m²]
            (I_yy sagittal, I_xx frontal).
        tip: distal point in the link frame [m]: the next joint, or the centre of the
            sole arc for a calf / leg; ``(0, 0)`` for the trunk.
    """

    name: str
    mass: float
    com: tuple[float, float]
    inertia: float
    tip: tuple[float, float] = (0.0, 0.0)

    @property
    def length(self) -> float:
        """Link length l = |tip| [m] (proximal joint → distal joint / arc centre)."""
        return float(math.hypot(*self.tip))

    @property
    def axis(self) -> np.ndarray:
        """Unit vector along the link, proximal → distal, in the link frame [-]."""
        t = np.asarray(self.tip, dtype=float)
        n = np.linalg.norm(t)
        if n < _TOL:
            raise ModelError(f"link {self.name!r} has no length: it has no axis")
        return t / n

    @property
    def com_along(self) -> float:
        """COM distance from the proximal joint along the link axis, a = c·û [m]."""
        return float(np.dot(self.com, self.axis))

    @property
    def com_across(self) -> float:
        """COM offset perpendicular to the link axis, c·n̂ with n̂ = (−û_2, û_1) [m]: positive
        toward the link frame's first in-plane axis (+x sagittal, +y frontal) for a link
        hanging down (û = (0, −1))."""
        u = self.axis
        return float(-self.com[0] * u[1] + self.com[1] * u[0])


@dataclass(frozen=True)
class SagittalView:
    """Parameters of the sagittal 5-link model for one stance side.

    Link order is that of the coordinates q^s = [θ_swing thigh, θ_swing calf,
    θ_stance thigh, θ_stance calf, θ_trunk] (see :mod:`granular_mpc.dynamics.planar`).

    Attributes:
        stance: ``"left"`` or ``"right"``: the side whose foot carries C1.
        trunk: trunk + both hip abduction links, in the trunk frame ``B`` (x, z).
        hip_stance, hip_swing: hip-pitch joint of each leg in ``B`` (x, z) [m]
            (abduction at 0).
        thigh_stance, thigh_swing: thigh links (tip = knee), in the hip-pitch joint frame.
        calf_stance, calf_swing: calf + foot links (tip = sole-arc centre, the foot frame
            ``F`` origin), in the knee joint frame.
        foot_radius: sole arc radius R [m].
        foot_half_angle: half-angle of the arc [rad]; C1 = arc centre − R ẑ lies on the sole
            while |foot pitch| ≤ this.
        foot_mount_pitch: pitch of ``F`` relative to the calf frame [rad]
            (foot pitch = θ_calf + foot_mount_pitch).
        gravity: g [m/s²].
        sign_pitch, sign_knee: +1 if the hip-pitch / knee joint rotates about +y of its
            frame, −1 about −y; indexed ``[stance, swing]``.
        joint_names: actuator names (left abd, pitch, knee, right abd, pitch, knee).
    """

    stance: str
    trunk: PlanarLink
    hip_stance: tuple[float, float]
    hip_swing: tuple[float, float]
    thigh_stance: PlanarLink
    calf_stance: PlanarLink
    thigh_swing: PlanarLink
    calf_swing: PlanarLink
    foot_radius: float
    foot_half_angle: float
    foot_mount_pitch: float
    gravity: float
    sign_pitch: tuple[int, int]
    sign_knee: tuple[int, int]
    joint_names: tuple[str, ...]

    @property
    def swing(self) -> str:
        return other_side(self.stance)

    @property
    def links(self) -> tuple[PlanarLink, ...]:
        """Links in coordinate order: swing thigh, swing calf, stance thigh, stance calf, trunk."""
        return (self.thigh_swing, self.calf_swing, self.thigh_stance, self.calf_stance,
                self.trunk)

    @property
    def total_mass(self) -> float:
        """M = Σ m_i [kg] (equals the mass of the 3-D model)."""
        return float(sum(link.mass for link in self.links))

    @property
    def trunk_com_from_hip(self) -> np.ndarray:
        """Trunk COM relative to the swing hip-pitch joint, in ``B`` (x, z) [m]."""
        return np.asarray(self.trunk.com) - np.asarray(self.hip_swing)

    @property
    def selection(self) -> np.ndarray:
        """S_s (6 × 5) with q_a = S_s q^s (see :func:`sagittal_selection`)."""
        return sagittal_selection(self.stance, self.sign_pitch, self.sign_knee)


@dataclass(frozen=True)
class FrontalView:
    """Parameters of the frontal 3-link model for one stance side.

    Coordinates q^f = [q1f, q2f, q3f]: angles about +x of the *lines* of the links, as in
    the paper's frontal figure: q1f of the stance leg line (sole-arc centre → abduction
    axis) from the upward vertical; q2f of the hip line (stance → swing abduction axis)
    from the downward vertical (+π/2 for a level trunk with the right leg in stance, the
    swing hip then being on the +y side; −π/2 with the left leg in stance); q3f of the
    swing leg line (abduction axis → arc centre) from the downward vertical. A line at
    angle q from the downward vertical points along (sin q, −cos q). Each line angle is the roll
    of the link plus a constant offset fixed by the geometry (:attr:`offset_stance`,
    :attr:`offset_trunk`, :attr:`offset_swing`).

    Attributes:
        stance: ``"left"`` or ``"right"``.
        trunk: the trunk alone, in ``B`` (y, z).
        hip_stance, hip_swing: abduction joint of each leg in ``B`` (y, z) [m].
        leg_stance, leg_swing: hip link + thigh + calf + foot at the reference pitch/knee
            angles, in the abduction joint frame (y, z); tip = sole-arc centre.
        reference_joints: the actuator angles [rad] at which the legs are frozen (only the
            hip-pitch and knee entries are used).
        foot_radius: R [m].
        gravity: g [m/s²].
        sign_abd: +1 if the abduction joint rotates about +x, −1 about −x; ``[stance, swing]``.
        offset_stance, offset_trunk, offset_swing: q1f − φ_stance leg, q2f − φ_trunk,
            q3f − φ_swing leg [rad], φ the roll of the link frame.
        joint_names: actuator names.
    """

    stance: str
    trunk: PlanarLink
    hip_stance: tuple[float, float]
    hip_swing: tuple[float, float]
    leg_stance: PlanarLink
    leg_swing: PlanarLink
    reference_joints: tuple[float, ...]
    foot_radius: float
    gravity: float
    sign_abd: tuple[int, int]
    offset_stance: float
    offset_trunk: float
    offset_swing: float
    joint_names: tuple[str, ...]

    @property
    def swing(self) -> str:
        return other_side(self.stance)

    @property
    def links(self) -> tuple[PlanarLink, ...]:
        """Links in coordinate order: stance leg, trunk, swing leg."""
        return (self.leg_stance, self.trunk, self.leg_swing)

    @property
    def total_mass(self) -> float:
        return float(sum(link.mass for link in self.links))

    @property
    def selection(self) -> np.ndarray:
        """∂q_a/∂q^f (6 × 3) (see :func:`frontal_selection`)."""
        return frontal_selection(self.stance, self.sign_abd)

    @property
    def hip_width(self) -> float:
        """b = distance between the two abduction axes [m]."""
        return float(math.dist(self.hip_stance, self.hip_swing))

    @property
    def hip_direction(self) -> np.ndarray:
        """Unit vector stance → swing abduction axis in ``B`` (y, z) [-]."""
        v = np.asarray(self.hip_swing) - np.asarray(self.hip_stance)
        return v / np.linalg.norm(v)

    @property
    def trunk_com_from_hip(self) -> tuple[float, float]:
        """Trunk COM relative to the stance abduction axis: (along the hip line, across
        it toward the trunk's +z side) [m]. The paper's figure has (b/2, 0)."""
        c = np.asarray(self.trunk.com) - np.asarray(self.hip_stance)
        u = self.hip_direction
        n = np.array([-u[1], u[0]])
        if n[1] < 0.0:
            n = -n
        return float(c @ u), float(c @ n)


# ------------------------------------------------------------------------------- helpers
def other_side(side: str) -> str:
    """The other leg (``"left"`` ↔ ``"right"``)."""
    check_side(side)
    return "right" if side == "left" else "left"


def check_side(side: str) -> None:
    if side not in SIDES:
        raise ConfigError(f"stance side must be one of {SIDES}, got {side!r}", key="stance",
                          value=side, allowed="left | right")


def sagittal_selection(stance: str, sign_pitch: Sequence[int] = (1, 1),
                       sign_knee: Sequence[int] = (1, 1)) -> np.ndarray:
    """The constant map S_s (6 × 5) of q_a = S_s q^s.

    With q^s = [θ_wt, θ_wc, θ_st, θ_sc, θ_b] (swing thigh, swing calf, stance thigh,
    stance calf, trunk; absolute pitch angles) and a joint about ±y of its frame:

        q_pitch = s_p (θ_thigh − θ_b),   q_knee = s_k (θ_calf − θ_thigh),   q_abd = 0.

    Args:
        stance: ``"left"`` or ``"right"``.
        sign_pitch, sign_knee: joint axis signs ``[stance, swing]`` (+1 about +y).

    Returns:
        S_s, rows in actuator order (left abd, pitch, knee, right abd, pitch, knee) [-].
    """
    check_side(stance)
    S = np.zeros((6, 5))
    legs = {"swing": (0, 1, 1), "stance": (2, 3, 0)}  # (thigh col, calf col, sign index)
    for role, (ct, cc, k) in legs.items():
        side = stance if role == "stance" else other_side(stance)
        r = 0 if side == "left" else 3
        sp, sk = sign_pitch[k], sign_knee[k]
        S[r + 1, ct], S[r + 1, 4] = sp, -sp
        S[r + 2, cc], S[r + 2, ct] = sk, -sk
    return S


def frontal_selection(stance: str, sign_abd: Sequence[int] = (1, 1)) -> np.ndarray:
    """The constant Jacobian ∂q_a/∂q^f (6 × 3) of the frontal hip mapping.

    With q^f = [q1f, q2f, q3f] (stance leg, hip line, swing leg; line angles about +x) and
    abduction joints about ±x of their frames (sign s)::

        q_abd,st = s_st (q1f − q2f) + const,   q_abd,sw = s_sw (q3f − q2f) + const

    (the constants are the geometric offsets of :class:`FrontalView`).

    Args:
        stance: ``"left"`` or ``"right"``.
        sign_abd: joint axis signs ``[stance, swing]`` (+1 about +x).

    Returns:
        rows in actuator order; only the two abduction rows are non-zero [-].
    """
    check_side(stance)
    S = np.zeros((6, 3))
    st = 0 if stance == "left" else 3
    sw = 3 - st
    S[st, 0], S[st, 1] = sign_abd[0], -sign_abd[0]
    S[sw, 2], S[sw, 1] = sign_abd[1], -sign_abd[1]
    return S


def _axis_sign(model: pin.Model, jid: int, axis: int) -> int:
    """+1 / −1 if joint ``jid`` is revolute about +/− the unit axis ``axis`` (0 x, 1 y)."""
    j = model.joints[jid]
    name = j.shortname()
    if name == "JointModelR" + "XYZ"[axis]:
        return 1
    if name == "JointModelRevoluteUnaligned":
        a = np.asarray(j.extract().axis, dtype=float)
        e = np.zeros(3)
        e[axis] = 1.0
        if np.allclose(a, e, atol=1e-9):
            return 1
        if np.allclose(a, -e, atol=1e-9):
            return -1
    raise ModelError(f"joint {model.names[jid]!r} ({name}) must be revolute about "
                     f"±{'xyz'[axis]} for the planar views")


def _leg_ids(biped: Biped, side: str) -> tuple[int, int, int]:
    model = biped.model
    names = biped.joint_names[:3] if side == "left" else biped.joint_names[3:]
    abd, pitch, knee = (model.getJointId(n) for n in names)
    if model.parents[pitch] != abd or model.parents[knee] != pitch:
        raise ModelError(f"{side} leg must be a chain abduction → hip pitch → knee "
                         f"({names})")
    if model.parents[abd] != 1:
        raise ModelError(f"{names[0]!r} must be attached to the trunk (root joint)")
    if biped.foot_joint[side] != knee:
        raise ModelError(f"{side} foot frame must be carried by the knee joint {names[2]!r}")
    for jid in (abd, pitch, knee):
        rot = model.jointPlacements[jid].rotation
        if not np.allclose(rot, np.eye(3), atol=1e-9):
            raise ModelError(f"joint {model.names[jid]!r}: the planar views need joint frames "
                             "aligned with the trunk at zero angles (placement rotation ≠ I)")
    return abd, pitch, knee


def _in_plane(v: np.ndarray, plane: str) -> tuple[float, float]:
    return (float(v[0]), float(v[2])) if plane == "xz" else (float(v[1]), float(v[2]))


def _link(name: str, inertia: pin.Inertia, plane: str, tip=(0.0, 0.0)) -> PlanarLink:
    axis = 1 if plane == "xz" else 0
    return PlanarLink(name=name, mass=float(inertia.mass),
                      com=_in_plane(np.asarray(inertia.lever), plane),
                      inertia=float(inertia.inertia[axis, axis]), tip=tuple(map(float, tip)))


def _line_angle_down(tip: Sequence[float]) -> float:
    """Angle about +x of the in-plane (y, z) vector ``tip`` from the downward vertical."""
    return float(math.atan2(tip[0], -tip[1]))


# ------------------------------------------------------------------------------- builders
def sagittal_view(biped: Biped, stance: str = "left") -> SagittalView:
    """Extract the sagittal 5-link parameters from the Pinocchio model.

    Trunk link = trunk + both hip abduction links (placed at abduction = 0); thigh link =
    the hip-pitch joint's body; calf link = the knee joint's body (calf + foot, merged by
    Pinocchio). In-plane coordinates (x, z) of each link frame; I_yy at the COM.

    Raises:
        ModelError: if the robot is not a trunk with two abduction → pitch → knee chains
            with joint frames aligned at zero angles, pitch/knee about ±y, and both feet
            on the knee bodies with the sole-arc centre in the calf's x–z plane.
        ConfigError: for a stance side other than ``"left"`` / ``"right"``.
    """
    check_side(stance)
    model = biped.model
    ids = {s: _leg_ids(biped, s) for s in SIDES}
    # trunk + both hip links, in B
    trunk = model.inertias[1]
    names = ["trunk"]
    for s in SIDES:
        abd = ids[s][0]
        trunk = trunk + model.jointPlacements[abd].act(model.inertias[abd])
        names.append(model.names[abd].replace("_abd", ""))
    trunk_link = _link("+".join(names), trunk, "xz")
    hips, thighs, calves, sp, sk = {}, {}, {}, {}, {}
    mount = {}
    for s in SIDES:
        abd, pitch, knee = ids[s]
        hips[s] = _in_plane((model.jointPlacements[abd] * model.jointPlacements[pitch])
                            .translation, "xz")
        thighs[s] = _link(f"{s}_thigh", model.inertias[pitch], "xz",
                          _in_plane(model.jointPlacements[knee].translation, "xz"))
        foot = model.frames[biped.foot_frame[s]].placement
        calves[s] = _link(f"{s}_calf+foot", model.inertias[knee], "xz",
                          _in_plane(foot.translation, "xz"))
        R = foot.rotation
        if abs(R[1, 1] - 1.0) > 1e-9:
            raise ModelError(f"{s} foot frame must be pitched only (about y) on the calf")
        mount[s] = float(math.atan2(R[0, 2], R[0, 0]))
        sp[s] = _axis_sign(model, pitch, 1)
        sk[s] = _axis_sign(model, knee, 1)
    sw = other_side(stance)
    foot = biped.config.foot
    return SagittalView(
        stance=stance, trunk=trunk_link, hip_stance=hips[stance], hip_swing=hips[sw],
        thigh_stance=thighs[stance], calf_stance=calves[stance], thigh_swing=thighs[sw],
        calf_swing=calves[sw], foot_radius=float(foot.radius),
        foot_half_angle=float(foot.half_angle), foot_mount_pitch=mount[stance],
        gravity=biped.gravity, sign_pitch=(sp[stance], sp[sw]), sign_knee=(sk[stance], sk[sw]),
        joint_names=tuple(biped.joint_names))


def frontal_view(biped: Biped, stance: str = "left",
                 reference_joints: Sequence[float] | None = None) -> FrontalView:
    """Extract the frontal 3-link parameters from the Pinocchio model.

    Each leg (hip link + thigh + calf + foot) is frozen at the hip-pitch and knee angles of
    ``reference_joints`` (default: ``biped.config.standing_joints``) and expressed in its
    abduction joint frame; the trunk link is the trunk body alone. In-plane coordinates
    (y, z); I_xx at the COM.

    Args:
        biped: the robot.
        stance: ``"left"`` or ``"right"``.
        reference_joints: six actuator angles [rad] (abduction entries ignored).

    Raises:
        ModelError: as :func:`sagittal_view`, with the abduction joints about ±x.
        ConfigError: for a bad stance side or reference vector.
    """
    check_side(stance)
    model = biped.model
    ref = np.asarray(biped.config.standing_joints if reference_joints is None
                     else reference_joints, dtype=float)
    if ref.shape != (6,) or not np.isfinite(ref).all():
        raise ConfigError("reference_joints must be 6 finite angles [rad]",
                          key="reference_joints", value=reference_joints)
    ids = {s: _leg_ids(biped, s) for s in SIDES}
    q_a = ref.copy()
    q_a[[0, 3]] = 0.0
    q = biped.q_from_parts([0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], q_a)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    legs, hips, sa = {}, {}, {}
    for s in SIDES:
        abd, pitch, knee = ids[s]
        oMa = data.oMi[abd]
        leg = pin.Inertia.Zero()
        for jid in (abd, pitch, knee):
            leg = leg + oMa.actInv(data.oMi[jid]).act(model.inertias[jid])
        tip = oMa.actInv(data.oMf[biped.foot_frame[s]]).translation
        names = "+".join(model.names[j] for j in (abd, pitch, knee))
        legs[s] = _link(f"{s} leg ({names} bodies)", leg, "yz", _in_plane(tip, "yz"))
        hips[s] = _in_plane(model.jointPlacements[abd].translation, "yz")
        sa[s] = _axis_sign(model, abd, 0)
    sw = other_side(stance)
    trunk_link = _link("trunk", model.inertias[1], "yz")
    hip_vec = np.asarray(hips[sw]) - np.asarray(hips[stance])
    if np.linalg.norm(hip_vec) < 1e-6:
        raise ModelError("the two abduction axes coincide: no frontal hip line")
    foot = biped.config.foot
    return FrontalView(
        stance=stance, trunk=trunk_link, hip_stance=hips[stance], hip_swing=hips[sw],
        leg_stance=legs[stance], leg_swing=legs[sw], reference_joints=tuple(map(float, ref)),
        foot_radius=float(foot.radius), gravity=biped.gravity,
        sign_abd=(sa[stance], sa[sw]),
        # stance leg line (arc centre → hip) from the upward vertical = angle of −tip from
        # up = angle of tip from down
        offset_stance=_line_angle_down(legs[stance].tip),
        offset_trunk=_line_angle_down(hip_vec),
        offset_swing=_line_angle_down(legs[sw].tip),
        joint_names=tuple(biped.joint_names))


__all__ = ["PlanarLink", "SagittalView", "FrontalView", "sagittal_view", "frontal_view",
           "sagittal_selection", "frontal_selection", "other_side", "check_side"]
