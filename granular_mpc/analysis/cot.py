"""Cost of transport (CoT) of a walking run, whole-run and accumulated over a stance.

The paper's definition (Sec. III-A)::

    CoT = E / (W_r d),   E = ∫_{t0}^{tf} ‖τ_aᵀ(t) q̇_a(t)‖ dt,   d = ∫_{t0}^{tf} v_CoM,x(t) dt

with τ_a [N·m] and q̇_a [rad/s] the six actuator torques and rates, W_r = m g [N] the
robot's weight and v_CoM,x [m/s] the forward (world x) velocity of the whole-body centre
of mass. Integrals are trapezoidal over the logged samples.

**Readings of E.** ‖τ_aᵀ q̇_a‖ is the norm of a scalar, so the paper's E is ambiguous. The
three readings (:data:`COT_READINGS`, each a power mode of :func:`mechanical_power`):

* ``"abs_per_joint"`` (**default reading**, mode ``"abs_joint"``): P = Σ_i |τ_i q̇_i|, each
  motor's absolute mechanical power. The paper's robot is motor-driven (torques measured
  from motor current): a motor draws current, and dissipates energy, whether it does
  positive or negative work, and one joint's braking cannot power another joint (no
  energy transfer between the hip and knee drives). Under the literal reading hip and knee
  powers of opposite sign cancel and the CoT can be near zero while both motors work hard.
* ``"abs_net"`` (mode ``"abs"``): P = |Σ_i τ_i q̇_i|, the literal reading (absolute value of
  the net actuator power); what :func:`cot_from_log` and friends compute by default, kept
  for compatibility.
* ``"positive"`` (mode ``"positive_joint"``): P = Σ_i max(τ_i q̇_i, 0), positive work of
  each joint (negative work free, as with an ideal per-joint brake).

Pointwise |Σ p_i| ≤ Σ |p_i| and Σ max(p_i, 0) ≤ Σ |p_i|, so CoT_abs_net ≤ CoT_abs_per_joint
and CoT_positive ≤ CoT_abs_per_joint; and Σ |p_i| = 2 Σ max(p_i, 0) − Σ p_i, so
E_abs_per_joint = 2 E_positive − W_net exactly (W_net = ∫ Σ τ_i q̇_i dt, the net actuator
work), for any signals and also for the trapezoidal sums. ``abs_net`` and ``positive`` are
not ordered. :func:`cot_readings_from_log` returns all three at once.

One further power mode is not a reading of the paper: mode ``"positive"``,
max(Σ_i τ_i q̇_i, 0), positive *net* work (perfect regeneration across joints and time) —
not to be confused with the reading ``"positive"`` (mode ``"positive_joint"``).

The decoupled sagittal + frontal CoT lives in :mod:`granular_mpc.analysis.cot_decoupled`.

**Cumulative CoT over a stance** (paper Fig. 6c), for t in a stance [t_s, t_e]::

    E(t) = ∫_{t_s}^{t} P dt',   d(t) = ∫_{t_s}^{t} v_CoM,x dt'
    "running":  CoT_cum(t) = E(t) / (W_r d(t))      (NaN while d(t) < f_min d(t_e))
    "final":    CoT_cum(t) = E(t) / (W_r d(t_e))

Both end at the whole-stance CoT at t = t_e. ``"running"`` normalises by the distance
covered so far (the energy per unit weight and distance *up to now*); ``"final"`` by the
stance's full distance (so the curve grows from 0, like the paper's Fig. 6c, whose CoT
"ramps up nearly linearly" and "jumps at pull-out").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pandas as pd
from scipy.integrate import cumulative_trapezoid, trapezoid

from .metrics import PHASE_COL, ID_COL, contact_segments
from .stances import SOURCE_COL, table_source

POWER_MODES = ("abs", "positive", "abs_joint", "positive_joint")
STANDARD_GRAVITY = 9.81
COT_READINGS = ("abs_per_joint", "abs_net", "positive")
"""Readings of the paper's E = ∫‖τ_aᵀ q̇_a‖ dt (module docstring)."""
DEFAULT_COT_READING = "abs_per_joint"
"""The reading this package recommends (module docstring: motors pay for negative work)."""
READING_POWER_MODES = {"abs_per_joint": "abs_joint", "abs_net": "abs",
                       "positive": "positive_joint"}
"""Power mode of :func:`mechanical_power` for each reading."""


def reading_mode(reading: str) -> str:
    """The :func:`mechanical_power` mode of a CoT reading (``"abs_per_joint"`` →
    ``"abs_joint"``, ``"abs_net"`` → ``"abs"``, ``"positive"`` → ``"positive_joint"``)."""
    try:
        return READING_POWER_MODES[reading]
    except KeyError:
        raise ValueError(f"reading must be one of {COT_READINGS}, got {reading!r}") from None


@dataclass(frozen=True)
class CotResult:
    """Cost of transport of one time window.

    Attributes:
        cot: E / (W_r d) [-]; NaN if d <= 0 (no forward progress: CoT undefined).
        energy_J: E [J].
        distance_m: d, forward CoM distance [m].
        weight_N: W_r [N].
        duration_s: t_f − t_0 [s].
        mode: the power mode used (see :func:`mechanical_power`).
    """

    cot: float
    energy_J: float
    distance_m: float
    weight_N: float
    duration_s: float
    mode: str


def mechanical_power(tau: np.ndarray, dq: np.ndarray, mode: str = "abs") -> np.ndarray:
    """Actuator power counted by the CoT [W], one value per sample.

    Args:
        tau: actuator torques [N·m], shape (n,) or (n, n_joints).
        dq: actuator rates [rad/s], same shape.
        mode: ``"abs"`` |Σ τ_i q̇_i| (reading ``abs_net``, the literal one),
            ``"abs_joint"`` Σ |τ_i q̇_i| (reading ``abs_per_joint``, the default reading),
            ``"positive_joint"`` Σ max(τ_i q̇_i, 0) (reading ``positive``), ``"positive"``
            max(Σ τ_i q̇_i, 0) (net positive work). :func:`reading_mode` maps readings to
            modes.
    """
    tau = np.asarray(tau, dtype=float)
    dq = np.asarray(dq, dtype=float)
    if tau.shape != dq.shape:
        raise ValueError(f"tau {tau.shape} and dq {dq.shape} must have the same shape")
    return combine_joint_powers(tau * dq, mode)


def combine_joint_powers(p: np.ndarray, mode: str = "abs") -> np.ndarray:
    """Counted power [W] per sample from per-joint powers p_i = τ_i q̇_i [W].

    Args:
        p: per-joint powers, shape (n,) (one joint) or (n, n_joints).
        mode: as :func:`mechanical_power`.
    """
    if mode not in POWER_MODES:
        raise ValueError(f"mode must be one of {POWER_MODES}, got {mode!r}")
    p = np.asarray(p, dtype=float)
    if p.ndim == 1:
        p = p[:, None]
    if mode == "abs":
        return np.abs(p.sum(axis=1))
    if mode == "positive":
        return np.maximum(p.sum(axis=1), 0.0)
    if mode == "abs_joint":
        return np.abs(p).sum(axis=1)
    return np.maximum(p, 0.0).sum(axis=1)


def _check_time(time: np.ndarray) -> np.ndarray:
    t = np.asarray(time, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError("time must be a 1-D array with at least two samples")
    if not np.all(np.diff(t) > 0):
        raise ValueError("time must be strictly increasing")
    return t


def _check_weight(weight: float) -> float:
    w = float(weight)
    if not np.isfinite(w) or w <= 0:
        raise ValueError(f"weight must be a positive force in N, got {weight!r}")
    return w


def cot_from_arrays(time: np.ndarray, tau: np.ndarray, dq: np.ndarray, v_com_x: np.ndarray,
                    weight: float, *, mode: str = "abs") -> CotResult:
    """CoT = E / (W_r d) from sampled signals (trapezoidal integration).

    Args:
        time: sample times [s], strictly increasing, shape (n,).
        tau: actuator torques [N·m], (n,) or (n, n_joints).
        dq: actuator rates [rad/s], same shape as ``tau``.
        v_com_x: forward CoM velocity in W [m/s], shape (n,).
        weight: W_r = m g [N].
        mode: power mode, see :func:`mechanical_power`.
    """
    t = _check_time(time)
    w = _check_weight(weight)
    p = mechanical_power(tau, dq, mode)
    v = np.asarray(v_com_x, dtype=float)
    if p.shape[0] != t.size or v.shape != t.shape:
        raise ValueError("time, tau/dq and v_com_x must have the same number of samples")
    energy = float(trapezoid(p, t))
    dist = float(trapezoid(v, t))
    cot = energy / (w * dist) if dist > 0 else float("nan")
    return CotResult(cot, energy, dist, w, float(t[-1] - t[0]), mode)


def cumulative_cot(time: np.ndarray, power: np.ndarray, v_com_x: np.ndarray, weight: float, *,
                   normalise: str = "running", min_distance_frac: float = 0.05) -> np.ndarray:
    """CoT accumulated from the first sample, per sample [-] (see the module docstring).

    Args:
        time: sample times [s] of one stance (or any window), strictly increasing.
        power: counted actuator power [W] per sample (from :func:`mechanical_power`).
        v_com_x: forward CoM velocity in W [m/s].
        weight: W_r [N].
        normalise: ``"running"`` E(t)/(W_r d(t)) or ``"final"`` E(t)/(W_r d(t_end)).
        min_distance_frac: with ``"running"``, samples with d(t) < this fraction of the
            window's total distance are NaN (0/0 at the start; the ratio is noise-dominated
            until the CoM has moved).

    Returns:
        Array (n,); all NaN if the total distance is not positive. The last value equals
        :func:`cot_from_arrays` over the same window.
    """
    if normalise not in ("running", "final"):
        raise ValueError(f"normalise must be 'running' or 'final', got {normalise!r}")
    t = _check_time(time)
    w = _check_weight(weight)
    p = np.asarray(power, dtype=float)
    v = np.asarray(v_com_x, dtype=float)
    if p.shape != t.shape or v.shape != t.shape:
        raise ValueError("time, power and v_com_x must have the same shape")
    e = cumulative_trapezoid(p, t, initial=0.0)
    d = cumulative_trapezoid(v, t, initial=0.0)
    d_end = d[-1]
    out = np.full(t.shape, np.nan)
    if not d_end > 0:
        return out
    if normalise == "final":
        return e / (w * d_end)
    ok = d >= max(min_distance_frac, 0.0) * d_end
    ok &= d > 0
    out[ok] = e[ok] / (w * d[ok])
    return out


# --------------------------------------------------------------------------- from logs
def log_joints(log: pd.DataFrame, biped=None, joints: Sequence[str] | None = None) -> list[str]:
    """Actuated joint names used for the power: ``joints``, else the biped's, else every
    name with both ``tau_<name>`` and ``dq_<name>`` columns (in column order)."""
    if joints is None and biped is not None:
        joints = list(biped.joint_names)
    if joints is None:
        joints = [c[4:] for c in log.columns if c.startswith("tau_") and f"dq_{c[4:]}" in log]
    joints = list(joints)
    missing = [c for j in joints for c in (f"tau_{j}", f"dq_{j}") if c not in log.columns]
    if not joints or missing:
        raise ValueError(f"the log lacks joint columns {missing or ['tau_*/dq_*']}")
    return joints


def resolve_weight(weight: float | None, biped=None) -> float:
    """W_r [N]: ``weight`` if given, else ``biped.weight``; ValueError if neither or not > 0."""
    if weight is not None:
        return _check_weight(weight)
    if biped is not None:
        return _check_weight(biped.weight)
    raise ValueError("give the robot weight W_r [N] (weight=…) or the robot model (biped=…)")


def log_power(log: pd.DataFrame, *, biped=None, joints: Sequence[str] | None = None,
              mode: str = "abs") -> np.ndarray:
    """Counted actuator power [W] per log row (see :func:`mechanical_power`)."""
    js = log_joints(log, biped, joints)
    tau = log[[f"tau_{j}" for j in js]].to_numpy(dtype=float)
    dq = log[[f"dq_{j}" for j in js]].to_numpy(dtype=float)
    return mechanical_power(tau, dq, mode)


def log_window(log: pd.DataFrame, t_start: float | None = None,
               t_end: float | None = None) -> pd.DataFrame:
    """Rows with t_start <= time <= t_end [s] (a bound left None is open)."""
    t = log["time"].to_numpy(dtype=float)
    sel = np.ones(t.size, dtype=bool)
    if t_start is not None:
        sel &= t >= t_start
    if t_end is not None:
        sel &= t <= t_end
    return log.loc[sel]


def cot_from_log(log: pd.DataFrame, *, weight: float | None = None, biped=None,
                 joints: Sequence[str] | None = None, mode: str = "abs",
                 t_start: float | None = None, t_end: float | None = None) -> CotResult:
    """Whole-window CoT of a run log (columns ``time``, ``tau_*``, ``dq_*``, ``com_vx``).

    Args:
        log: run log DataFrame.
        weight: W_r [N]; defaults to ``biped.weight``.
        biped: robot model (joint names and weight), optional.
        joints: actuated joint names, optional (default: see :func:`log_joints`).
        mode: power mode, see :func:`mechanical_power` (default ``"abs"``: the literal
            reading ``abs_net``; :func:`cot_readings_from_log` gives every reading).
        t_start, t_end: restrict to t_start <= time <= t_end [s] (e.g. skip a transient).
    """
    w = resolve_weight(weight, biped)
    part = log_window(log, t_start, t_end)
    p = log_power(part, biped=biped, joints=joints, mode=mode)
    tt = _check_time(part["time"].to_numpy(dtype=float))
    energy = float(trapezoid(p, tt))
    dist = float(trapezoid(part["com_vx"].to_numpy(dtype=float), tt))
    cot = energy / (w * dist) if dist > 0 else float("nan")
    return CotResult(cot, energy, dist, w, float(tt[-1] - tt[0]), mode)


def stance_cumulative_cot(log: pd.DataFrame, *, weight: float | None = None, biped=None,
                          joints: Sequence[str] | None = None, segments: pd.DataFrame | None = None,
                          mode: str = "abs", normalise: str = "running",
                          min_distance_frac: float = 0.05) -> pd.DataFrame:
    """Cumulative CoT within every stance segment of a log (paper Fig. 6c).

    Args:
        segments: from :func:`~granular_mpc.analysis.metrics.segment_stances`; default:
            touchdown to lift-off (:func:`~granular_mpc.analysis.metrics.contact_segments`).
        mode: power mode (:func:`mechanical_power`; ``reading_mode(r)`` for a reading r).
        Others: as :func:`cot_from_log` and :func:`cumulative_cot`.

    Returns:
        Long DataFrame ``[stance_id, side, time, phase_pct, energy_J, distance_m, cot_cum,
        stance_source]`` with E(t) [J] and d(t) [m] accumulated from the stance start and
        ``cot_cum`` as in :func:`cumulative_cot`.
    """
    w = resolve_weight(weight, biped)
    if segments is None:
        segments = contact_segments(log)
    src = table_source(segments)
    p_all = log_power(log, biped=biped, joints=joints, mode=mode)
    t_all = log["time"].to_numpy(dtype=float)
    v_all = log["com_vx"].to_numpy(dtype=float)
    parts = []
    for seg in segments.itertuples(index=False):
        sl = slice(seg.row_start, seg.row_stop)
        t, p, v = t_all[sl], p_all[sl], v_all[sl]
        parts.append(pd.DataFrame({
            ID_COL: int(seg.stance_id), "side": seg.side, "time": t,
            PHASE_COL: 100.0 * (t - t[0]) / (t[-1] - t[0]),
            "energy_J": cumulative_trapezoid(p, t, initial=0.0),
            "distance_m": cumulative_trapezoid(v, t, initial=0.0),
            "cot_cum": cumulative_cot(t, p, v, w, normalise=normalise,
                                      min_distance_frac=min_distance_frac),
            SOURCE_COL: src}))
    cols = [ID_COL, "side", "time", PHASE_COL, "energy_J", "distance_m", "cot_cum", SOURCE_COL]
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=cols)


# --------------------------------------------------------------------------- readings
@dataclass(frozen=True)
class CotReadings:
    """CoT of one window under each reading of the paper's E (module docstring).

    Attributes:
        abs_per_joint: P = Σ_i |τ_i q̇_i| (the default reading).
        abs_net: P = |Σ_i τ_i q̇_i| (the literal reading).
        positive: P = Σ_i max(τ_i q̇_i, 0).
        net_work_J: W_net = ∫ Σ_i τ_i q̇_i dt [J]; E_abs_per_joint = 2 E_positive − W_net.
    """

    abs_per_joint: CotResult
    abs_net: CotResult
    positive: CotResult
    net_work_J: float

    def get(self, reading: str) -> CotResult:
        """The :class:`CotResult` of ``reading`` (one of :data:`COT_READINGS`)."""
        reading_mode(reading)
        return getattr(self, reading)

    @property
    def default(self) -> CotResult:
        """The result under :data:`DEFAULT_COT_READING`."""
        return self.get(DEFAULT_COT_READING)

    def cots(self) -> dict[str, float]:
        """``{reading: CoT}`` for every reading [-]."""
        return {r: self.get(r).cot for r in COT_READINGS}


def cot_readings_from_arrays(time: np.ndarray, tau: np.ndarray, dq: np.ndarray,
                             v_com_x: np.ndarray, weight: float, *,
                             distance: float | None = None) -> CotReadings:
    """Every reading's CoT from sampled signals (arguments as :func:`cot_from_arrays`).

    Args:
        distance: d [m] to divide by instead of ∫ v_com_x dt (e.g. a CoM displacement);
            the CoT is NaN if d <= 0.
    """
    t = _check_time(time)
    w = _check_weight(weight)
    tau = np.asarray(tau, dtype=float)
    dq = np.asarray(dq, dtype=float)
    if tau.shape != dq.shape:
        raise ValueError(f"tau {tau.shape} and dq {dq.shape} must have the same shape")
    p = tau * dq
    v = np.asarray(v_com_x, dtype=float)
    if p.shape[0] != t.size or v.shape != t.shape:
        raise ValueError("time, tau/dq and v_com_x must have the same number of samples")
    dist = float(trapezoid(v, t)) if distance is None else float(distance)
    dur = float(t[-1] - t[0])
    res = {}
    for r in COT_READINGS:
        mode = reading_mode(r)
        e = float(trapezoid(combine_joint_powers(p, mode), t))
        res[r] = CotResult(e / (w * dist) if dist > 0 else float("nan"), e, dist, w, dur, mode)
    net = float(trapezoid(p.sum(axis=1) if p.ndim == 2 else p, t))
    return CotReadings(res["abs_per_joint"], res["abs_net"], res["positive"], net)


def cot_readings_from_log(log: pd.DataFrame, *, weight: float | None = None, biped=None,
                          joints: Sequence[str] | None = None, t_start: float | None = None,
                          t_end: float | None = None,
                          distance: float | None = None) -> CotReadings:
    """Every reading's whole-window CoT of a run log (arguments as :func:`cot_from_log`;
    ``distance`` as :func:`cot_readings_from_arrays`). The ``abs_net`` result equals
    ``cot_from_log(..., mode="abs")``."""
    w = resolve_weight(weight, biped)
    part = log_window(log, t_start, t_end)
    js = log_joints(part, biped, joints)
    return cot_readings_from_arrays(
        part["time"].to_numpy(dtype=float), part[[f"tau_{j}" for j in js]].to_numpy(dtype=float),
        part[[f"dq_{j}" for j in js]].to_numpy(dtype=float),
        part["com_vx"].to_numpy(dtype=float), w, distance=distance)


def estimate_weight_from_grf(log: pd.DataFrame, g: float = STANDARD_GRAVITY) -> float:
    """Robot weight W_r [N] from the vertical impulse balance of a log.

    With ground reaction forces and gravity the only vertical external forces,
    ∫ ΣF_z dt = m g T + m Δv_CoM,z, hence ``W_r = ∫ ΣF_z dt / (T + Δv_CoM,z / g)``
    (exact up to the integration error). Uses ``left_grf_z + right_grf_z`` (or ``grf_z``
    if the per-foot columns are absent), ``com_vz`` and ``time``. Use it only when the
    robot model is not at hand; an external force on the trunk invalidates it.
    """
    t = _check_time(log["time"].to_numpy(dtype=float))
    if "left_grf_z" in log.columns and "right_grf_z" in log.columns:
        fz = log["left_grf_z"].to_numpy(dtype=float) + log["right_grf_z"].to_numpy(dtype=float)
    else:
        fz = log["grf_z"].to_numpy(dtype=float)
    vz = log["com_vz"].to_numpy(dtype=float)
    denom = (t[-1] - t[0]) + (vz[-1] - vz[0]) / g
    return _check_weight(trapezoid(fz, t) / denom)


__all__ = [
    "CotResult", "POWER_MODES", "COT_READINGS", "DEFAULT_COT_READING", "READING_POWER_MODES",
    "reading_mode", "combine_joint_powers", "CotReadings", "cot_readings_from_arrays",
    "cot_readings_from_log", "log_window", "resolve_weight", "mechanical_power",
    "cot_from_arrays", "cumulative_cot",
    "log_joints", "log_power", "cot_from_log", "stance_cumulative_cot",
    "estimate_weight_from_grf",
]
