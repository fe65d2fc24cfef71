"""From a measurement data set to replayable stance windows (multiple shooting).

Every complete stance phase of a data set (a maximal run of one ``left`` / ``right``
label, touchdown and lift-off both recorded) becomes a :class:`StanceWindow`: the
measured state at its first sample, the measured torques over it, the initial contact
state of both feet, and the measured channels to compare a replay with.

State estimation (offline, so non-causal smoothing is fine):

* joint angles, trunk position and orientation: Savitzky–Golay smoothing (window
  ``smooth_window`` samples, quadratic) of the measured columns; the quaternion is
  smoothed component-wise and renormalised;
* joint rates: Savitzky–Golay derivative of the measured angles (the ``dq_*`` columns of
  a differentiated encoder are noisier than the derivative of a local fit);
* trunk linear and angular velocity: Savitzky–Golay smoothing of ``base_v*`` / ``base_w*``;
* at a touchdown (the sample before the impact) the landing leg's angles and the trunk's
  angular velocity come instead from a one-sided cubic fit to the samples up to it
  (:data:`PAST_FIT_DEGREE`): a centred smoother would read the impact into them;
* ``grf_*`` and ``intrusion_*`` are smoothed *within* each stance run (they switch feet
  at the label change).

**Local frame.** Each window is replayed in a frame translated so that the free surface
under the stance foot's touchdown point is the origin: motion-capture offsets and the
unknown height of the sand surface in the world frame then cancel, and sloped or uneven
ground is handled stance by stance. The translation is stored (``origin``).

**Initial contacts.** The stance (leading) foot starts *fresh* when its measured
intrusion and force at the first sample are ≈ 0 (the stance starts at touchdown), else
buried at its measured intrusion with its elastic displacement set from its measured
force. The other (trailing) foot is in contact when the previous run was its stance: it
starts buried at its last measured intrusion, loaded with its last measured force, with
its deepest depth and its time in stance from that run. Each foot gets its own free
surface at its measured depth below its contact point (per-foot ``surface_height``).

**Restarts** (``segments`` > 1): a window may also carry states mid-stance from which
its replay starts again (:mod:`.restarts`; off by default).

**Declared channels** (``Dataset.channels``): only measured groups are read and scored
(:func:`channel_names`), an absent one is never replaced by zeros; without trunk position
/ velocity they are estimated by leg odometry (:mod:`.estimation`), without intrusion the
surface is a plane through the leading foot's touchdown point and every phase starts at a
touchdown (with kinematic stance labels, re-estimated from the joint torques or the leg
kinematics: :func:`~.contact_estimation.refined_landing`),
without foot force a buried foot starts loaded with the force estimated from the joint
torques (:mod:`.contact_estimation`; ``docs/import.md``). A replay needs
:data:`REPLAY_REQUIRED`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pandas as pd
import pinocchio as pin

from ..columns import (AXES, BASE_ANGULAR_VELOCITY, BASE_LINEAR_VELOCITY, BASE_POSITION,
                       BASE_QUATERNION, GRF_COLUMNS, INTRUSION_COLUMNS, STANCE, TIME,
                       format_columns, joint_columns)
from ..robot.model import SIDES, Biped
from ..rotations import matrix_from_quat_wxyz
from .dataformat import Dataset, stance_phases
from .dataformat.channels import ChannelGroup, ChannelSet
from .contact_estimation import estimate_foot_forces, refined_landing
from .estimation import contact_offsets, estimate_trunk
from .foot_geometry import contact_point_rows, foot_pitch, foot_pitch_rows, patch_points
from .foot_state import FootInit, foot_init
from .restarts import Restart, stance_restarts
from .scored_channels import (CHANNEL_UNITS, REPLAY_REQUIRED, SCORED_GROUPS,  # noqa: F401
                              channel_names, channel_unit, check_replayable)


#: a touchdown window's free surface is the mean of (the stance foot's height + measured
#: intrusion) over this many first samples of the phase [samples]
SURFACE_SAMPLES = 15


@dataclass(frozen=True)
class StanceWindow:
    """One complete stance phase, ready to replay (all positions in the local frame).

    Attributes:
        index: position in the list of windows.
        trial: trial name; ``speed``: commanded speed [m/s].
        side: stance foot (``left`` / ``right``); ``foot``: its index (0 left, 1 right).
        row_start, row_stop: positional rows of the predicted (scored) samples in the
            trial (stop exclusive); the replay starts one sample before ``row_start``.
        time: times of the scored samples from the start of the stance phase [s], (n,).
        phase: stance phase [%], shape (n,).
        q0, v0: initial configuration (13) and velocity (12), Pinocchio conventions.
        tau: measured actuator torques [N·m], shape (n, 6): ``tau[k]`` is held over the
            sample interval that ends at scored sample k.
        feet: initial contact state of (left, right).
        origin: world position of the local-frame origin [m].
        touchdown_W: world position of the stance foot's touchdown point on the free
            surface (forward kinematics of the measured state + measured intrusion) [m].
        meas: measured channels (format-v1 names) → (n,) arrays.
        features: measured state variables for localisation → (n,) arrays.
        columns: every numeric column of the data format on the scored rows, as measured
            (``time``, ``q_*``, ``dq_*``, ``tau_*``, ``base_*``, ``grf_*``,
            ``intrusion_*``) → (n,) arrays: what a sensor effect reads besides the
            replayed channels.
        restarts: where the replay starts again from the measured state
            (:mod:`.restarts`; empty: one replay over the whole stance).
    """

    index: int
    trial: str
    speed: float
    side: str
    foot: int
    row_start: int
    row_stop: int
    time: np.ndarray
    phase: np.ndarray
    q0: np.ndarray
    v0: np.ndarray
    tau: np.ndarray
    feet: tuple
    origin: np.ndarray
    touchdown_W: np.ndarray
    meas: dict
    features: dict = field(default_factory=dict)
    columns: dict = field(default_factory=dict)
    restarts: tuple[Restart, ...] = ()

    @property
    def n(self) -> int:
        return int(self.time.size)


#: degree of the one-sided fit that gives a landing leg's joint angles one sample before
#: its touchdown (:meth:`TrialStates.past_fit`, over ``smooth_window`` samples). The leg
#: decelerates hard there and a quadratic cannot follow the change of its deceleration:
#: on the noise-free copies of five benchmark plant runs (120 touchdowns,
#: ``bench/noise_bias.py --states``, ``docs/validation.md`` §5.3.12) a quadratic over 15
#: samples missed the angle by 2.1 mrad RMS, a cubic by 0.02 mrad; with the noise of
#: level 1 (1 mrad per encoder sample) by 2.2 and 0.83 mrad (the raw sample: 1.1 mrad).
#: The same fit gives the trunk's angular velocity there
#: (:meth:`TrialStates.past_angular_velocity`): the centred smoother of the gyro missed it
#: by 7.6 mrad/s RMS on the same noise-free data (the trunk's rotation changes at the
#: impact), the one-sided cubic by 2.2 mrad/s; with the gyro's noise (10 mrad/s per
#: sample) by 8.2 and 8.1 mrad/s: the same scatter, a quarter of the bias
PAST_FIT_DEGREE = 3


def _savgol(x: np.ndarray, window: int, deriv: int = 0, delta: float = 1.0) -> np.ndarray:
    from scipy.signal import savgol_filter

    n = x.shape[0]
    w = min(window, n if n % 2 == 1 else n - 1)
    if w < 3:
        if deriv == 0 or n < 2:
            return x.copy() if deriv == 0 else np.zeros_like(x)
        return np.gradient(x, delta, axis=0)
    poly = min(2, w - 1)
    return savgol_filter(x, w, poly, deriv=deriv, delta=delta, axis=0, mode="interp")


class TrialStates:
    """Smoothed state estimates of one trial (arrays over its rows).

    Channels of groups that ``channels`` does not hold are not read: ``dqa_meas`` is
    None without joint velocities, ``grf``/``grf_s`` without foot force and
    ``intr``/``intr_s``/``dintr_s`` without intrusion; the trunk position and velocity are
    then estimated (``trunk_source``: ``"measured"``, ``"velocity from position"`` or
    ``"leg odometry"``).
    """

    def __init__(self, biped: Biped, df: pd.DataFrame, joint_names: Sequence[str],
                 fs: float, window: int = 15, contact_window: int = 9,
                 channels: ChannelSet | None = None, refine_touchdowns: bool = False) -> None:
        ch = ChannelSet.all() if channels is None else channels
        self.channels = ch
        self.n = len(df)
        J = list(joint_names)
        dt = 1.0 / fs
        qa = df[joint_columns(J, "q")].to_numpy(dtype=float)
        self.qa_raw = qa
        self.dqa_meas = (df[joint_columns(J, "dq")].to_numpy(dtype=float)
                         if ch.has(ChannelGroup.JOINT_VELOCITIES) else None)
        self.window = window
        self.dt = dt
        self.qa = _savgol(qa, window)
        self.dqa = _savgol(qa, window, deriv=1, delta=dt)
        self.tau = df[joint_columns(J, "tau")].to_numpy(dtype=float)
        quat = df[list(BASE_QUATERNION)].to_numpy(dtype=float)
        quat = quat * np.sign(quat[:, :1] + (quat[:, :1] == 0))
        self.quat_raw = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        quat = _savgol(quat, window)
        self.quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)     # w x y z
        self.w_B_raw = df[list(BASE_ANGULAR_VELOCITY)].to_numpy(dtype=float)
        self.w_B = _savgol(self.w_B_raw, window)
        self.time = df[TIME].to_numpy(dtype=float)
        self.labels = df[STANCE].astype(str).to_numpy()
        self.biped = biped
        self.phases = stance_phases(df, sides=("left", "right"))
        # each stance phase's first row (and the row whose contact height is the free
        # surface, None: from intrusion); kinematic labels: from the leg kinematics
        self.starts = [ph.row_start for ph in self.phases]
        self.surface_rows: list[int | None] = [None] * len(self.phases)
        self.touchdown_counts = {"joint torques": 0, "leg kinematics": 0}
        if refine_touchdowns:
            self._landings(fs)
        has_p, has_v = ch.has(ChannelGroup.TRUNK_POSITION), ch.has(ChannelGroup.TRUNK_LINEAR_VELOCITY)
        if has_p:
            self.p_raw = df[list(BASE_POSITION)].to_numpy(dtype=float)
            self.trunk_source = "measured" if has_v else "velocity from position"
        else:
            est = estimate_trunk(biped, self.quat, self.qa, self.anchor_labels(), fs, dq_a=self.dqa,
                                 w_B=self.w_B, smooth_window=window)
            self.p_raw = est.position
            self.trunk_source = "leg odometry"
        self.p = _savgol(self.p_raw, window)
        if has_v:
            self.v_W = _savgol(df[list(BASE_LINEAR_VELOCITY)].to_numpy(dtype=float), window)
        elif has_p:
            self.v_W = _savgol(self.p_raw, window, deriv=1, delta=dt)
        else:
            self.v_W = est.velocity
        self.has_force = ch.has(ChannelGroup.FOOT_FORCE)
        self.has_intrusion = ch.has(ChannelGroup.INTRUSION)
        self.grf = df[list(GRF_COLUMNS)].to_numpy(dtype=float) if self.has_force else None
        self.intr = (df[list(INTRUSION_COLUMNS)].to_numpy(dtype=float)
                     if self.has_intrusion else None)
        # within-run smoothing of the stance-foot channels
        self.grf_s = np.zeros_like(self.grf) if self.has_force else None
        self.intr_s = np.zeros_like(self.intr) if self.has_intrusion else None
        self.dintr_s = np.zeros_like(self.intr) if self.has_intrusion else None
        change = np.flatnonzero(self.labels[1:] != self.labels[:-1]) + 1
        starts, stops = np.r_[0, change], np.r_[change, self.n]
        self.runs = list(zip(starts.tolist(), stops.tolist()))
        for a, b in self.runs:
            if self.labels[a] == "none":
                continue
            cw = contact_window          # the foot sinks within ≈ 20 ms: a shorter window
            if self.has_force:
                self.grf_s[a:b] = _savgol(self.grf[a:b], cw)
            if self.has_intrusion:
                self.intr_s[a:b] = _savgol(self.intr[a:b], cw)
                self.dintr_s[a:b] = _savgol(self.intr[a:b], cw, deriv=1, delta=dt)

    def _landings(self, fs: float) -> None:
        """Each phase's first row and surface row instead of its (late) label change:
        from the joint torques, else the leg kinematics (:func:`~.contact_estimation.
        refined_landing`); ``touchdown_counts`` says how many of each."""
        h = self.foot_heights()
        self.estimated_force(SIDES[0], 0)                     # computes self._forces
        for n, ph in enumerate(self.phases):
            if ph.row_start <= 1:
                continue
            other = SIDES[1 - SIDES.index(ph.side)]
            ld, source = refined_landing(self._forces.normal(ph.side), h[ph.side] - h[other],
                                         ph.row_start, fs)
            self.touchdown_counts[source] += 1
            self.starts[n] = min(max(ld.start, 1), ph.row_stop - 3)
            self.surface_rows[n] = min(max(ld.stop, self.starts[n]), ph.row_stop - 1)

    def anchor_labels(self) -> np.ndarray:
        """The stance labels with each phase starting where its foot has stopped on the
        ground (``surface_rows``; else its row in ``starts``): the previous stance foot
        is the anchor until then."""
        lab = self.labels.copy()
        rows = [s if s is not None else a for a, s in zip(self.starts, self.surface_rows)]
        for ph, a in zip(self.phases, rows):
            if a < ph.row_start:
                lab[a:ph.row_start] = ph.side
            elif a > ph.row_start:
                lab[ph.row_start:a] = SIDES[1 - SIDES.index(ph.side)]
        return lab

    def estimated_force(self, side: str, k: int) -> np.ndarray:
        """Without measured foot force: foot ``side``'s force at row ``k`` [N] (W),
        ESTIMATED from the joint torques (:mod:`.contact_estimation`; mean of rows
        k − 2 … k), computed once per trial."""
        if not hasattr(self, "_forces"):
            self._forces = estimate_foot_forces(self.biped, self.quat_raw, self.qa_raw,
                                                self.tau, self.w_B, 1.0 / self.dt)
        return self._forces.force[side][max(k - 2, 0):k + 1].mean(axis=0)

    def foot_heights(self) -> dict[str, np.ndarray]:
        """Each foot's contact-point height relative to the trunk origin in W per row [m]
        (leg kinematics and trunk orientation only; computed once)."""
        if not hasattr(self, "_heights"):
            self._heights = {s: contact_offsets(self.biped, self.quat_raw, self.qa_raw, s)[0][:, 2]
                             for s in SIDES}
        return self._heights

    def _past_poly(self, raw: np.ndarray, k: int) -> np.ndarray | None:
        """Coefficients (highest degree first) of a polynomial of degree
        :data:`PAST_FIT_DEGREE` in t − t_k fitted to ``raw``'s rows up to ``k`` only (the
        last ``window`` of them; None when there are too few)."""
        a = max(0, k - self.window + 1)
        if k + 1 - a < PAST_FIT_DEGREE + 3:
            return None
        t = (np.arange(a, k + 1) - k) * self.dt
        return np.polyfit(t, raw[a:k + 1], PAST_FIT_DEGREE)

    def past_fit(self, k: int, cols: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """Angle and rate of joints ``cols`` at row ``k`` from a polynomial fit of degree
        :data:`PAST_FIT_DEGREE` to the rows up to ``k`` only (no smoothing across an
        impact after ``k``)."""
        coef = self._past_poly(self.qa_raw[:, cols], k)
        if coef is None:
            return self.qa[k, cols], self.dqa[k, cols]
        return coef[-1], coef[-2]

    def past_angular_velocity(self, k: int) -> np.ndarray:
        """Trunk angular velocity in B at row ``k`` from a polynomial fit of degree
        :data:`PAST_FIT_DEGREE` to the ``base_w*`` rows up to ``k`` only: the centred
        smoother reads the touchdown's change of the trunk's rotation into the row before
        it (:data:`PAST_FIT_DEGREE`'s note) [rad/s]."""
        coef = self._past_poly(self.w_B_raw, k)
        return self.w_B[k].copy() if coef is None else coef[-1]

    def q(self, k: int, qa: np.ndarray | None = None) -> np.ndarray:
        b = self.biped
        w, x, y, z = self.quat[k]
        return b.q_from_parts(self.p[k], [x, y, z, w], self.qa[k] if qa is None else qa)

    def q_raw(self, k: int) -> np.ndarray:
        w, x, y, z = self.quat_raw[k]
        return self.biped.q_from_parts(self.p_raw[k], [x, y, z, w], self.qa_raw[k])

    def v(self, k: int, dqa: np.ndarray | None = None) -> np.ndarray:
        R = matrix_from_quat_wxyz(self.quat[k])
        v = np.zeros(self.biped.model.nv)
        v[0:3] = R.T @ self.v_W[k]
        v[3:6] = self.w_B[k]
        v[self.biped.idx_v] = self.dqa[k] if dqa is None else dqa
        return v

    def run_of(self, k: int) -> tuple[int, int]:
        for a, b in self.runs:
            if a <= k < b:
                return a, b
        raise IndexError(k)


def _foot_kinematics(biped: Biped, data: pin.Data, st: "TrialStates", side: str, a: int,
                     b: int) -> dict:
    """Per row of [a, b): foot pitch ψ_c [rad], contact-point (material) velocity v_c [m/s]
    in W, its heading-frame components (v_h, v_l, v_z) and the unit heading (hx, hy)."""
    n = b - a
    lin, ang = np.zeros((n, 3)), np.zeros((n, 3))
    pos, rot = np.zeros((n, 3)), np.zeros((n, 3, 3))
    fid = biped.foot_frame[side]
    for k in range(n):                           # Pinocchio per row, the rest on the arrays
        pin.forwardKinematics(biped.model, data, st.q(a + k), st.v(a + k))
        oMf = pin.updateFramePlacement(biped.model, data, fid)
        vel = pin.getFrameVelocity(biped.model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        lin[k], ang[k] = vel.linear, vel.angular
        pos[k], rot[k] = oMf.translation, oMf.rotation
    pitch = foot_pitch_rows(rot)
    arm = contact_point_rows(biped, pos, rot) - pos
    hn = np.hypot(rot[:, 0, 0], rot[:, 1, 0])
    hn[hn == 0.0] = 1.0
    head = np.column_stack([rot[:, 0, 0] / hn, rot[:, 1, 0] / hn])
    vc = lin + np.cross(ang, arm)                # rows: the same products as one by one
    v_h = vc[:, 0] * head[:, 0] + vc[:, 1] * head[:, 1]
    v_l = -vc[:, 0] * head[:, 1] + vc[:, 1] * head[:, 0]
    return {"pitch": pitch, "vc_x": vc[:, 0], "vc_y": vc[:, 1], "vc_z": vc[:, 2],
            "v_h": v_h, "v_l": v_l, "heading_x": head[:, 0], "heading_y": head[:, 1]}


def _contact_points(biped: Biped, data: pin.Data, st: "TrialStates", side: str, a: int,
                    b: int) -> np.ndarray:
    """The foot's contact point (mean over patches) in W per row of [a, b) [m], (n, 3)."""
    out = np.empty((b - a, 3))
    for k in range(a, b):
        pin.framesForwardKinematics(biped.model, data, st.q(k))
        out[k - a] = patch_points(biped, data.oMf[biped.foot_frame[side]]).mean(axis=0)
    return out


def _stance_channels(st: "TrialStates", biped: Biped, data: pin.Data, side: str, r0: int,
                     b: int, surface_W: float, touchdown_xy: np.ndarray, smooth: int,
                     fs: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Stance-foot intrusion (smoothed) and its rate over rows [r0, b) [m, m/s], the
    vertical load [N] for the localisation features, and where they come from: the
    measured channels, else the foot's kinematic displacement since touchdown and the
    whole-body load estimate m (g + z̈_B)."""
    if st.has_intrusion:
        intr, dintr, src = st.intr_s[r0:b], st.dintr_s[r0:b], "measured"
    else:
        pts = _contact_points(biped, data, st, side, r0, b)
        intr = np.column_stack([pts[:, 0] - touchdown_xy[0], pts[:, 1] - touchdown_xy[1],
                                surface_W - pts[:, 2]])
        dintr = _savgol(intr, min(smooth, 9), deriv=1, delta=1.0 / fs)
        src = "kinematic"
    if st.has_force:
        load = st.grf_s[r0:b, 2].copy()
    else:
        mass = float(sum(i.mass for i in biped.model.inertias))
        acc = _savgol(st.p_raw, st.window, deriv=2, delta=st.dt)[r0:b, 2]
        load = mass * (9.81 + acc)
    return intr, dintr, load, src


def stance_windows(ds: Dataset, biped: Biped, *, contact_stiffness: float = 2.0e5,
                   smooth_window: int = 15, min_samples: int = 20,
                   touchdown_depth: float = 3e-3, segments: int = 1) -> list[StanceWindow]:
    """Every complete stance phase of ``ds`` as a :class:`StanceWindow`.

    A phase whose first samples show the stance foot at (almost) zero intrusion (median
    of the first three samples below ``touchdown_depth``) starts at its **touchdown**: the
    window starts one sample earlier, with that foot still above the sand; its joints'
    angles there (and their rates, when ``dq_*`` is not measured) and the trunk's angular
    velocity come from a fit to the samples *before* the impact
    (:meth:`TrialStates.past_fit`, :meth:`TrialStates.past_angular_velocity`), and its
    free surface from the mean of (contact-point height + measured intrusion) over the
    first samples of the phase. Otherwise (labels that start mid-stance) the window
    starts at the first sample with the foot buried at its measured intrusion. Without
    measured intrusion every phase starts at its touchdown (module docstring).

    Args:
        ds: the data set (only its measured channel groups are read).
        biped: the robot model of ``ds.meta.robot``.
        contact_stiffness: K per patch of the model terrain (the elastic displacement of a
            loaded foot is −F/(n K)) [N/m].
        smooth_window: Savitzky–Golay window [samples].
        min_samples: shorter stance runs are skipped (contact flicker).
        touchdown_depth: see above [m].
        segments: replay segments per stance: the replay restarts from the measured
            state ``segments − 1`` times, where that state is measured (:mod:`.restarts`).

    Raises:
        DataFormatError: the data set lacks a group a replay needs (:func:`check_replayable`).
    """
    check_replayable(ds)
    fs = ds.meta.sample_rate_hz
    data = biped.create_data()
    out: list[StanceWindow] = []
    J = list(ds.joint_names)
    scored = channel_names(J, ds.channels)
    refine = ds.stance_source == "kinematics"      # late label changes on sand
    for trial, df in ds.trials.items():
        st = TrialStates(biped, df, J, fs, smooth_window, channels=ds.channels,
                         refine_touchdowns=refine)
        speed = ds.commanded_speed(trial)
        phases, starts = st.phases, st.starts
        # each column read once per trial (the windows take row ranges of them)
        arrays = {c: df[c].to_numpy(dtype=float)
                  for c in dict.fromkeys([*scored, *format_columns(J)])
                  if c != STANCE and c in df.columns}
        for n_ph, ph in enumerate(phases):
            if not ph.complete or ph.n_rows < min_samples:
                continue
            # a phase ends where the next one starts (its kinematic touchdown)
            stop = (starts[n_ph + 1] if n_ph + 1 < len(phases)
                    and phases[n_ph + 1].row_start == ph.row_stop else ph.row_stop)
            out.append(_window(len(out), st, arrays, biped, data, ph._replace(trial=trial), J,
                               scored, float(speed),
                               contact_stiffness, smooth_window, touchdown_depth, fs,
                               starts[n_ph], stop, st.surface_rows[n_ph], segments))
    return out


def _window(index: int, st: TrialStates, arrays: dict, biped: Biped, data: pin.Data,
            ph, J: list, scored: list, speed: float, contact_stiffness: float,
            smooth_window: int, touchdown_depth: float, fs: float,
            start: int, stop: int, surface_row: int | None = None,
            segments: int = 1) -> StanceWindow:
    """One stance phase as a :class:`StanceWindow` (see :func:`stance_windows`), over the
    rows [start, stop) (the phase's rows, or its kinematic touchdown to the next one's);
    ``arrays``: the trial's columns as float arrays (the scored and the format's)."""
    a, b = start, stop
    a_label = ph.row_start
    side = ph.side
    i = SIDES.index(side)
    other = SIDES[1 - i]
    leg = [k for k, j in enumerate(J) if j.startswith(side + "_")]
    touchdown = (not st.has_intrusion
                 or float(np.median(st.intr[a:a + 3, 2])) < touchdown_depth)
    k0 = a - 1 if touchdown else a
    qa0, dqa0 = st.qa[k0].copy(), st.dqa[k0].copy()
    if touchdown and leg:
        # the swing leg decelerates hard before touchdown: angles from a fit to the
        # samples up to k0, rates as measured at k0 (no smoothing across the impact)
        qa0[leg], fit_rate = st.past_fit(k0, leg)
        dqa0[leg] = st.dqa_meas[k0, leg] if st.dqa_meas is not None else fit_rate
    q0 = st.q(k0, qa0)
    v0 = st.v(k0, dqa0)
    if touchdown:
        v0[3:6] = st.past_angular_velocity(k0)
    pin.framesForwardKinematics(biped.model, data, q0)
    c_W = patch_points(biped, data.oMf[biped.foot_frame[side]]).mean(axis=0)
    if touchdown and st.has_intrusion:
        m = min(SURFACE_SAMPLES, b - a)
        heights = []
        for k in range(a, a + m):
            pin.framesForwardKinematics(biped.model, data, st.q_raw(k))
            pts = patch_points(biped, data.oMf[biped.foot_frame[side]])
            heights.append(pts[:, 2].mean() + st.intr[k, 2])
        surface_W = float(np.mean(heights))
        pin.framesForwardKinematics(biped.model, data, q0)
    elif touchdown:
        # no intrusion: the contact point is on the surface at the first stance sample,
        # or (kinematic labels) at the refined touchdown / stop, averaged over 3 samples
        r_s = a if surface_row is None else surface_row
        heights = []
        for k in range(max(r_s - 1, 0), min(r_s + 2, st.n)) if surface_row is not None else (a,):
            pin.framesForwardKinematics(biped.model, data, st.q_raw(k))
            heights.append(patch_points(biped, data.oMf[biped.foot_frame[side]])[:, 2].mean())
        surface_W = float(np.mean(heights))
        pin.framesForwardKinematics(biped.model, data, q0)
    else:
        surface_W = float(c_W[2] + max(st.intr_s[a, 2], 0.0))
    origin = np.array([c_W[0], c_W[1], surface_W])
    lead_depth = surface_W - c_W[2]
    K = contact_stiffness
    if touchdown:
        lead = foot_init(biped, data, side, depth=lead_depth, intrusion=np.zeros(3),
                          force=np.zeros(3), in_contact=False, depth_max=0.0,
                          t_stance=0.0, K=K, origin=origin)
    else:
        lead = foot_init(biped, data, side, depth=lead_depth, intrusion=st.intr_s[a],
                          force=st.grf_s[a] if st.has_force else np.zeros(3), in_contact=True,
                          depth_max=float(st.intr_s[a, 2]), t_stance=0.0, K=K, origin=origin)
    # the trailing foot: in contact if the run before the phase was its stance
    if a_label > 0 and st.labels[a_label - 1] == other:
        pa, pb = st.run_of(a_label - 1)
        kt = min(a, pb) - 1                       # its last sample before the window
        force = st.grf_s[kt] if st.has_force else st.estimated_force(other, kt)
        if st.has_intrusion:
            # its deepest depth is its depth now: it carried the single-support load up to
            # this sample (the maximum of the noisy intrusion over the run is biased deep,
            # a spurious elastic rebound: docs/validation.md §2, "The trailing foot")
            trail = foot_init(biped, data, other, depth=float(st.intr_s[kt, 2]),
                               intrusion=st.intr_s[kt], force=force, in_contact=True,
                               depth_max=float(st.intr_s[kt, 2]),
                               t_stance=float(st.time[kt] - st.time[pa]), K=K,
                               origin=origin)
        else:
            # one flat surface through the leading foot's touchdown point; the trailing
            # foot at its kinematic depth below it, at its deepest point
            z_t = patch_points(biped, data.oMf[biped.foot_frame[other]])[:, 2].mean()
            depth = float(surface_W - z_t)
            trail = foot_init(biped, data, other, depth=depth, intrusion=np.zeros(3),
                               force=force, in_contact=depth > 0.0,
                               depth_max=max(depth, 0.0),
                               t_stance=float(st.time[kt] - st.time[pa]), K=K,
                               origin=origin)
    else:
        trail = foot_init(biped, data, other, depth=0.0, intrusion=np.zeros(3),
                           force=np.zeros(3), in_contact=False, depth_max=0.0,
                           t_stance=0.0, K=K, origin=origin)
    feet = [None, None]
    feet[i], feet[1 - i] = lead, trail
    q_loc = q0.copy()
    q_loc[0:3] -= origin
    r0 = k0 + 1                           # first predicted (scored) row
    t_ph = st.time[a:b]
    t = st.time[r0:b] - st.time[a]
    meas = {c: arrays[c][r0:b] for c in scored}
    kin = _foot_kinematics(biped, data, st, side, r0, b)
    intr, dintr, load, _ = _stance_channels(st, biped, data, side, r0, b, surface_W,
                                            c_W[:2], smooth_window, fs)
    pin.framesForwardKinematics(biped.model, data, q0)
    depth = intr[:, 2]
    feats = {
        "depth": depth.copy(),
        "sink_velocity": dintr[:, 2].copy(),
        "rise_from_deepest": np.maximum.accumulate(depth) - depth,
        "slip_velocity": np.hypot(dintr[:, 0], dintr[:, 1]),
        "sink_acceleration": _savgol(dintr[:, 2], smooth_window, 1, 1.0 / fs),
        "grf_z": load,
        "time_in_stance": t.copy(),
        "joint_speed": np.abs(st.dqa[r0:b]).mean(axis=1),
        "trunk_speed": np.linalg.norm(st.v_W[r0:b], axis=1),
        "x_position": st.p[r0:b, 0].copy(),
        **kin,
    }
    return StanceWindow(
        index=index, trial=ph.trial, speed=speed, side=side, foot=i,
        row_start=r0, row_stop=b, time=t,
        phase=100.0 * t / max(t_ph[-1] - t_ph[0], 1e-9),
        q0=q_loc, v0=v0, tau=st.tau[k0:b - 1].copy(), feet=tuple(feet), origin=origin,
        touchdown_W=np.array([c_W[0], c_W[1], surface_W]), meas=meas, features=feats,
        columns={c: arrays[c][r0:b] for c in format_columns(J) if c in arrays},
        restarts=stance_restarts(st, biped, data, side=side, k0=k0, stop=b, origin=origin,
                                 trail=trail, K=K, segments=segments,
                                 min_depth=touchdown_depth))


def windows_frame(windows: Sequence[StanceWindow], values: Sequence[dict] | None = None,
                  channels: Sequence[str] | None = None) -> pd.DataFrame:
    """Long table of windows: ``trial, commanded_speed_mps, stance_id, side, phase_pct,
    time`` and the channels (measured, or ``values[i]`` per window)."""
    frames = []
    for w in windows:
        src = w.meas if values is None else values[w.index]
        chans = list(channels or src.keys())
        block = {"trial": np.full(w.n, w.trial, dtype=object),
                 "commanded_speed_mps": np.full(w.n, w.speed),
                 "stance_id": np.full(w.n, w.index), "side": np.full(w.n, w.side, dtype=object),
                 "phase_pct": w.phase, "time": w.time}
        for c in chans:
            block[c] = np.asarray(src[c], dtype=float)
        frames.append(pd.DataFrame(block))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


__all__ = ["StanceWindow", "FootInit", "Restart", "TrialStates", "stance_windows", "windows_frame",
           "SURFACE_SAMPLES", "PAST_FIT_DEGREE",
           "channel_names", "channel_unit", "check_replayable", "patch_points", "foot_pitch",
           "AXES", "REPLAY_REQUIRED", "SCORED_GROUPS", "CHANNEL_UNITS"]
