"""What an effect may read: the contact-patch state (terrain forces) and the sensor context.

A ``terrain_force`` effect receives a :class:`PatchState` per contact patch (numbers, or
CasADi expressions when it is compiled into the plant's contact function); a ``sensor``
effect receives the columns of a trial and a :class:`SensorContext`. Joint effects read
the joint angles and velocities, geometry effects only their parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np


@dataclass
class PatchState:
    """What a terrain-force effect may read about one contact patch (values or CasADi
    expressions).

    Attributes:
        depth: depth of the lowest sole point below the free surface [m] (> 0 in contact).
        in_contact: 1 when the patch touches the terrain, else 0.
        p_c: contact point (lowest sole point) in W [m].
        v_c: its velocity in W [m/s].
        a_c: its acceleration in W (finite difference over one step) [m/s²].
        intrusion: (x_s, y_s, z_s) = contact point relative to the touchdown point C0,
            z positive deeper [m].
        heading, lateral: unit horizontal vectors along the foot's x axis and left of it.
        f_terrain: the terrain model's own force on the patch in W [N].
        f_yield_z: vertical force the medium bears at this depth for pure penetration [N].
        area_h: horizontal area of the submerged sole of the patch [m²].
        width: patch (slice) width [m].
        density: bulk density of the medium [kg/m³] (0 for rigid ground).
        dt: plant step [s].
        depth_max: deepest depth of this patch since touchdown [m].
        t_stance: time since touchdown [s].
        foot: which foot the patch belongs to: 0.0 left, 1.0 right (a number, or a CasADi
            expression in the compiled contact law, so write ``o.if_else(s.foot > 0.5, …)``
            or multiply by :attr:`is_right` / :attr:`is_left`, never ``if s.foot:``).
        depth_rate: rate at which the sole material at the contact point penetrates the
            free surface, −v_c·n with n the surface's upward normal (small slopes) [m/s]
            (> 0 sinking, < 0 rising).

    Per-foot and depth-profile terms (a worn right sole, left/right tracks of different
    sand, a loose top layer over a harder one) read :attr:`foot` and :attr:`depth`; see
    :mod:`granular_mpc.effects.variants` and docs/validation.md.
    """

    depth: Any
    in_contact: Any
    p_c: tuple
    v_c: tuple
    a_c: tuple
    intrusion: tuple
    heading: tuple
    lateral: tuple
    f_terrain: tuple
    f_yield_z: Any
    area_h: Any
    width: float
    density: float
    dt: Any
    depth_max: Any = 0.0
    t_stance: Any = 0.0
    foot: Any = 0.0
    depth_rate: Any = 0.0

    @property
    def is_right(self) -> Any:
        """1 on the right foot's patches, 0 on the left's (a number or an expression)."""
        return self.foot

    @property
    def is_left(self) -> Any:
        """1 on the left foot's patches, 0 on the right's (a number or an expression)."""
        return 1.0 - self.foot


#: a terrain-force effect: ``fn(o, s, p) -> (fx, fy, fz)`` [N] in W, ``o`` the math namespace
ForceFn = Callable[[Any, PatchState, Mapping[str, Any]], tuple]


@dataclass(frozen=True)
class SensorContext:
    """What a sensor effect may read besides the columns.

    Attributes:
        stance: stance labels (``left`` / ``right`` / ``none``) per row.
        time: sample times [s].
        joint_names: actuated joints in actuator order.
    """

    stance: np.ndarray
    time: np.ndarray
    joint_names: tuple[str, ...]

    @property
    def in_stance(self) -> np.ndarray:
        """1.0 on rows with a stance foot (its force sensor is read), else 0.0."""
        return (np.asarray(self.stance).astype(str) != "none").astype(float)


__all__ = ["PatchState", "ForceFn", "SensorContext"]
