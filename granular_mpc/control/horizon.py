"""The MPC horizon's inputs at one tick: contact plan, supports, references, capacities.

At an MPC tick at time ``t`` the horizon is N steps of ``dt``. For step k (mid-point
``t_k = t + (k + ½)·dt``) and each foot the gait plan says whether it is down; a foot
down carries ``mg / n`` (n feet down). A foot down either *stays down* from now (it is in
stance at ``t`` and lifts off after ``t_k``): its contact points are where it stands,
deeper by the sinkage ``Z(load)`` still to come; or it *lands* within the horizon: at its
swing target (or one stride on, ``2·v_x·T/2``), at depth ``Z(load)``. The horizontal CoM
reference is the linear inverted pendulum rolled out over the supports (the foot's
centre, or the mean of both)::

    p ← s + (p − s)·cosh(ω dt) + (v/ω)·sinh(ω dt),   v ← (p − s)·ω·sinh(ω dt) + v·cosh(ω dt)

(free flight, no foot down: ``p ← p + v dt``), the height the CoM reference and the yaw the
heading. On granular ground each foot down may bear the capacity at the depth the allowed
sink rate reaches by the step's end: ``depth_now + rate·(k + 1)·dt`` (stays down) or
``rate·max((k + 1)·dt − t_touchdown, 0)`` (lands).

Written for speed (N ≈ 10: Python floats cost less than NumPy calls on 10-element
arrays): one pass over the steps on Python floats, each support group (foot, stays down?,
feet down) evaluated once, the per-tick constants computed once
(:class:`HorizonConstants`). The numbers are bit for bit those of the former step-by-step
NumPy set-up (``tests/test_horizon.py`` checks them against the definitions above).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import MPCConfig
from ..rotations import rot_z
from .contact_model import GroundModel
from .gait import GaitSchedule
from .wbc import FootPoints


def mean_point(points: np.ndarray) -> np.ndarray:
    """Mean of the rows of ``points`` (n, k): ``points.mean(axis=0)``'s arithmetic (the
    sum over rows, divided by n) without its Python wrapper."""
    return np.add.reduce(points, axis=0) / len(points)


def sole_depth(surface_height: float, points: np.ndarray) -> float:
    """Depth of a foot's contact points (n, 3) [m, W] below the surface at
    ``surface_height`` [m]: the surface minus their mean height [m]."""
    # ndarray.sum's reduction called directly (the same sum, without its wrapper)
    return float(surface_height - np.add.reduce(points[:, 2], None) / len(points))


@dataclass(frozen=True)
class HorizonConstants:
    """What the horizon set-up needs at every tick but computes once (N steps of ``dt``
    after the tick; read-only by convention).

    Attributes:
        dt: the step [s]; max_sink_rate: the allowed sink rate [m/s]; period: the gait
            period [s].
        mid_list: the steps' mid-points ``(k + ½)·dt`` after the tick (N floats) [s].
        end_list: the steps' ends ``(k + 1)·dt`` (N floats) [s].
        sink_list: ``max_sink_rate·(k + 1)·dt``, the sinkage a standing foot may add by
            each step's end (N floats) [m].
        loads: the weight each foot carries with 0, 1, 2 feet down, ``mg / max(n, 1)`` [N].
        sinkages: the depth ``Z`` each of ``loads`` settles a foot at [m] (0 on rigid).
        slice_rows: the sole slices' offsets as rows ``(0, y, 0)`` (n_points, 3) [m, foot].
        x_ref_template: the state reference with the CoM height set (N, 12).
        omega: √(g/h) [1/s]; cosh, sinh: of ω·dt (the pendulum's step).
    """

    dt: float
    max_sink_rate: float
    period: float
    mid_list: list
    end_list: list
    sink_list: list
    loads: tuple[float, float, float]
    sinkages: tuple[float, float, float]
    slice_rows: np.ndarray
    x_ref_template: np.ndarray
    omega: float
    cosh: float
    sinh: float

    @classmethod
    def build(cls, config: MPCConfig, horizon: int, weight: float, ground: GroundModel,
              schedule: GaitSchedule, slice_offsets: np.ndarray, com_height: float,
              omega: float) -> "HorizonConstants":
        """The constants of an N = ``horizon`` step horizon for a robot of ``weight`` [N]
        on ``ground``, sole slices at ``slice_offsets`` [m], CoM ``com_height`` [m] above
        the surface, pendulum frequency ``omega`` [1/s]."""
        dt, mg = config.dt, weight
        x_ref = np.zeros((horizon, 12))
        x_ref[:, 5] = ground.surface_height + com_height
        loads = (mg / 1, mg / 1, mg / 2)
        # per step k: (k + ½)·dt, (k + 1)·dt and rate·(k + 1)·dt on Python floats
        return cls(dt=dt, max_sink_rate=config.max_sink_rate, period=schedule.period,
                   mid_list=[(k + 0.5) * dt for k in range(horizon)],
                   end_list=[(k + 1) * dt for k in range(horizon)],
                   sink_list=[config.max_sink_rate * (k + 1) * dt for k in range(horizon)],
                   loads=loads, sinkages=tuple(ground.sinkage(f) for f in loads),
                   slice_rows=np.array([[0.0, y, 0.0] for y in slice_offsets]),
                   x_ref_template=x_ref, omega=omega,
                   cosh=math.cosh(omega * dt), sinh=math.sinh(omega * dt))


@dataclass(frozen=True)
class MPCHorizon:
    """The horizon's inputs to :meth:`~granular_mpc.control.mpc.CentroidalMPC.solve`.

    Attributes:
        x_ref: state reference per step (N, 12) (yaw, CoM position, CoM velocity set).
        contacts: planned contact per step and foot (N, 2) bool.
        points: contact points per step and foot (N, 2, n_points, 3) [m, W] (zero off).
        load: nominal normal load per step and foot (N, 2) [N].
        capacity: normal force each foot down may bear (N, 2) [N]; None on rigid ground.
    """

    x_ref: np.ndarray
    contacts: np.ndarray
    points: np.ndarray
    load: np.ndarray
    capacity: np.ndarray | None


def plan_horizon(hz: HorizonConstants, schedule: GaitSchedule, ground: GroundModel, *,
                 t: float, stance: tuple[bool, bool], feet: tuple[FootPoints, FootPoints],
                 targets: list, v_x: float, yaw: float, com: np.ndarray,
                 vcom: np.ndarray) -> MPCHorizon:
    """The horizon's inputs at an MPC tick (the module docstring's definitions).

    Args:
        hz: the constants (:meth:`HorizonConstants.build`).
        schedule: the gait plan; ground: the controller's ground model.
        t: the tick's time [s]; stance: the plan's contact (left, right) at ``t``.
        feet: both feet's contact points now (W).
        targets: per foot its swing target (3,) [m, W] or None.
        v_x: the commanded forward speed [m/s]; yaw: the heading [rad].
        com, vcom: CoM position [m] and velocity [m/s] in W.
    """
    # per foot, constant over the horizon: how long it stays down / until it lands
    liftoff = [schedule.time_to_liftoff(t, i) for i in range(2)]
    touchdown = [schedule.time_to_touchdown(t, i) for i in range(2)]
    # one pass over the steps: the points depend only on (foot, stays down?, feet down),
    # so each such group is evaluated once and the steps index into the groups
    groups: dict = {}               # (foot, stays down?, feet down) -> group index
    where = []                      # per step: per foot its group index + 1 (0: off)
    contacts, downs, load = [], [], []
    for tk in hz.mid_list:
        c = schedule.contacts(t + tk)
        n = c[0] + c[1]
        row, row_down = [0, 0], [False, False]
        for i in range(2):
            if c[i]:
                down = bool(stance[i] and liftoff[i] >= tk)
                row[i] = groups.setdefault((i, down, n), len(groups)) + 1
                row_down[i] = down
        where.append(row)
        contacts.append(c)
        downs.append(row_down)
        # mg / max(n, 1) on each foot down [N]
        load.append((hz.loads[n] if c[0] else 0.0, hz.loads[n] if c[1] else 0.0))
    granular = ground.granular
    now = ([sole_depth(ground.surface_height, feet[0].points),
            sole_depth(ground.surface_height, feet[1].points)] if granular else [0.0, 0.0])
    table = [np.zeros_like(hz.slice_rows)]          # the groups' points (n_points, 3)
    offsets = None                                  # the landing slices' offsets (W)
    landing: dict = {}                              # foot -> where it lands (x, y)
    for i, is_down, n in groups:
        if is_down:
            # where it stands, deeper by the sinkage still to come
            pts = feet[i].points.copy()
            if granular:
                pts[:, 2] -= max(hz.sinkages[n] - now[i], 0.0)
        else:
            if i not in landing:
                # its swing target, or one stride on (twice the half-period's travel)
                stride = np.array([v_x * hz.period * 0.5, 0.0])
                xy = (targets[i][:2] if targets[i] is not None and not stance[i]
                      else mean_point(feet[i].points)[:2] + 2 * stride)
                landing[i] = xy.tolist()
            if offsets is None:
                offsets = (hz.slice_rows @ rot_z(yaw).T).tolist()
            x, y = landing[i]
            z = ground.surface_height - hz.sinkages[n]
            pts = np.array([(x + ox, y + oy, z) for ox, oy, _ in offsets])
        table.append(pts)
    table = np.array(table)
    points = table[np.array(where)]                 # (N, 2, n_points, 3)
    # each group's centre (x, y): mean_point of its rows, all groups in one reduction
    centres = (np.add.reduce(table[:, :, :2], axis=1) / table.shape[1]).tolist()
    # the inverted pendulum rolled out over the supports (the module docstring)
    omega, ch, sh, dt = hz.omega, hz.cosh, hz.sinh, hz.dt
    px, py = float(com[0]), float(com[1])
    vx, vy = float(vcom[0]), float(vcom[1])
    roll = []
    for left, right in where:
        if left or right:
            if left and right:
                (ax, ay), (bx, by) = centres[left], centres[right]
                sx, sy = (ax + bx) / 2.0, (ay + by) / 2.0
            else:
                sx, sy = centres[left or right]
            rx, ry = px - sx, py - sy
            px, py, vx, vy = (sx + rx * ch + vx / omega * sh, sy + ry * ch + vy / omega * sh,
                              rx * omega * sh + vx * ch, ry * omega * sh + vy * ch)
        else:
            px, py = px + vx * dt, py + vy * dt
        roll.append((px, py, vx, vy))
    x_ref = hz.x_ref_template.copy()                # the CoM height already set
    x_ref[:, 2] = yaw
    x_ref[:, [3, 4, 9, 10]] = roll
    capacity = None
    if granular:
        # depth per step and foot down at the step's end: from the present depth (stays
        # down) or from the surface at touchdown (lands)
        rate = hz.max_sink_rate
        kk, ii, depths = [], [], []
        for k, (c, row_down) in enumerate(zip(contacts, downs)):
            for i in range(2):
                if c[i]:
                    kk.append(k)
                    ii.append(i)
                    depths.append(now[i] + hz.sink_list[k] if row_down[i]
                                  else rate * max(hz.end_list[k] - touchdown[i], 0.0))
        capacity = np.zeros((len(where), 2))
        if depths:
            # one interpolation for all (ground.capacity's numbers point by point)
            capacity[kk, ii] = ground.capacities(depths)
    return MPCHorizon(x_ref=x_ref, contacts=np.array(contacts), points=points,
                      load=np.array(load), capacity=capacity)


__all__ = ["HorizonConstants", "MPCHorizon", "plan_horizon", "mean_point", "sole_depth"]
