"""Foot rolling during stance: rolling angle Δθ_r, its rate, effective radius R_eff, plateaus.

Paper (Sec. II-B, eqs. theta_r and Reff): the stance foot's orientation angle θ_r is the
slope angle of the sole contour at the contact point C (the lowest sole point) in the
foot's local frame, ``tan θ_r = dz_r/dx_r |_C``; ``Δθ_r = θ_r1 − θ_r0`` compares the current
contact C1 with the touchdown contact C0, and ``R_eff ≈ ‖v_s‖ / |θ̇_r|`` with
``v_s = (ẋ_s, ż_s)`` the intrusion velocity of the contact point.

**θ_r from the log.** The sole tangent at its lowest point is horizontal in the world, so
its slope angle in the foot frame equals the foot's world pitch up to sign. For our
cylindrical sole (radius R, centre at the foot frame origin) the lowest point sits at the arc
angle ψ from the foot's −z axis toward its +x axis, where its slope is ``dz_r/dx_r = tan ψ``
in (x_r forward, z_r up) axes; the log's foot pitch ``<side>_pitch`` is ψ_c = −ψ (the angle
from world-down to the foot's −z axis, positive toward the foot heading; see
``docs/notation.md``). Both change by exactly the rolling angle. We define
``θ_r := ψ_c`` and ``Δθ_r(t) = ψ_c(t) − ψ_c(t_touchdown)`` [rad].

**Sign.** When the robot walks forward the stance leg sweeps backward and the foot rolls
forward like a wheel (positive rotation about +y): the foot's −z axis tilts backward, ψ_c
*decreases*, and Δθ_r < 0 — the paper's Fig. 6a convention ("negative sign presents
decreasing values"). Measured in (x_r forward, z_r up) axes the slope angle would grow
instead; ``θ_r := ψ_c`` is the choice that reproduces the paper's sign. A foot pitching
toe-up over the stance gives Δθ_r > 0.

**R_eff.** ``R_eff = ‖v_s‖ / |θ̇_r|`` [m] with ``θ̇_r = dψ_c/dt`` [rad/s] and
``v_s = (d intrusion_x/dt, d intrusion_z/dt)`` [m/s] (world x and depth; optionally with
``d intrusion_y/dt``). Derivatives are finite differences over each stance separately
(``numpy.gradient``, second order, non-uniform time allowed). Where ``|θ̇_r| < min_rate``
the ratio is meaningless (a pure slide without rotation has R_eff → ∞) and is reported as
**NaN**. Because ``intrusion_*`` follow the *lowest sole point*, a disc-like sole rolling
without slip on rigid ground gives R_eff = sole radius; sliding adds to ‖v_s‖ and raises it.

**Plateau.** A plateau is a run of stance phase where ``|θ̇_r| < threshold`` lasting at
least ``min_duration_pct`` of the stance; the paper reports one starting near 40 % of
stance on sand and none on rigid ground (see :func:`detect_plateau`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .metrics import ID_COL, PHASE_COL, contact_segments, stance_column
from .stances import SOURCE_COL, table_source, true_runs

DEFAULT_MIN_RATE = 0.05  # rad/s


def _deriv(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """dy/dt by second-order finite differences (first order if fewer than 3 samples)."""
    return np.gradient(y, t, edge_order=2 if y.size >= 3 else 1)


def rolling_from_arrays(time: np.ndarray, pitch: np.ndarray, intrusion_x: np.ndarray,
                        intrusion_z: np.ndarray, *, intrusion_y: np.ndarray | None = None,
                        min_rate: float = DEFAULT_MIN_RATE) -> pd.DataFrame:
    """Rolling quantities over one stance, from touchdown (first sample) on.

    Args:
        time: sample times of one stance [s], strictly increasing.
        pitch: foot pitch ψ_c [rad] (``<side>_pitch``); θ_r := ψ_c.
        intrusion_x, intrusion_z: contact point relative to touchdown [m], world x and
            depth (positive deeper), i.e. the paper's x_s, z_s.
        intrusion_y: lateral slip y_s [m]; if given it is included in ‖v_s‖ (3-D speed).
        min_rate: |θ̇_r| [rad/s] below which R_eff is NaN.

    Returns:
        DataFrame with ``time``, ``theta_r`` (= ψ_c) [rad], ``dtheta_r`` (Δθ_r) [rad],
        ``dtheta_r_rate`` (θ̇_r) [rad/s], ``vs_x``, ``vs_z`` (and ``vs_y``) [m/s], ``v_s``
        (‖v_s‖) [m/s], ``gamma`` (atan2(ż_s, ẋ_s)) [rad], ``r_eff`` [m].
    """
    t = np.asarray(time, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError("time must be 1-D, strictly increasing, with at least two samples")
    psi = np.asarray(pitch, dtype=float)
    xs = np.asarray(intrusion_x, dtype=float)
    zs = np.asarray(intrusion_z, dtype=float)
    if psi.shape != t.shape or xs.shape != t.shape or zs.shape != t.shape:
        raise ValueError("time, pitch and intrusion arrays must have the same shape")
    if min_rate < 0:
        raise ValueError("min_rate must be >= 0")
    rate = _deriv(psi, t)
    vx, vz = _deriv(xs, t), _deriv(zs, t)
    out = {"time": t, "theta_r": psi, "dtheta_r": psi - psi[0], "dtheta_r_rate": rate,
           "vs_x": vx, "vs_z": vz}
    speed2 = vx ** 2 + vz ** 2
    if intrusion_y is not None:
        ys = np.asarray(intrusion_y, dtype=float)
        if ys.shape != t.shape:
            raise ValueError("intrusion_y must have the same shape as time")
        vy = _deriv(ys, t)
        out["vs_y"] = vy
        speed2 = speed2 + vy ** 2
    speed = np.sqrt(speed2)
    out["v_s"] = speed
    out["gamma"] = np.arctan2(vz, vx)
    r_eff = np.full(t.shape, np.nan)
    ok = np.abs(rate) >= min_rate
    ok &= np.abs(rate) > 0
    r_eff[ok] = speed[ok] / np.abs(rate[ok])
    out["r_eff"] = r_eff
    return pd.DataFrame(out)


def rolling_from_log(log: pd.DataFrame, *, segments: pd.DataFrame | None = None,
                     min_rate: float = DEFAULT_MIN_RATE, lateral: bool = False) -> pd.DataFrame:
    """Rolling quantities of every stance segment of a run log.

    Uses per stance the stance foot's ``<side>_pitch`` and ``<side>_intrusion_x/z``
    (falling back to ``intrusion_x/z`` of the v1 columns when per-foot ones are absent).

    Args:
        log: run log DataFrame.
        segments: from :func:`~granular_mpc.analysis.metrics.segment_stances`; default:
            touchdown to lift-off (:func:`~granular_mpc.analysis.metrics.contact_segments`:
            contact state, else force, else the plan), so Δθ_r is measured from touchdown.
        min_rate: see :func:`rolling_from_arrays`.
        lateral: include ẏ_s in ‖v_s‖.

    Returns:
        Long DataFrame ``[stance_id, side, stance_source, phase_pct, …]`` with the columns
        of :func:`rolling_from_arrays`.
    """
    if segments is None:
        segments = contact_segments(log)
    src = table_source(segments)
    t_all = log["time"].to_numpy(dtype=float)
    parts = []
    for seg in segments.itertuples(index=False):
        sl = slice(seg.row_start, seg.row_stop)
        side = seg.side

        def col(name: str) -> np.ndarray:
            for c in (f"{side}_{name}", stance_column(name, side, log.columns)):
                if c in log.columns:
                    return log[c].to_numpy(dtype=float)[sl]
            raise ValueError(f"rolling_from_log: the log has no {side}_{name} column")

        t = t_all[sl]
        df = rolling_from_arrays(t, col("pitch"), col("intrusion_x"), col("intrusion_z"),
                                 intrusion_y=col("intrusion_y") if lateral else None,
                                 min_rate=min_rate)
        df.insert(0, PHASE_COL, 100.0 * (t - t[0]) / (t[-1] - t[0]))
        df.insert(0, SOURCE_COL, src)
        df.insert(0, "side", side)
        df.insert(0, ID_COL, int(seg.stance_id))
        parts.append(df)
    if not parts:
        return pd.DataFrame(columns=[ID_COL, "side", SOURCE_COL, PHASE_COL, "time", "theta_r",
                                     "dtheta_r", "dtheta_r_rate", "vs_x", "vs_z", "v_s", "gamma", "r_eff"])
    return pd.concat(parts, ignore_index=True)


@dataclass(frozen=True)
class PlateauResult:
    """Plateaus of the rolling angle within one stance.

    Attributes:
        fraction: share of the stance (by phase) covered by plateaus [-], 0–1.
        intervals: (start, end) of each plateau [% stance].
        onset_pct: start of the first plateau [%], NaN if none.
        threshold: the |θ̇_r| threshold used [rad/s].
    """

    fraction: float
    intervals: tuple[tuple[float, float], ...] = field(default_factory=tuple)
    onset_pct: float = float("nan")
    threshold: float = float("nan")

    @property
    def has_plateau(self) -> bool:
        return len(self.intervals) > 0


def detect_plateau(phase_pct: np.ndarray, rate: np.ndarray, *, threshold: float | None = None,
                   rel_threshold: float = 0.1, min_duration_pct: float = 5.0) -> PlateauResult:
    """Find where the rolling angle stalls: |θ̇_r| < threshold for long enough.

    Each sample stands for the phase half-way to its neighbours (trapezoid cells), so a
    run of samples i..j covers [(φ_{i−1}+φ_i)/2, (φ_j+φ_{j+1})/2] (clipped to the stance).

    Args:
        phase_pct: stance phase of the samples [%], increasing.
        rate: θ̇_r [rad/s] at the samples.
        threshold: absolute |θ̇_r| threshold [rad/s]; if None it is
            ``rel_threshold × mean |θ̇_r|`` over the stance (relative to the stance's
            average rolling speed, so it adapts to gait speed).
        min_duration_pct: shorter sub-threshold runs (e.g. the instant θ̇_r crosses zero)
            are not plateaus [% stance].

    Returns:
        :class:`PlateauResult`.
    """
    ph = np.asarray(phase_pct, dtype=float)
    r = np.abs(np.asarray(rate, dtype=float))
    if ph.shape != r.shape or ph.ndim != 1 or ph.size < 2:
        raise ValueError("phase_pct and rate must be 1-D arrays of equal length >= 2")
    if threshold is None:
        ref = float(np.nanmean(r))
        threshold = rel_threshold * ref
    mids = np.concatenate(([ph[0]], 0.5 * (ph[1:] + ph[:-1]), [ph[-1]]))
    span = ph[-1] - ph[0]
    intervals = []
    for a, b in true_runs(r < threshold):
        lo, hi = float(mids[a]), float(mids[b])
        if hi - lo >= min_duration_pct:
            intervals.append((lo, hi))
    covered = sum(hi - lo for lo, hi in intervals)
    frac = covered / span if span > 0 else float("nan")
    onset = intervals[0][0] if intervals else float("nan")
    return PlateauResult(float(frac), tuple(intervals), float(onset), float(threshold))


def plateau_by_stance(rolling: pd.DataFrame, **kwargs) -> pd.DataFrame:
    """:func:`detect_plateau` on every stance of :func:`rolling_from_log` output.

    Returns:
        ``[stance_id, side, fraction, onset_pct, n_plateaus, threshold, stance_source]``
        (``stance_source`` copied from ``rolling``, ``"planned"`` if it has none);
        ``kwargs`` go to :func:`detect_plateau`.
    """
    rows = []
    for sid, g in rolling.groupby(ID_COL, sort=True):
        res = detect_plateau(g[PHASE_COL].to_numpy(), g["dtheta_r_rate"].to_numpy(), **kwargs)
        src = str(g[SOURCE_COL].iloc[0]) if SOURCE_COL in g.columns else "planned"
        rows.append((sid, g["side"].iloc[0], res.fraction, res.onset_pct, len(res.intervals),
                     res.threshold, src))
    return pd.DataFrame(rows, columns=[ID_COL, "side", "fraction", "onset_pct", "n_plateaus",
                                       "threshold", SOURCE_COL])


__all__ = ["rolling_from_arrays", "rolling_from_log", "PlateauResult", "detect_plateau",
           "plateau_by_stance", "DEFAULT_MIN_RATE"]
