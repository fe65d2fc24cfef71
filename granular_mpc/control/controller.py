"""The walking controller: gait + footholds + swing + MPC (≈40 Hz) + WBC (≈500 Hz).

The controller owns its own ground model, built from the terrain the user chose for the
controller (``controller.terrain``: ``plant`` or any terrain file) — on sand a user can run
a rigid-assumption controller on a granular plant. It reads the plant's state (q, v) —
perfect state estimation — and returns actuator torques.

Solver status is data: every MPC and WBC tick appends a :class:`TickRecord`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pinocchio as pin

from ..config import CommandConfig, ControllerConfig
from ..robot.model import SIDES, Biped
from ..rotations import matrix_from_quat_xyzw, rot_z
from ..terrain.base import TerrainModel
from .contact_model import GroundModel, ground_model
from .gait import LEFT, CommandRamp, GaitSchedule, foothold, predict_com, predict_dcm
from .horizon import HorizonConstants, plan_horizon
from .mpc import CentroidalMPC, MPCData, MPCPlan
from .swing import cycloid_components
from .wbc import FootPoints, WBCData, WBCReference, WholeBodyController


def max_contact_pairs(schedule: GaitSchedule, mpc) -> int:
    """Most (step, foot-in-contact) pairs any MPC horizon of this gait contains (sampled
    over one gait cycle after the start-up)."""
    best = mpc.horizon
    t0 = schedule.start
    for s in np.linspace(0.0, schedule.period, 97):
        n = sum(sum(schedule.contacts(t0 + s + (k + 0.5) * mpc.dt)) for k in range(mpc.horizon))
        best = max(best, n)
    return int(best)


def effective_gait(config: ControllerConfig, ground: GroundModel, weight: float):
    """The gait with the load-transfer double support this ground needs.

    On sand a touching-down foot bears nothing until it has sunk to the depth whose
    capacity carries the load, ``Z(W)``; loading it no faster than ``max_sink_rate`` takes
    ``Z(W)/max_sink_rate`` seconds, during which the other foot must still stand. With
    ``load_transfer: auto`` that time is taken out of each swing (0 on rigid ground)."""
    gait = config.gait
    lt = gait.load_transfer
    if lt == "auto":
        lt = ground.sinkage(weight) / config.mpc.max_sink_rate if ground.granular else 0.0
    swing = min(gait.swing_fraction, 0.5 - float(lt) / gait.period)
    if swing <= 0.05:
        from ..exceptions import ConfigError
        raise ConfigError(f"load transfer of {lt:.3f} s leaves no swing in a {gait.period} s gait",
                          key="controller.gait.load_transfer", value=lt)
    return gait.model_copy(update={"swing_fraction": swing, "load_transfer": float(lt)})


def next_tick(current: float, t: float, period: float, first: bool) -> float:
    """Time of the MPC tick after the one run at ``t`` [s].

    Ticks stay on the grid ``t_first + n·period`` (the first tick sets its phase), so the
    MPC rate is the configured one even when the controller is only called on a coarser
    grid (each tick then runs at the first call at or after its grid time, at most one
    call late, never accumulating the lateness); ticks missed entirely are skipped."""
    nxt = t + period if first else current + period
    while nxt <= t + 1e-9:
        nxt += period
    return nxt


def nominal_forces(stance: tuple[bool, bool], weight: float, n_points: int) -> np.ndarray:
    """The weight ``weight`` [N] shared equally by the stance feet, vertical, spread
    equally over each foot's ``n_points`` contact points: shape (2, n_points, 3) [N, W]."""
    forces = np.zeros((2, n_points, 3))
    n_st = sum(bool(c) for c in stance)
    for i in range(2):
        if stance[i]:
            forces[i, :, 2] = weight / n_st / n_points
    return forces


_ZERO3 = (0.0, 0.0, 0.0)
_NO_TURN = np.zeros(3)                  # the trunk's angular velocity reference (read-only)
_NO_TURN.flags.writeable = False


@dataclass(frozen=True)
class TickConstants:
    """What :meth:`WalkingController.compute` reads at every tick but is fixed per run.

    Attributes:
        dt: MPC step [s]; N: MPC horizon [steps]; mpc_period: 1 / MPC rate [s].
        mass: robot mass [kg]; gravity: (0, 0, −g) in W [m/s²] (read-only).
        start_delay: the command's start delay [s].
        k_speed_integral: foothold speed-integral gain [1/s]; integral_limit: the
            integral's bound [m].
        half_period: half the gait period [s]; max_lateral: largest lateral CoM–foot
            offset the ground can push back [m]; target_z: swing targets' height [m, W].
        sole_radius: sole arc radius [m]; swing_height: swing apex [m]; swing_duration [s].
        foot_frames: the feet's frame ids (left, right).
    """

    dt: float
    N: int
    mpc_period: float
    mass: float
    gravity: np.ndarray
    start_delay: float
    k_speed_integral: float
    integral_limit: float
    half_period: float
    max_lateral: float
    target_z: float
    sole_radius: float
    swing_height: float
    swing_duration: float
    foot_frames: tuple


@dataclass(frozen=True)
class TickRecord:
    """One controller tick (status as data, never printed)."""

    t: float
    kind: str               # "mpc" or "wbc"
    status: str
    solve_ms: float
    total_ms: float
    fallback: str = ""


@dataclass
class ControllerData:
    mpc: MPCData
    wbc: WBCData
    ramp: CommandRamp
    origin: np.ndarray                      # initial CoM (x, y) and yaw
    liftoff: list = field(default_factory=lambda: [None, None])   # foot-frame origin at lift-off
    target: list = field(default_factory=lambda: [None, None])    # current swing targets (sole)
    was_stance: list = field(default_factory=lambda: [True, True])
    plan: MPCPlan | None = None
    next_mpc: float = 0.0
    speed_integral: float = 0.0             # ∫(v_cmd − v_com,x) dt while walking [m]
    last_t: float | None = None
    last_v_ref: np.ndarray | None = None    # the speed reference at last_t (x, y) [m/s]
    records: list = field(default_factory=list)
    last_tau: np.ndarray | None = None

    heading: np.ndarray | None = None       # rot_z(origin yaw), made once (read-only)

    @property
    def qp_failures(self) -> int:
        return self.mpc.failures + self.wbc.failures

    def command_velocity(self, t: float) -> np.ndarray:
        """The speed reference (x, y) [m/s, W] at ``t`` [s]: the last tick's when ``t`` is
        its time (no second evaluation of the ramp per tick), else the ramp's."""
        if t == self.last_t and self.last_v_ref is not None:
            return self.last_v_ref
        return self.ramp.reference(t)[1]

    def trunk_heading(self) -> np.ndarray:
        """The trunk orientation the WBC holds, ``rot_z(origin[2])`` (3, 3), built at the
        first call and shared (read-only) by every later tick's reference."""
        if self.heading is None:
            self.heading = rot_z(float(self.origin[2]))
            self.heading.flags.writeable = False
        return self.heading


@dataclass(frozen=True)
class WalkingController:
    """Controller model (immutable); changing state lives in :class:`ControllerData`."""

    config: ControllerConfig
    command: CommandConfig
    biped: Biped
    terrain: TerrainModel
    ground: GroundModel
    schedule: GaitSchedule
    mpc: CentroidalMPC
    wbc: WholeBodyController
    inertia_B: np.ndarray
    nominal_com_height: float

    @classmethod
    def build(cls, config: ControllerConfig, command: CommandConfig, biped: Biped,
              terrain: TerrainModel) -> "WalkingController":
        """Controller for ``biped`` believing the ground is ``terrain``."""
        ground = ground_model(terrain, config.mpc)
        config = config.model_copy(update={"gait": effective_gait(config, ground, biped.weight)})
        q0 = biped.standing_configuration()
        data = biped.create_data()
        pin.ccrba(biped.model, data, q0, np.zeros(biped.model.nv))
        inertia = np.array(data.Ig.inertia)
        schedule = GaitSchedule(config.gait)
        mpc = CentroidalMPC(config.mpc, biped.mass, inertia, biped.gravity, ground,
                            n_points=biped.config.foot.slices,
                            max_pairs=max_contact_pairs(schedule, config.mpc))
        wbc = WholeBodyController(config.wbc, biped, ground, config.swing.kp, config.swing.kd,
                                  n_points=biped.config.foot.slices)
        return cls(config, command, biped, terrain, ground, schedule, mpc, wbc, inertia,
                   float(biped.com(q0)[2] - biped.lowest_sole_point(q0).min()))

    def new_data(self, q: np.ndarray, dt_wbc: float | None = None) -> ControllerData:
        com = self.biped.com(q)
        R = matrix_from_quat_xyzw(q[3:7])
        yaw = math.atan2(R[1, 0], R[0, 0])
        return ControllerData(self.mpc.new_data(), self.wbc.new_data(),
                              CommandRamp(self.command, dt_wbc or 1.0 / self.config.wbc.rate_hz),
                              np.array([com[0], com[1], yaw]))

    # ------------------------------------------------------------------ helpers
    @cached_property
    def omega(self) -> float:
        """Natural frequency √(g/h) of the inverted pendulum over the stance foot [1/s]."""
        return math.sqrt(self.biped.gravity / self.config.mpc.com_height)

    @cached_property
    def foothold_config(self):
        """Foothold settings with the step width this ground allows."""
        return self.config.foothold.model_copy(update={"step_width": self.step_width})

    @cached_property
    def step_width(self) -> float:
        """Step width the controller uses [m]: the nominal one, narrowed where the ground
        cannot push sideways enough. In the linear inverted pendulum the lateral force is
        ``F_y/F_z ≈ (w/2)/h``, so ``w ≤ 2·margin·(F_l/F_z)_max·h``."""
        f = self.config.foothold
        return min(f.step_width,
                   2.0 * f.lateral_margin * self.ground.lateral_ratio * self.config.mpc.com_height)

    @property
    def com_height_ref(self) -> float:
        """CoM height above the undisturbed surface: the granular-aware controller keeps the
        leg geometry of rigid walking by lowering the CoM by the expected sinkage."""
        h = self.config.mpc.com_height
        if self.ground.granular:
            h -= self.ground.sinkage(self.biped.weight)
        return h

    def foot_points(self, pdata: pin.Data) -> tuple[FootPoints, FootPoints]:
        """Contact points (lowest points of the sole slices) of both feet, in W.

        The closed form of :func:`~granular_mpc.terrain.contact.slice_geometry` (the same
        IEEE operations in the same order, vectorised over the slices): each slice's
        lowest point is its centre ``p + y e_y`` plus the arc point
        ``R sin ψ e_x − R cos ψ e_z``, with ψ the world-down direction in the slice plane
        clipped to the sole's half-angle; ψ is the same for every slice of a foot."""
        return self.sole_contacts(pdata)[0]

    def sole_contacts(self, pdata: pin.Data) -> tuple[tuple[FootPoints, FootPoints], tuple]:
        """:meth:`foot_points` and each foot's mean contact point ``(x, y, z)`` [m, W] as
        Python floats (NumPy's mean: the points summed in order, divided by n).
        """
        R_arc, half, ys, frames = self._sole
        n = len(ys)
        flat: list = []
        means = []
        for rot, pos in self._placement_views(pdata):
            # the rows of R (the components of e_x, e_y, e_z along W's x, y, z) and p
            (xx, yx, zx), (xy, yy, zy), (xz, yz, zz) = rot.tolist()
            px, py, pz = pos.tolist()
            psi = min(max(math.atan2(-xz, zz), -half), half)
            s_, c_ = R_arc * math.sin(psi), -R_arc * math.cos(psi)
            ax, ay, az = s_ * xx + c_ * zx, s_ * xy + c_ * zy, s_ * xz + c_ * zz
            pts = [((px + y * yx) + ax, (py + y * yy) + ay, (pz + y * yz) + az) for y in ys]
            sx = sy = sz = 0.0
            for x, y, z in pts:
                flat += (x, y, z)
                sx += x
                sy += y
                sz += z
            # their offsets from p (per component, the numbers of ``pts - p``)
            for x, y, z in pts:
                flat += (x - px, y - py, z - pz)
            means.append((sx / n, sy / n, sz / n))
        # both feet's points and offsets as one (4, n, 3) array from a flat list of floats
        # (one NumPy call, for speed): four contiguous blocks
        both = np.array(flat).reshape(4, n, 3)
        return (FootPoints(both[0], both[1]), FootPoints(both[2], both[3])), tuple(means)

    def _placement_views(self, pdata: pin.Data) -> tuple:
        """Both feet's frame placements in ``pdata`` as views of its storage ((R, p) per
        foot, left then right), made at the first call for this ``pdata`` and reused
        (Pinocchio updates them in place; reading a view costs less than ``oMf[id]``)."""
        cache = self._views
        if cache.get("pdata") is not pdata:
            cache["pdata"] = pdata
            cache["views"] = tuple((pdata.oMf[fid].rotation, pdata.oMf[fid].translation)
                                   for fid in self._sole[3])
        return cache["views"]

    @cached_property
    def _views(self) -> dict:
        """The one-entry cache of :meth:`_placement_views` (the last ``pdata`` and its
        views)."""
        return {}

    @cached_property
    def _horizon(self) -> HorizonConstants:
        """The MPC horizon's per-tick constants."""
        return HorizonConstants.build(self.config.mpc, self.mpc.N, self.biped.weight,
                                      self.ground, self.schedule, self.biped.slice_offsets,
                                      self.com_height_ref, self.omega)

    @cached_property
    def _tick(self) -> TickConstants:
        """The per-run constants of :meth:`compute` (looked up once, not per tick)."""
        c, b = self.config, self.biped
        fh = c.foothold
        g = np.array([0.0, 0.0, -b.gravity])
        g.flags.writeable = False
        return TickConstants(
            dt=c.mpc.dt, N=self.mpc.N, mpc_period=1.0 / c.mpc.rate_hz,
            mass=b.mass, gravity=g,
            start_delay=self.command.start_delay,
            k_speed_integral=fh.k_speed_integral,
            integral_limit=fh.max_speed_correction / max(fh.k_speed_integral, 1e-9),
            half_period=0.5 * self.schedule.period,
            max_lateral=self.ground.lateral_ratio * c.mpc.com_height,
            target_z=self.ground.surface_height - c.swing.touchdown_depth,
            sole_radius=b.config.foot.radius, swing_height=c.swing.height,
            swing_duration=self.schedule.swing_duration,
            foot_frames=tuple(b.foot_frame[side] for side in SIDES))

    @cached_property
    def _sole(self) -> tuple:
        """Sole arc radius [m], half-angle [rad], slice offsets [m] and both feet's frame
        ids (left, right): the constants of :meth:`foot_points`."""
        foot = self.biped.config.foot
        return (foot.radius, foot.half_angle, self.biped.slice_offsets.tolist(),
                tuple(self.biped.foot_frame[side] for side in SIDES))

    def _force_cap_now(self, mean_z: tuple[float, float]) -> np.ndarray:
        """Normal force each foot may carry now [N]: the capacity at its depth plus the
        sinkage allowed over half an MPC step. The excess over the present capacity,
        ≈ F_cap'(z)·δ, is what makes the foot sink, so the look-ahead δ sets both how fast
        the load can be taken and the largest overshoot (load only as fast as it sinks)."""
        step = self.config.mpc.max_sink_rate * 0.5 * self.config.mpc.dt
        # per foot on Python floats: the depth (the surface minus the mean height ``mean_z``
        # [m] of its points) plus the look-ahead, and its capacity
        h, cap = self.ground.surface_height, self.ground.capacity
        return np.array((cap((h - mean_z[0]) + step), cap((h - mean_z[1]) + step)))

    # ------------------------------------------------------------------ the tick
    def compute(self, d: ControllerData, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Actuator torques [N·m] at time ``t`` for plant state (q, v)."""
        b = self.biped
        k_ = self._tick
        pd = d.wbc.pin
        pin.forwardKinematics(b.model, pd, q, v)
        pin.updateFramePlacements(b.model, pd)
        # the CoM from the kinematics just computed (centerOfMass(q, v) would redo them:
        # the same numbers bit for bit)
        pin.centerOfMass(b.model, pd, pin.VELOCITY, False)
        com, vcom = pd.com[0].copy(), pd.vcom[0].copy()
        # the tick's scalar arithmetic on Python floats (NumPy scalars cost more per
        # operation; the numbers are the same)
        (cx, cy, _), (vx, vy, _) = com.tolist(), vcom.tolist()
        feet, means = self.sole_contacts(pd)
        stance = self.schedule.contacts(t)
        # lift-off bookkeeping
        for i in range(2):
            if d.was_stance[i] and not stance[i]:
                d.liftoff[i] = pd.oMf[k_.foot_frames[i]].translation.copy()
                d.target[i] = None
            d.was_stance[i] = stance[i]
        p_ref, v_ref, a_ref = d.ramp.reference(t)
        vrx, vry = v_ref.tolist()
        # integral of the forward speed error: corrects the speed the footholds assume
        # no windup during start-up and ramp
        if d.last_t is not None and t >= k_.start_delay + d.ramp.ramp_duration:
            d.speed_integral += (vrx - vx) * (t - d.last_t)
            lim = k_.integral_limit
            d.speed_integral = float(min(max(d.speed_integral, -lim), lim))
        d.last_t = t
        d.last_v_ref = v_ref
        yaw_ref = d.origin[2]
        # footholds of swinging feet (sole points) for their next touchdown, from the DCM
        phases = [0.0, 0.0]             # swing phase of each swinging foot at t
        if not (stance[0] and stance[1]):
            omega = self.omega
            # the command with the integral's correction on x
            v_step = (vrx + k_.k_speed_integral * d.speed_integral, vry)
            y_line = float(d.origin[1] + p_ref[1])
            # c + ċ/ω per component
            dcm = (cx + vx / omega, cy + vy / omega)
            for i in range(2):
                if stance[i]:
                    continue
                t_td, phase = self.schedule.swing_timing(t, i)
                phases[i] = phase
                if d.target[i] is None or phase < 0.8:
                    if stance[1 - i]:
                        # one foot down: the pendulum over its mean contact point
                        p_st = means[1 - i]
                        xi = predict_dcm(dcm, p_st, omega, t_td)
                        c_td = predict_com((cx, cy), (vx, vy), p_st, omega, t_td)
                    else:
                        xi, c_td = dcm, (cx, cy)
                    xy = foothold(self.foothold_config, dcm=xi, v_cmd=v_step,
                                  stance_duration=k_.half_period, omega=omega,
                                  lateral_sign=1.0 if i == LEFT else -1.0,
                                  y_error=cy - y_line, com_y=float(c_td[1]),
                                  max_lateral=k_.max_lateral)
                    d.target[i] = np.array((xy[0], xy[1], k_.target_z))
        if self.schedule.standing(t):
            return self._weight_shift(d, t, q, v, com, feet)
        # ---------------- MPC
        if d.plan is None or t >= d.next_mpc - 1e-9:
            first = d.plan is None
            R = matrix_from_quat_xyzw(q[3:7])
            rpy = pin.rpy.matrixToRpy(R)
            omega_W = R @ v[3:6]
            self._run_mpc(d, t, com, vcom, rpy, omega_W, feet, stance, vrx, yaw_ref)
            d.next_mpc = next_tick(d.next_mpc, t, k_.mpc_period, first)
        plan = d.plan
        dt, N = k_.dt, k_.N
        forces = self._force_reference(plan, t, stance)
        # CoM reference: the MPC prediction at t (linear in time inside the step)
        s = min(max((t - plan.t) / dt, 0.0), float(N))
        k0 = min(int(s), N - 1)
        xs = plan.states[k0]
        # per component: xs[3:6] + ((s − k0 − 1)·dt)·xs[9:12], the array form's numbers
        (x3, x4, x5), (x9, x10, x11) = xs[3:6].tolist(), xs[9:12].tolist()
        lead = (s - k0 - 1.0) * dt
        com_ref = np.array((x3 + lead * x9, x4 + lead * x10, x5 + lead * x11))
        com_vel_ref = xs[9:12]
        f_tot = np.add.reduce(forces, axis=(0, 1))     # forces.sum(axis=(0, 1))
        com_acc = f_tot / k_.mass + k_.gravity
        granular = self.ground.granular
        if granular and N >= 3:
            k = int(min(max((t - plan.t) // dt, 0), N - 1))
            k1, k2 = min(k + 1, N - 1), min(k + 2, N - 1)
            # per foot: (z[k2] − 2 z[k1] + z[k]) / dt², the array form's numbers
            (a0, a1), (b0, b1), (c0, c1) = (plan.sinkage[k2].tolist(),
                                            plan.sinkage[k1].tolist(),
                                            plan.sinkage[k].tolist())
            dt2 = dt ** 2
            sink_accel = np.array(((a0 - 2.0 * b0 + c0) / dt2, (a1 - 2.0 * b1 + c1) / dt2))
        else:
            sink_accel = np.zeros(2)
        # swing references (foot-frame origin = sole point + R up), rows of Python floats
        # made into arrays once
        rows = [[_ZERO3, _ZERO3], [_ZERO3, _ZERO3], [_ZERO3, _ZERO3]]
        for i in range(2):
            if stance[i] or d.liftoff[i] is None:
                continue
            gx, gy, gz = d.target[i].tolist()
            rows[0][i], rows[1][i], rows[2][i] = cycloid_components(
                d.liftoff[i].tolist(), (gx, gy, gz + k_.sole_radius), k_.swing_height,
                phases[i], k_.swing_duration)
        ref = WBCReference(com=com_ref, com_vel=com_vel_ref, com_acc=com_acc,
                           R_trunk=d.trunk_heading(), omega=_NO_TURN, stance=stance,
                           forces=forces, swing_pos=np.array(rows[0]),
                           swing_vel=np.array(rows[1]), swing_acc=np.array(rows[2]),
                           sink_accel=sink_accel,
                           force_cap=(self._force_cap_now((means[0][2], means[1][2]))
                                      if granular else None))
        t_wbc = time.perf_counter()
        tau = self.wbc.solve(d.wbc, q, v, ref, feet)
        d.records.append(TickRecord(t, "wbc", d.wbc.last_status.value, d.wbc.last_ms,
                                    (time.perf_counter() - t_wbc) * 1e3))
        d.last_tau = tau
        return tau

    def _force_reference(self, plan: MPCPlan, t: float, stance: tuple[bool, bool]) -> np.ndarray:
        """Contact forces (2, n_points, 3) [N, W] the WBC tracks at ``t``.

        The MPC samples each step's contact set at the step's mid-point, so a step that
        contains a contact event plans the set of its longer part: for the rest of that
        step the plan disagrees with the schedule at ``t`` (the foot still swinging is
        held at zero force by the WBC, the one still standing planned at zero), and
        tracking it unloads the robot up to half a step before a touchdown. The reference
        is therefore the planned forces of the step nearest to ``t`` whose contact set is
        the schedule's at ``t`` (the step the plan says ``t`` belongs to, else its
        neighbour on ``t``'s side of the event, else the other one); if no step within one
        of ``t`` matches (an event right at the start of a fresh plan), the weight shared
        equally over the scheduled stance feet, vertical, spread over their points."""
        dt = self.config.mpc.dt
        n = plan.forces.shape[0]
        s = (t - plan.t) / dt
        k = min(max(math.floor(s), 0), n - 1)
        want = [bool(stance[0]), bool(stance[1])]
        near = k - 1 if s - k < 0.5 else k + 1
        contacts = plan.contacts
        for j in (k, near, 2 * k - near):
            if 0 <= j < n and contacts[j].tolist() == want:
                return plan.forces[j].copy()
        return nominal_forces(stance, self.biped.weight, plan.forces.shape[2])

    def _weight_shift(self, d: ControllerData, t: float, q: np.ndarray, v: np.ndarray,
                      com: np.ndarray, feet) -> np.ndarray:
        """Initial double support: move the CoM (smoothly, WBC only) to where the periodic
        gait's DCM starts: ``c = w/(1 + e^{ωT_st})`` inside the first stance (left) foot."""
        b = self.biped
        T = self.schedule.start
        s = min(max(t / T, 0.0), 1.0) if T > 0 else 1.0
        blend = 0.5 - 0.5 * math.cos(math.pi * s)
        dblend = 0.5 * math.pi / T * math.sin(math.pi * s) if T > 0 else 0.0
        e = math.exp(self.omega * 0.5 * self.schedule.period)
        shift = 0.5 * self.step_width * (e - 1.0) / (e + 1.0)   # w/2 − c
        # ndarray.mean's arithmetic (the sum, divided by n) without its Python wrapper
        y_l = np.add.reduce(feet[0].points[:, 1], None) / len(feet[0].points)
        y_r = np.add.reduce(feet[1].points[:, 1], None) / len(feet[1].points)
        mid = 0.5 * (y_l + y_r)
        target = np.array([d.origin[0], mid + shift * np.sign(y_l - y_r),
                           self.ground.surface_height + self.com_height_ref])
        start = np.array([d.origin[0], d.origin[1], target[2]])
        com_ref = start + blend * (target - start)
        com_vel = dblend * (target - start)
        # np.clip's number on a scalar (lo ≤ hi, NaN kept) as min(max(·))
        share_l = float(min(max((com_ref[1] - y_r) / max(y_l - y_r, 1e-6), 0.0), 1.0))
        forces = np.zeros((2, self.mpc.n_points, 3))
        forces[0, :, 2] = share_l * b.weight / self.mpc.n_points
        forces[1, :, 2] = (1.0 - share_l) * b.weight / self.mpc.n_points
        z3 = np.zeros((2, 3))
        ref = WBCReference(com=com_ref, com_vel=com_vel, com_acc=np.zeros(3),
                           R_trunk=d.trunk_heading(), omega=np.zeros(3), stance=(True, True),
                           forces=forces, swing_pos=z3, swing_vel=z3, swing_acc=z3,
                           sink_accel=np.zeros(2), force_weight=1e-3)
        t_wbc = time.perf_counter()
        tau = self.wbc.solve(d.wbc, q, v, ref, feet)
        d.records.append(TickRecord(t, "wbc", d.wbc.last_status.value, d.wbc.last_ms,
                                    (time.perf_counter() - t_wbc) * 1e3))
        d.last_tau = tau
        return tau

    def _run_mpc(self, d, t, com, vcom, rpy, omega_W, feet, stance, v_x, yaw_ref):
        """One MPC tick: the horizon's inputs (:func:`~granular_mpc.control.horizon.plan_horizon`),
        then the solve; the plan goes to ``d.plan``."""
        t0 = time.perf_counter()
        x0 = np.concatenate([rpy, com, omega_W, vcom])
        x0[2] = yaw_ref + (x0[2] - yaw_ref + math.pi) % (2 * math.pi) - math.pi
        hz = plan_horizon(self._horizon, self.schedule, self.ground, t=t, stance=stance,
                          feet=feet, targets=d.target, v_x=v_x, yaw=yaw_ref, com=com,
                          vcom=vcom)
        plan = self.mpc.solve(d.mpc, t=t, x0=x0, x_ref=hz.x_ref, contacts=hz.contacts,
                              points=hz.points, nominal_load=hz.load, capacity=hz.capacity)
        d.plan = plan
        d.records.append(TickRecord(t, "mpc", plan.status.value, plan.solve_ms,
                                    (time.perf_counter() - t0) * 1e3, plan.fallback))


__all__ = ["WalkingController", "ControllerData", "TickRecord", "next_tick", "nominal_forces"]
