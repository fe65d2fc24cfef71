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
from .contact_model import GroundModel
from .gait import GaitSchedule
from .wbc import FootPoints


def _mean_row(rows: list) -> tuple[float, float, float]:
    """Mean of (x, y, z) rows of Python floats: ``np.mean(rows, axis=0)``'s numbers (the
    rows summed in order, divided by their number)."""
    sx = sy = sz = 0.0
    for x, y, z in rows:
        sx += x
        sy += y
        sz += z
    n = len(rows)
    return sx / n, sy / n, sz / n


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
        slice_ys: their y as Python floats [m].
        x_ref_template: the state reference with the CoM height set (N, 12).
        com_z: that CoM height [m, W].
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
    slice_ys: list
    x_ref_template: np.ndarray
    com_z: float
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
                   slice_ys=[float(y) for y in slice_offsets],
                   x_ref_template=x_ref, com_z=float(x_ref[0, 5]) if horizon else 0.0,
                   omega=omega,
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
    h = ground.surface_height
    rows = (feet[0].points.tolist(), feet[1].points.tolist())   # per foot (x, y, z) rows
    n_pts = len(rows[0])
    # each foot's mean contact point (NumPy's mean: summed in order, divided by n)
    means = [_mean_row(fr) for fr in rows]
    # depth now (the surface minus the points' mean height)
    now = [h - means[0][2], h - means[1][2]] if granular else [0.0, 0.0]
    zero = [(0.0, 0.0, 0.0)] * n_pts
    table = [zero]                                  # the groups' points, rows (x, y, z)
    centres = [(0.0, 0.0)]                          # the groups' centres (x, y)
    offsets = None                                  # the landing slices' offsets (W)
    landing: dict = {}                              # foot -> where it lands (x, y)
    for i, is_down, n in groups:
        if is_down:
            # where it stands, deeper by the sinkage still to come
            drop = max(hz.sinkages[n] - now[i], 0.0) if granular else 0.0
            pts = [(x, y, z - drop) for x, y, z in rows[i]] if drop else rows[i]
        else:
            if i not in landing:
                # its swing target, or one stride on (twice the half-period's travel)
                if targets[i] is not None and not stance[i]:
                    landing[i] = targets[i][:2].tolist()
                else:
                    landing[i] = [means[i][0] + 2 * (v_x * hz.period * 0.5),
                                  means[i][1] + 2 * 0.0]
            if offsets is None:
                # the slices' rows (0, y, 0) rotated by the heading, ``slice_rows @
                # rot_z(yaw).T``: each component is y times one entry of rot_z (the other
                # products are exact zeros), so on floats: (−y sin, y cos)
                c_yaw, s_yaw = math.cos(yaw), math.sin(yaw)
                offsets = [(y * -s_yaw, y * c_yaw) for y in hz.slice_ys]
            x, y = landing[i]
            z = h - hz.sinkages[n]
            pts = [(x + ox, y + oy, z) for ox, oy in offsets]
        table.append(pts)
        # its centre (x, y): NumPy's mean of the points
        centres.append(_mean_row(pts)[:2])
    # (N, 2, n_points, 3): the groups' table as one array, indexed by the steps' groups
    points = np.array(table)[np.array(where)]
    # the inverted pendulum rolled out over the supports (the module docstring), written
    # straight into the state reference's rows (yaw, CoM height set; the rest zero)
    omega, ch, sh, dt = hz.omega, hz.cosh, hz.sinh, hz.dt
    px, py = float(com[0]), float(com[1])
    vx, vy = float(vcom[0]), float(vcom[1])
    yaw, zc = float(yaw), hz.com_z
    x_rows = []
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
        x_rows.append((0.0, 0.0, yaw, px, py, zc, 0.0, 0.0, 0.0, vx, vy, 0.0))
    x_ref = np.array(x_rows)
    capacity = None
    if granular:
        # depth per step and foot at the step's end: from the present depth (stays down)
        # or from the surface at touchdown (lands); 0 for a foot off (capacity 0 there)
        rate = hz.max_sink_rate
        depths = []
        for k, (c, row_down) in enumerate(zip(contacts, downs)):
            for i in (0, 1):
                depths.append((now[i] + hz.sink_list[k] if row_down[i]
                               else rate * max(hz.end_list[k] - touchdown[i], 0.0))
                              if c[i] else 0.0)
        # one interpolation for all (ground.capacity's numbers point by point)
        capacity = ground.capacities(depths).reshape(len(where), 2)
    return MPCHorizon(x_ref=x_ref, contacts=np.array(contacts), points=points,
                      load=np.array(load), capacity=capacity)


__all__ = ["HorizonConstants", "MPCHorizon", "plan_horizon"]
