"""Proposed joint-torque and torque-sensor terms from the joint equation error
(``docs/validation.md`` §3.6, "joint axis").

A joint effect or a torque-sensing error does not change the foot force the model
computes at the measured state, so the force proposal (:mod:`.proposal`) cannot see it.
It shows in the **joint torque equation error** at the measured state:

    e_j(t) = RNEA(q, q̇, q̈; measured foot force)_j − τ_meas,j(t)            [N·m]

— the torque the joints had beyond the measured one (Pinocchio's recursive Newton–Euler
on the floating base: base pose and twist from the data set's ``base_*`` columns, the
measured foot force applied at the stance sole's lowest arc point). q̈ (and the base's
twist rate) is a Savitzky–Golay derivative; τ and the foot force get the same smoothing,
so the two sides of the equation see the same time blur (a torque held between
controller ticks against a smoothed acceleration is a 1 N·m error otherwise). Rows near a
stance change are dropped: the impact, and the trailing foot still held by the sand after
the label moved to the other foot (no force is measured on it) — at least until its sole
is back above the height it touched down at, or — when the trial starts in its stance —
the height the other foot touched down at (:func:`footprint_exit`; without that fallback
the first change of every trial kept the trailing foot's rows in the sand, which took a
third of a 3 N·m/rad knee spring out of its fit).

Per joint, ``e_j`` is fitted with the sparse machinery of the force proposal
(:func:`.sparse.sparse_fit`: STLSQ, trial-grouped CV, stability selection over resampled
stances) on named features of that joint: ``const`` [N·m], ``q`` [rad], ``dq`` [rad/s],
``sign_dq`` (tanh(q̇/0.05 rad/s), Coulomb/stiction-like) and ``tau`` (the measured
torque: a torque-**sensor** gain, τ_meas = (1 + g)·τ ⇒ e = −g/(1+g)·τ_meas). Unpenalised
nuisance columns: the leg's stance flag and stance flag × vertical foot force (the
centre of pressure in the sole is not measured: a constant lever-arm error of it is a
torque ∝ F_z). Selected ``const``/``q``/``dq``/``sign_dq`` terms become a joint effect,
``tau`` terms a sensor effect on ``tau_*`` (:func:`joint_effect_source`), in the file of
the force proposal. Needs the trunk pose and twist (``base_*``): without them (no motion
capture) nothing is proposed on the joint axis and the note says so. An encoder offset
is not expressed by these features (it moves the posture RNEA is evaluated at).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np
import pinocchio as pin
from scipy.signal import savgol_filter

from ...columns import (BASE_ANGULAR_VELOCITY, BASE_LINEAR_VELOCITY, BASE_POSITION,
                        BASE_QUATERNION, FOOT_SIDES, GRF_COLUMNS, STANCE, joint_columns)
from ...robot.model import Biped
from ...rotations import matrix_from_quat_xyzw, xyzw_from_wxyz
from .held_torque import delayed, hold_delay
from .proposal_records import JointFit, JointTerm, change_text
from .sparse import SparseFit, sparse_fit

#: Savitzky–Golay window [s] and order of the derivative and of the matching smoothing
SMOOTH_WINDOW = 0.042
SMOOTH_ORDER = 3
#: rows dropped before / after every stance change [s] (impact; trailing foot in the sand)
SKIP_BEFORE = 0.024
SKIP_AFTER = 0.09
#: rows after a touchdown whose mean sole height is taken as the sand's surface there
TOUCHDOWN_ROWS = 3
#: fit the swing leg's rows only: on the stance leg the equation error carries a
#: systematic ≈ 1 N·m (the centre of pressure of the sole in the sand, not measured) that
#: on null data makes a false knee term (measured: const + q + τ terms on both knees)
SWING_ONLY = True
#: velocity scale of the ``sign_dq`` feature [rad/s]
SIGN_RATE = 0.05
#: a joint contributes terms when the stable refit removes this share of its held-out
#: equation error (and the per-fold selection half of it)
MIN_JOINT_REDUCTION = 0.15
#: ... and when the torque it explains, √(RMS_before² − RMS_after²), is at least this
#: [N·m]: on null data (three plant mismatches, seed 101; one without, seed 5) the swing
#: knees show a systematic const + q + q̇ error explaining 0.076–0.084 N·m with a held-out
#: reduction of 30–35 %, and the left-foot force bias (no joint effect) 0.076–0.080 N·m;
#: the joint and torque-sensor forms explain 0.135–0.98 N·m
MIN_EXPLAINED_RMS = 0.1
#: largest torque-sensor gain error |g| a ``tau`` term may imply (the bounds of the
#: measurement family's ``torque_gain``): e = −g/(1+g)·τ_meas, so a coefficient near −1
#: means the measured torque is not the joint's at all — on the benchmark's vertical
#: damping (15 N·s/m) the swing knee's torque fights the sand still holding the trailing
#: foot, c = −1.02, g = −62, which is no gain error (and no valid effect file)
MAX_SENSOR_GAIN = 0.5
#: fewest rows a joint fit needs
MIN_ROWS = 200
#: a joint of both legs (``left_<x>``, ``right_<x>``) is also fitted on both legs' rows
#: with one set of coefficients (the legs carry the same actuators and springs): that
#: fit is proposed instead of the two per-joint fits when it passes the rule and its
#: held-out error reduction is at most this much below theirs (pooled over the two
#: joints' rows). Half the coefficients on twice the rows: on the benchmark's knee spring
#: (1 N·m/rad about 1.4 rad, seed 1) the per-joint fits gave k = 1.21 and 0.21 N·m/rad,
#: the one fit of both knees k = 1.01 about 1.38 rad.
POOL_MARGIN = 0.05
#: the joint features: name, unit of the feature, whether a joint effect can write it
JOINT_FEATURES = (("const", "1", True), ("q", "rad", True), ("dq", "rad/s", True),
                  ("sign_dq", "1", True), ("tau", "N·m", False))
PROPOSED_JOINT = "proposed_joint"
PROPOSED_SENSOR = "proposed_torque_sensor"
#: bounds of a proposed parameter: this many times the proposed value
BOUND_FACTOR = 20.0
#: the one magnitude of an emitted effect: it scales the fitted shape (0 switches the
#: effect off). One regression column per proposal, not one per fitted coefficient: with
#: a column per coefficient (10–15 of them) the replay screening overfits and the
#: proposal ranked last on every joint form of the benchmark (measured)
SCALE_PARAM = ("    'scale': Param(1.0, 0.0, 3.0, '-', 'scale of the proposed {what} "
               "(1: as fitted from the equation error; 0: off)', physical=(0.0, 3.0)),")

JOINT_NOTE = ("joint torque equation error at the measured state (RNEA on the floating "
              "base with the measured foot force, minus the measured torque; rows near "
              "stance changes and until the trailing foot has left its footprint dropped; "
              "the swing leg's rows only), fitted per joint on "
              "const, q, q̇, tanh(q̇/0.05), τ by the force proposal's STLSQ + "
              "trial-grouped CV + stability selection.")


@dataclass(frozen=True, eq=False)
class JointSamples:
    """The joint equation-error rows of a data set.

    Attributes:
        error: (N, J) RNEA torque − measured torque [N·m] (the torque the joints lacked).
        q, dq, tau: (N, J) smoothed joint angle [rad], rate [rad/s], measured torque [N·m].
        stance_leg: (N, J) 1 where the joint's leg is in stance.
        grf_z: (N,) smoothed vertical foot force of the stance foot [N].
        trial, unit: per row, its trial and its stance segment (resampling unit).
        torque_delay: the delay d [s] of the torque acting at a row behind its logged
            value: ``error`` and ``tau`` are at τ(t − d) (:mod:`.held_torque`; 0: τ(t)).
    """

    error: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    stance_leg: np.ndarray
    grf_z: np.ndarray
    trial: np.ndarray
    unit: np.ndarray
    torque_delay: float = 0.0

    @property
    def n(self) -> int:
        return int(self.trial.size)


def _window(rate_hz: float) -> int:
    n = max(int(round(SMOOTH_WINDOW * rate_hz)) | 1, SMOOTH_ORDER + 2 | 1)
    return n


def trial_equation_error(df, biped: Biped, rate_hz: float) -> dict[str, np.ndarray]:
    """RNEA torque − measured torque on every row of one trial (no rows dropped).

    Returns:
        ``error``, ``q``, ``dq``, ``tau`` (rows, J), ``grf`` (rows, 3) smoothed, ``stance``.
    """
    J = biped.joint_names
    m = biped.model
    data = m.createData()
    n = len(df)
    win = min(_window(rate_hz), n - (1 - n % 2))
    dt = 1.0 / rate_hz
    qa = df[joint_columns(J, "q")].to_numpy(float)
    tau = df[joint_columns(J, "tau")].to_numpy(float)
    quat = np.asarray(xyzw_from_wxyz(df[list(BASE_QUATERNION)].to_numpy(float)))
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    p = df[list(BASE_POSITION)].to_numpy(float)
    v_w = df[list(BASE_LINEAR_VELOCITY)].to_numpy(float)
    V = np.zeros((n, m.nv))
    Q = np.zeros((n, m.nq))
    for k in range(n):
        Q[k] = biped.q_from_parts(p[k], quat[k], qa[k])
        V[k, 0:3] = matrix_from_quat_xyzw(quat[k]).T @ v_w[k]
    V[:, 3:6] = df[list(BASE_ANGULAR_VELOCITY)].to_numpy(float)
    V[:, biped.idx_v] = df[joint_columns(J, "dq")].to_numpy(float)
    smooth = dict(window_length=win, polyorder=SMOOTH_ORDER, axis=0)
    A = savgol_filter(V, deriv=1, delta=dt, **smooth)
    Vs = savgol_filter(V, **smooth)
    Qs_a = savgol_filter(qa, **smooth)
    tau_s = savgol_filter(tau, **smooth)
    grf = savgol_filter(df[list(GRF_COLUMNS)].to_numpy(float), **smooth)
    stance = df[STANCE].astype(str).to_numpy()
    radius = float(biped.config.foot.radius)
    err = np.zeros((n, len(J)))
    sole_z = np.zeros((n, len(FOOT_SIDES)))
    grf_rows = grf.tolist()
    zero = [pin.Force.Zero() for _ in range(m.njoints)]
    frames = [biped.foot_frame[side] for side in FOOT_SIDES]
    for k in range(n):
        fext = pin.StdVec_Force()
        for f in zero:
            fext.append(f)
        side = stance[k]
        pin.forwardKinematics(m, data, Q[k])
        for i, fid in enumerate(frames):
            sole_z[k, i] = pin.updateFramePlacement(m, data, fid).translation[2] - radius
        if side in biped.foot_frame:
            fid, jid = biped.foot_frame[side], biped.foot_joint[side]
            a0, a1, _ = data.oMf[fid].translation
            a2 = sole_z[k, FOOT_SIDES.index(side)]
            b0, b1, b2 = grf_rows[k]
            # pt × grf, the same operations as np.cross (a fraction of its cost per row)
            moment = np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
            fext[jid] = data.oMi[jid].actInv(pin.Force(grf[k], moment))
        err[k] = pin.rnea(m, data, Q[k], Vs[k], A[k], fext)[biped.idx_v] - tau_s[k]
    return {"error": err, "q": Qs_a, "dq": Vs[:, biped.idx_v], "tau": tau_s, "grf": grf,
            "stance": stance, "sole_z": sole_z}


def footprint_exit(stance: np.ndarray, sole_z: np.ndarray, change: int) -> int | None:
    """The first row at or after the stance change at row ``change`` at which the trailing
    foot (the one whose stance ended there) has left its footprint: its sole's lowest point
    above the height it had at its own touchdown (the sand's surface there).

    When that foot's touchdown is not in the trial (the trial starts in its stance), the
    surface is the height the leading foot touched down at, at ``change`` — the sand a
    step away. Returns None for a change from ``"none"``; the next stance change (or the
    trial's end) when the foot has not left by then.
    """
    trailing, leading = str(stance[change - 1]), str(stance[change])
    if trailing not in FOOT_SIDES:
        return None
    changes = np.flatnonzero(stance[1:change] != stance[:change - 1]) + 1
    touchdowns = changes[stance[changes] == trailing]
    f = FOOT_SIDES.index(trailing)
    if touchdowns.size:
        td, g = int(touchdowns[-1]), f
    elif leading in FOOT_SIDES:
        td, g = change, FOOT_SIDES.index(leading)
    else:
        return None
    surface = float(np.mean(sole_z[td:td + TOUCHDOWN_ROWS, g]))
    later = np.flatnonzero(stance[change + 1:] != stance[change:-1])
    end = change + 1 + int(later[0]) if later.size else stance.size
    out = np.flatnonzero(sole_z[change:end, f] > surface)
    return change + int(out[0]) if out.size else end


def kept_rows(stance: np.ndarray, rate_hz: float, sole_z: np.ndarray | None = None
              ) -> np.ndarray:
    """Rows away from every stance change (and from the trial's ends).

    With ``sole_z`` ((rows, 2) lowest sole point of each foot [m], :data:`FOOT_SIDES`
    order) the rows after a change are dropped at least until the trailing foot has left
    its footprint (:func:`footprint_exit`) and half a smoothing window more: the sand holds
    it, with no force measured on it, for ≈ 80 ms on the model's own gait but longer when
    an effect changes the gait (112 ms with a 3 N·m/rad knee spring, measured)."""
    n = stance.size
    ok = np.ones(n, bool)
    before, after = int(round(SKIP_BEFORE * rate_hz)), int(round(SKIP_AFTER * rate_hz))
    blur = int(round(0.5 * SMOOTH_WINDOW * rate_hz))
    for i in np.flatnonzero(stance[1:] != stance[:-1]) + 1:
        stop = i + after
        if sole_z is not None:
            out = footprint_exit(stance, sole_z, int(i))
            stop = max(stop, out + blur) if out is not None else stop
        ok[max(0, i - before):stop] = False
    ok[:after] = False
    ok[max(0, n - after):] = False
    return ok & (stance != "none")


def joint_samples(trials, biped: Biped, rate_hz: float, *, torque_delay: float = 0.0
                  ) -> JointSamples:
    """The equation-error rows of every trial (``trials``: name → DataFrame).

    ``torque_delay`` [s]: the torque acting at a row's stamp is the logged τ(t − delay)
    (half the hold of a held command, :func:`.held_torque.hold_delay`); the error and the
    ``tau`` feature use it."""
    J = biped.joint_names
    leg = np.array(["left" if j.startswith("left") else "right" for j in J])
    parts: dict[str, list] = {k: [] for k in ("error", "q", "dq", "tau", "st", "fz", "trial", "unit")}
    for name, df in trials.items():
        r = trial_equation_error(df, biped, rate_hz)
        ok = kept_rows(r["stance"], rate_hz, r["sole_z"])
        if torque_delay != 0.0:
            tau = delayed(r["tau"], rate_hz, torque_delay)
            r = {**r, "error": r["error"] + r["tau"] - tau, "tau": tau}
        seg = np.cumsum(np.r_[0, r["stance"][1:] != r["stance"][:-1]])
        for k in ("error", "q", "dq", "tau"):
            parts[k].append(r[k][ok])
        parts["st"].append((r["stance"][ok][:, None] == leg[None, :]).astype(float))
        parts["fz"].append(r["grf"][ok, 2])
        parts["trial"].append(np.full(int(ok.sum()), str(name)))
        parts["unit"].append(np.array([f"{name}|{s}" for s in seg[ok]]))
    cat = {k: (np.concatenate(v) if v else np.zeros((0, len(J)))) for k, v in parts.items()}
    return JointSamples(cat["error"], cat["q"], cat["dq"], cat["tau"], cat["st"],
                        cat["fz"], cat["trial"], cat["unit"], torque_delay)


def feature_matrix(s: JointSamples, j: int) -> np.ndarray:
    """(N, 5) features of joint ``j`` in :data:`JOINT_FEATURES` order."""
    return np.column_stack([np.ones(s.n), s.q[:, j], s.dq[:, j],
                            np.tanh(s.dq[:, j] / SIGN_RATE), s.tau[:, j]])


def nuisance_matrix(s: JointSamples, j: int) -> np.ndarray:
    """(N, 2) unpenalised columns of joint ``j``: stance flag, stance flag × F_z."""
    return np.column_stack([s.stance_leg[:, j], s.stance_leg[:, j] * s.grf_z])


def sensor_gain(c: float) -> float:
    """The torque-sensor gain error g a ``tau`` coefficient c means: τ_meas = (1 + g)·τ
    gives e = −g/(1+g)·τ_meas, so g = −c/(1 + c) (∞ at c ≤ −1)."""
    return -c / (1.0 + c) if c > -1.0 else float("inf")


def joint_passes(heldout_reduction: float, heldout_reduction_selected: float,
                 rms_before: float, rms_after: float, tau_coefficient: float | None = None
                 ) -> bool:
    """The evidence rule of one joint: the stable refit removes ≥ :data:`MIN_JOINT_REDUCTION`
    of the held-out equation error (the per-fold selection half of that), the torque it
    explains is ≥ :data:`MIN_EXPLAINED_RMS` [N·m], and a selected ``tau`` term
    (``tau_coefficient``) means a gain error |g| ≤ :data:`MAX_SENSOR_GAIN`."""
    explained = float(np.sqrt(max(rms_before ** 2 - rms_after ** 2, 0.0)))
    gain_ok = tau_coefficient is None or abs(sensor_gain(tau_coefficient)) <= MAX_SENSOR_GAIN
    return bool(heldout_reduction_selected >= MIN_JOINT_REDUCTION
                and heldout_reduction >= 0.5 * MIN_JOINT_REDUCTION
                and explained >= MIN_EXPLAINED_RMS and gain_ok)


def leg_pairs(joint_names: Sequence[str]) -> list[tuple[int, int]]:
    """The (left, right) indices of each joint both legs have (``left_<x>``, ``right_<x>``)."""
    names = list(joint_names)
    return [(j, names.index("right_" + n[5:])) for j, n in enumerate(names)
            if n.startswith("left_") and "right_" + n[5:] in names]


class _GroupFit(NamedTuple):
    """One sparse fit of some joints' equation error (one set of coefficients)."""

    fit: SparseFit
    passes: bool        # the evidence rule (:func:`joint_passes`) and a term selected
    rows: int


def _fit_joints(s: JointSamples, js: Sequence[int], seed: int) -> _GroupFit:
    """One sparse fit of the equation error of the joints ``js`` stacked (one set of
    coefficients)."""
    parts = []
    for j in js:
        rows = s.stance_leg[:, j] == 0.0 if SWING_ONLY else np.ones(s.n, bool)
        nuis = nuisance_matrix(s, j)[rows]
        parts.append((feature_matrix(s, j)[rows], nuis[:, :0] if SWING_ONLY else nuis,
                      s.error[rows, j], s.trial[rows],
                      # a resampling unit is one stance of one joint (one joint: its
                      # stances, named as they are)
                      np.char.add(s.unit[rows].astype(str), f"|{j}") if len(js) > 1
                      else s.unit[rows]))
    X, N, y, trial, unit = (np.concatenate([p[i] for p in parts]) for i in range(5))
    fit = sparse_fit(X, N, y, trial, unit, seed=seed)
    tau_k = [f[0] for f in JOINT_FEATURES].index("tau")
    ok = joint_passes(fit.heldout_reduction, fit.heldout_reduction_selected,
                      fit.rmse_before, fit.rmse_after,
                      float(fit.coef[tau_k]) if fit.selected[tau_k] else None) \
        and bool(fit.selected.any())
    return _GroupFit(fit, ok, y.size)


def _pooled_reduction(own: Sequence[_GroupFit]) -> float:
    """The held-out reduction of per-joint fits over their rows together (each joint's
    share weighted by its rows × its error's mean square)."""
    w = np.array([g.rows * g.fit.rmse_before ** 2 for g in own])
    h = np.array([g.fit.heldout_reduction_selected for g in own])
    return float(np.sum(w * h) / np.sum(w)) if np.sum(w) > 0 else 0.0


def fit_joint_terms(s: JointSamples, joint_names: Sequence[str], *, seed: int = 0
                    ) -> tuple[tuple[JointTerm, ...], tuple[JointFit, ...]]:
    """Sparse fit of every joint's equation error (:func:`.sparse.sparse_fit`): per joint,
    and for a joint of both legs also both legs in one fit (:data:`POOL_MARGIN`)."""
    if s.n < MIN_ROWS:
        return (), ()
    single = {j: _fit_joints(s, [j], seed) for j in range(len(joint_names))}
    groups: list[tuple[tuple[int, ...], _GroupFit]] = []
    paired = set()
    for pair in leg_pairs(joint_names):
        pooled = _fit_joints(s, pair, seed)
        if pooled.passes and pooled.fit.heldout_reduction_selected >= _pooled_reduction(
                [single[j] for j in pair]) - POOL_MARGIN:
            groups.append((pair, pooled))
            paired.update(pair)
    groups += [((j,), single[j]) for j in range(len(joint_names)) if j not in paired]
    terms: list[JointTerm] = []
    fits: list[JointFit] = []
    for js, (fit, ok, _) in groups:
        for j in js:
            fits.append(JointFit(joint_names[j], fit.heldout_reduction,
                                 fit.heldout_reduction_selected, fit.rmse_before,
                                 fit.rmse_after, ok, len(js) > 1))
            if not ok:
                continue
            for k in np.flatnonzero(fit.selected):
                feat, unit, _ = JOINT_FEATURES[k]
                cu = "-" if feat == "tau" else ("N·m" if unit == "1" else f"N·m/({unit})")
                terms.append(JointTerm(joint_names[j], feat, float(fit.coef[k]),
                                       float(fit.stderr[k]), cu, float(fit.frequency[k])))
    order = {n: i for i, n in enumerate(joint_names)}
    return (tuple(sorted(terms, key=lambda t: order[t.joint])),
            tuple(sorted(fits, key=lambda f: order[f.joint])))


#: the data groups the joint equation error needs (RNEA on the measured trunk motion)
EQUATION_GROUPS = ("trunk_position", "trunk_orientation", "trunk_linear_velocity",
                   "trunk_angular_velocity", "joint_torques", "foot_force")


def missing_groups(dataset) -> list[str]:
    """The groups of :data:`EQUATION_GROUPS` the data set does not measure."""
    return [g for g in EQUATION_GROUPS if not dataset.has(g)]


def equation_rows(dataset, biped: Biped, rate_hz: float) -> JointSamples | None:
    """The joint equation-error rows of a data set, the torques at the delay its held
    commands imply (:func:`.held_torque.hold_delay`); None when it does not measure every
    group of :data:`EQUATION_GROUPS`."""
    if missing_groups(dataset):
        return None
    return joint_samples(dataset.trials, biped, rate_hz,
                         torque_delay=hold_delay(dataset.meta.torque_hold_s))


def propose_joint_terms(dataset, biped: Biped, rate_hz: float, *, seed: int = 0,
                        rows: JointSamples | None = None
                        ) -> tuple[tuple[JointTerm, ...], tuple[JointFit, ...], str]:
    """The joint-axis proposal of a data set: (terms, per-joint fits, note).

    Nothing is proposed without the trunk pose and twist (``base_*``) or the joint torques.
    ``rows``: the data set's :func:`equation_rows`, if the caller has them (None: computed).
    """
    missing = missing_groups(dataset)
    if missing:
        return (), (), ("joint proposal not available: the data set does not measure "
                        + ", ".join(missing) + " (RNEA needs the measured trunk motion)")
    hold = dataset.meta.torque_hold_s
    s = rows if rows is not None else equation_rows(dataset, biped, rate_hz)
    terms, fits = fit_joint_terms(s, biped.joint_names, seed=seed)
    held = (f" The torques are commands held {1e3 * hold:g} ms (meta.yaml torque_hold_s): "
            f"τ(t − {1e3 * s.torque_delay:g} ms) acts at t." if hold else
            " The torques act at their stamps (meta.yaml declares no torque hold).")
    return terms, fits, JOINT_NOTE + f" {s.n} rows." + held


def joint_torque(terms: Sequence[JointTerm], joint_names: Sequence[str], q_a: np.ndarray,
                 dq_a: np.ndarray) -> np.ndarray:
    """The proposed joint torque [N·m] (actuator order) at ``q_a``, ``dq_a``: what the
    emitted ``proposed_joint`` effect returns (``tau`` terms are sensor terms: skipped)."""
    out = np.zeros(len(joint_names))
    for t in terms:
        j = list(joint_names).index(t.joint)
        out[j] += t.coefficient * {"const": 1.0, "q": q_a[j], "dq": dq_a[j],
                                   "sign_dq": np.tanh(dq_a[j] / SIGN_RATE)}.get(t.feature, 0.0)
    return out


def _pname(t: JointTerm) -> str:
    return f"{t.joint}_{t.feature}"


def _bounds(c: float) -> tuple[float, float, float, float]:
    b = BOUND_FACTOR * abs(c) if c != 0 else 1.0
    return -b, b, (0.0 if c > 0 else -b), (b if c > 0 else 0.0)


def joint_effect_source(terms: Sequence[JointTerm], fits: Sequence[JointFit],
                        joint_names: Sequence[str], effects: Sequence[str] | None = None,
                        data: str = "") -> str:
    """The joint and torque-sensor proposal as plugin-format source (empty when nothing
    is proposed).

    Args:
        effects: emit only these of :data:`PROPOSED_JOINT` / :data:`PROPOSED_SENSOR`
            (None: both, to be appended to the force proposal's source); with one name the
            source is a file of its own (a module docstring first).
        data: the data set's name, for that docstring.
    """
    keep = set(joint_effect_names(terms) if effects is None else effects)
    jt = [t for t in terms if t.feature != "tau"] if PROPOSED_JOINT in keep else []
    st = [t for t in terms if t.feature == "tau"] if PROPOSED_SENSOR in keep else []
    terms = jt + st
    if not terms:
        return ""
    lines = ["", "", "# --- joint axis: " + JOINT_NOTE]
    if effects is not None:
        name = PROPOSED_JOINT if jt else PROPOSED_SENSOR
        what = "a joint torque" if jt else "a torque-sensor gain error"
        lines = ['"""A term proposed by `granular-mpc diagnose`' + (f" for {data}" if data else "")
                 + f": `{name}`, {what}.", "",
                 "A hypothesis, never added by the diagnosis that proposed it: pass this file",
                 f"back alone with --effect-file {name}.py to have it refitted on the replays",
                 "and judged like any candidate.", '"""', "", "# " + JOINT_NOTE]
    for f in fits:
        lines.append(f"#   {f.joint}{' (one fit of both legs)' if f.both_legs else ''}: "
                     "held-out error "
                     f"{change_text(f.heldout_error_reduction_selected)} "
                     f"(per fold {change_text(f.heldout_error_reduction)}), RMS "
                     f"{f.rms_before:.3f} → {f.rms_after:.3f} N·m" + ("" if f.proposed else
                                                                     "  [not proposed]"))
    for t in terms:
        lines.append(f"#   {_pname(t)}: {t.coefficient:.4g} ± {t.std_error:.2g} {t.unit}, "
                     f"selected in {100 * t.selection_frequency:.0f} % of the resamples")
    lines += ["", "from granular_mpc.effects import Param, register_joint_effect, register_sensor_effect",
              "import numpy as np", "", f"JOINTS = {tuple(joint_names)!r}"]
    if jt:
        lines += ["", f"@register_joint_effect({PROPOSED_JOINT!r}, replace=True, params={{"]
        for t in jt:
            lo, hi, plo, phi = _bounds(t.coefficient)
            doc = f"proposed {t.feature} torque of {t.joint}"
            lines.append(f"    {_pname(t)!r}: Param({t.coefficient:.6g}, {lo:.6g}, {hi:.6g}, "
                         f"{t.unit!r}, {doc!r}, physical=({plo:.6g}, {phi:.6g})),")
        lines += [SCALE_PARAM.format(what="torque"),
                  f"}}, main='scale', neutral={{'scale': 0.0}})",
                  f"def {PROPOSED_JOINT}(q_a, dq_a, p):",
                  '    """The proposed torque added to the actuators [N·m], actuator order."""',
                  "    tau = np.zeros_like(dq_a)"]
        expr = {"const": "1.0", "q": "q_a[j]", "dq": "dq_a[j]",
                "sign_dq": f"np.tanh(dq_a[j] / {SIGN_RATE})"}
        for t in jt:
            lines += [f"    j = JOINTS.index({t.joint!r})",
                      f"    tau[j] = tau[j] + p[{_pname(t)!r}] * {expr[t.feature]}"]
        lines.append("    return p['scale'] * tau")
    if st:
        # e = −g/(1+g)·τ_meas ⇒ the sensor reads (1 + g)·τ with g = −c/(1 + c)
        lines += ["", f"@register_sensor_effect({PROPOSED_SENSOR!r}, replace=True, params={{"]
        for t in st:
            g = sensor_gain(t.coefficient)
            lo, hi, plo, phi = _bounds(g)
            doc = f"proposed torque-sensor gain error of {t.joint}: tau reads (1 + g)·τ"
            lines.append(f"    {'gain_' + t.joint!r}: Param({g:.6g}, {max(lo, -0.9):.6g}, "
                         f"{hi:.6g}, '-', {doc!r}, physical=({max(plo, -0.9):.6g}, {phi:.6g})),")
        lines += [SCALE_PARAM.format(what="gain errors"),
                  f"}}, main='scale', neutral={{'scale': 0.0}})",
                  f"def {PROPOSED_SENSOR}(cols, p, ctx):",
                  '    """Measured torque = (1 + scale·g_j)·true torque on the proposed joints."""',
                  "    return {f'tau_{j}': (1.0 + p['scale'] * p['gain_' + j])",
                  "            * np.asarray(cols[f'tau_{j}'], float)",
                  "            for j in JOINTS if 'gain_' + j in p and f'tau_{j}' in cols}"]
    return "\n".join(lines) + "\n"


def joint_report_lines(terms: Sequence[JointTerm], fits: Sequence[JointFit],
                       note: str = "") -> list[str]:
    """The report's lines on the joint-axis proposal (empty when it was not fitted)."""
    if not fits:
        return [f"* joint axis: {note}"] if note else []
    lines = ["", "### Joint axis (proposed from the joint-torque equation error)", ""]
    lines += [f"* {f.joint}{' (one fit of both legs)' if f.both_legs else ''}: held-out "
              f"equation error {change_text(f.heldout_error_reduction_selected)} "
              f"(selection redone per fold {change_text(f.heldout_error_reduction)}), RMS "
              f"{f.rms_before:.3f} → {f.rms_after:.3f} N·m"
              + ("" if f.proposed else " — nothing proposed") for f in fits]
    if terms:
        lines += ["", "| joint | feature | coefficient | selected in | effect |", "|---|---|---|---|---|"]
        lines += [f"| {t.joint} | {t.feature} | {t.coefficient:.4g} ± {t.std_error:.2g} {t.unit} | "
                  f"{100 * t.selection_frequency:.0f} % | "
                  f"{PROPOSED_SENSOR if t.feature == 'tau' else PROPOSED_JOINT} |" for t in terms]
    return lines


def joint_effect_names(terms: Sequence[JointTerm]) -> tuple[str, ...]:
    """The effects :func:`joint_effect_source` registers for ``terms``."""
    out = []
    if any(t.feature != "tau" for t in terms):
        out.append(PROPOSED_JOINT)
    if any(t.feature == "tau" for t in terms):
        out.append(PROPOSED_SENSOR)
    return tuple(out)


__all__ = ["JointSamples", "joint_samples", "trial_equation_error", "kept_rows", "footprint_exit",
           "feature_matrix", "nuisance_matrix", "fit_joint_terms", "propose_joint_terms",
           "equation_rows", "missing_groups", "EQUATION_GROUPS",
           "joint_torque", "joint_effect_source", "joint_effect_names", "joint_report_lines",
           "JOINT_FEATURES", "PROPOSED_JOINT", "PROPOSED_SENSOR", "MIN_JOINT_REDUCTION",
           "MIN_EXPLAINED_RMS", "JOINT_NOTE", "joint_passes", "sensor_gain", "MAX_SENSOR_GAIN",
           "leg_pairs", "POOL_MARGIN"]
