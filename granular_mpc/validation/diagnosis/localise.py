"""Stage 5, localise: where (channel × stance phase, per side), at which speed, with which
measured variable and how slowly (stance to stance) a residual is structured
(``docs/validation.md`` §3.4)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
from scipy.special import stdtr
from statsmodels.stats.diagnostic import acorr_ljungbox

from ..prepare import StanceWindow, channel_unit
from .candidates import Column
from .cubes import bin_means, group_keys, residual_cube
from .localization_records import (Cell, ChannelStructure, Correlate, Localization, SpeedBias,
                                   Whiteness)
from .mutual_info import mutual_info
from .problem import Problem
from .regression import Regression
from .residuals import Residuals, channel_sigma
from .thresholds import LOCALISATION_FEATURES, MAJOR_BIAS, PRACTICAL_BIAS, T_CELL

#: strongest significant cells kept in :attr:`Localization.significant_cells`
MAX_LISTED_CELLS = 40
#: binned samples the mutual-information estimate is subsampled to
MI_MAX_SAMPLES = 3000
#: σ of white noise = 1.4826 · median |second difference| / √6 (robust, ignores smooth motion)
_MAD_TO_SIGMA = 1.4826 / math.sqrt(6.0)


def spearman(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Spearman ρ and its p-value over the finite pairs (NaN with < 10 or constant)."""
    m = np.isfinite(x) & np.isfinite(y)
    if m.sum() < 10 or np.std(x[m]) == 0 or np.std(y[m]) == 0:
        return float("nan"), float("nan")
    # scipy.stats.spearmanr's steps (ranks, corrcoef of the ranks, Student-t p-value),
    # equal bit for bit without its per-call input handling (≈ 1 ms a call)
    rs = np.corrcoef(np.column_stack([average_ranks(x[m]), average_ranks(y[m])]),
                     rowvar=False)
    dof = int(m.sum()) - 2
    with np.errstate(divide="ignore"):
        t = rs * np.sqrt((dof / ((rs + 1.0) * (1.0 - rs))).clip(0))
    p = 2 * stdtr(dof, -np.abs(t))
    return float(rs[1, 0]), float(p[1, 0])


def average_ranks(v: np.ndarray) -> np.ndarray:
    """Ranks 1…n of ``v``, ties getting their average rank
    (``scipy.stats.rankdata(v, method="average")``)."""
    order = np.argsort(v, kind="stable")
    s = v[order]
    first = np.flatnonzero(np.r_[True, s[:-1] != s[1:]])
    counts = np.diff(first, append=v.size)
    ranks = (first + 1.0) + (counts.astype(float) - 1) / 2
    out = np.empty(v.size)
    out[order] = np.repeat(ranks, counts)
    return out


def measurement_noise(windows: Sequence[StanceWindow],
                      channels: Sequence[str]) -> dict[str, float]:
    """Per channel: the measurement noise of one sample, estimated from the data.

    The second difference x[k+1] − 2x[k] + x[k−1] of white noise of σ has variance 6σ²,
    while the measured motion contributes ~a·Δt² (at 500 Hz: 1e-5 m for a sole decelerating
    at 2.5 m/s², against 1 mm of marker noise), so σ = 1.4826 · median |Δ²x| / √6 over the
    stance samples (the median ignores the force steps of touchdown). Low-passed noise
    (``dq_*``, ``base_v*``) is underestimated, which only makes the practical-size test
    of :func:`localize` less strict.

    Args:
        windows: stance windows; their ``meas`` arrays (channel units).
        channels: channels to estimate.

    Returns:
        channel → σ_meas (channel units; 0 where fewer than 3 finite samples).
    """
    out = {}
    for ch in channels:
        d2 = []
        for w in windows:
            x = np.asarray(w.meas.get(ch, ()), float)
            if x.size >= 3:
                d = np.diff(x, 2)
                d2.append(d[np.isfinite(d)])
        d2 = np.concatenate(d2) if d2 else np.empty(0)
        out[ch] = float(_MAD_TO_SIGMA * np.median(np.abs(d2))) if d2.size else 0.0
    return out


def practical_floor(sigma_c: float, sigma_meas: float) -> float:
    """The smallest cell bias of practical size: ``PRACTICAL_BIAS`` × the error of one
    sample of a correct model, √(σ_c² + σ_meas²) — its stance-to-stance replay scatter
    and the sensor's noise (channel units)."""
    return PRACTICAL_BIAS * math.hypot(sigma_c, sigma_meas)


def _cells(windows, R, channels, edges, sigma, noise) -> list[Cell]:
    W, C, B = R.shape
    floor = {ch: practical_floor(sigma.get(ch, 1.0), noise.get(ch, 0.0)) for ch in channels}
    cells = []
    sides = np.array([w.side for w in windows])
    # pooled over both stance sides, and per side (a lateral effect may flip sign with the
    # side, or the legs may answer it differently)
    for side in ("all", "left", "right"):
        m_side = np.ones(W, bool) if side == "all" else sides == side
        if m_side.sum() < 3:
            continue
        for c, ch in enumerate(channels):
            for b in range(B):
                v = R[m_side, c, b]
                v = v[np.isfinite(v)]
                if v.size < 3:
                    continue
                mean, sd = float(v.mean()), float(v.std(ddof=1))
                t = mean / (sd / math.sqrt(v.size)) if sd > 0 else 0.0
                nb = mean / sigma.get(ch, 1.0)
                major = (bool(abs(nb) >= MAJOR_BIAS and abs(mean) >= floor[ch])
                         if abs(t) >= T_CELL else None)
                cells.append(Cell(ch, side, float(edges[b]), float(edges[b + 1]), mean, sd,
                                  float(np.sqrt(np.mean(v ** 2))), t, int(v.size),
                                  channel_unit(ch), nb, major))
    return cells


def _correlates(windows, R, channels, edges, sigma, seed) -> dict[str, tuple[Correlate, ...]]:
    """Binned features vs binned normalised residual, per channel."""
    W, C, B = R.shape
    feats = list(LOCALISATION_FEATURES)
    Fcube = np.empty((W, len(feats), B))
    for i, w in enumerate(windows):
        Fcube[i] = bin_means(w, w.features, feats, edges)
    speeds = np.array([w.speed for w in windows])
    spd = np.repeat(speeds[:, None], B, axis=1)
    names = feats + ["commanded_speed"]
    X = np.column_stack([(spd if f == "commanded_speed" else Fcube[:, k, :]).ravel()
                         for k, f in enumerate(names)])
    correlates = {}
    rng = np.random.default_rng(seed)
    for c, ch in enumerate(channels):
        y = (R[:, c, :] / sigma.get(ch, 1.0)).ravel()
        rho_p = [spearman(X[:, k], y) for k in range(len(names))]
        m = np.isfinite(y) & np.isfinite(X).all(axis=1)
        mi = [None] * len(names)
        if m.sum() > 30:
            idx = np.flatnonzero(m)
            if idx.size > MI_MAX_SAMPLES:
                idx = rng.choice(idx, MI_MAX_SAMPLES, replace=False)
            mi = [float(v) for v in mutual_info(X[idx], y[idx], random_state=seed)]
        out = [Correlate(f, rho, p, v) for f, (rho, p), v in zip(names, rho_p, mi)]
        out.sort(key=lambda e: -(abs(e.spearman) if e.spearman == e.spearman else 0))
        correlates[ch] = tuple(out)
    return correlates


def _whiteness(windows, R, channels, model_df) -> dict[str, Whiteness]:
    """Ljung–Box per channel of the stance-mean residual in time order (trials
    concatenated)."""
    W = R.shape[0]
    order = sorted(range(W), key=lambda i: (windows[i].trial, windows[i].row_start))
    whiteness = {}
    for c, ch in enumerate(channels):
        seq = np.array([np.nanmean(R[i, c, :]) for i in order])
        seq = seq[np.isfinite(seq)]
        lags = int(min(10, max(1, seq.size // 5)))
        if seq.size > lags + model_df + 2:
            lb = acorr_ljungbox(seq - seq.mean(), lags=[lags], model_df=min(model_df, lags - 1)
                                if lags > 1 else 0)
            whiteness[ch] = Whiteness(lags, float(lb["lb_stat"].iloc[0]),
                                      float(lb["lb_pvalue"].iloc[0]))
    return whiteness


def localize(windows: Sequence[StanceWindow], R: np.ndarray, channels: Sequence[str],
             edges: np.ndarray, sigma: Mapping[str, float], *, model_df: int = 0,
             seed: int = 0, noise: Mapping[str, float] | None = None) -> Localization:
    """Where, when and with what the residual cube ``R`` (W, C, B) is structured.

    A cell is *significant* when |t| ≥ ``T_CELL`` and *major* (structure a missing effect
    must explain) when it is also of practical size: |bias| ≥ ``MAJOR_BIAS`` σ_c and
    |bias| ≥ :func:`practical_floor` (σ_c, σ_meas).

    Args:
        R: binned residual (channel units); edges: phase-bin edges [%].
        sigma: channel → stance-to-stance scatter σ_c (channel units).
        model_df: parameters fitted to the residual (Ljung–Box degrees of freedom).
        seed: seed of the mutual-information estimate.
        noise: channel → measurement noise of one sample σ_meas (channel units;
            :func:`measurement_noise`); None: 0 (the size test is |bias| ≥ σ_c alone).
    """
    cells = _cells(windows, R, channels, edges, sigma, noise or {})
    sig = [cl for cl in cells if abs(cl.t) >= T_CELL]
    sig.sort(key=lambda cl: (not cl.major, -abs(cl.t)))
    by_channel = {}
    for c, ch in enumerate(channels):
        v = R[:, c, :]
        mean_profile = np.nanmean(v, axis=0)
        total = float(np.nanmean(v ** 2))
        syst = float(np.nanmean(mean_profile ** 2))
        by_channel[ch] = ChannelStructure(math.sqrt(total) if total == total else None,
                                          math.sqrt(syst) if syst == syst else None,
                                          syst / total if total > 0 else None, channel_unit(ch))
    speeds = np.array([w.speed for w in windows])
    by_speed = []
    for s in np.unique(speeds):
        m = speeds == s
        for c, ch in enumerate(channels):
            v = R[m, c, :]
            by_speed.append(SpeedBias(float(s), ch, float(np.nanmean(v)),
                                      float(np.sqrt(np.nanmean(v ** 2))), int(m.sum())))
    return Localization(tuple(cells), tuple(sig[:MAX_LISTED_CELLS]), len(sig),
                        int(sum(cl.major for cl in sig)), by_channel, tuple(by_speed),
                        _correlates(windows, R, channels, edges, sigma, seed),
                        _whiteness(windows, R, channels, model_df))


def where_summary(loc: Localization, top: int = 5) -> list[str]:
    """The strongest cells in words, one line per channel (at most ``top``)."""
    lines = []
    seen = set()
    for cl in loc.significant_cells:
        key = cl.channel
        if key in seen:
            continue
        seen.add(key)
        cor = [e for e in loc.correlates.get(key, ()) if e.p_value == e.p_value
               and e.p_value is not None and e.p_value < 1e-3 and abs(e.spearman) >= 0.2]
        with_what = ", ".join(f"{e.feature} (ρ = {e.spearman:+.2f})" for e in cor[:3])
        side = "" if cl.side == "all" else f" ({cl.side} stances)"
        lines.append(f"{key}: bias {cl.bias:+.3g} {cl.unit} at {cl.phase_lo:g}–"
                     f"{cl.phase_hi:g} % of stance{side} (t = {cl.t:+.1f})"
                     + (f"; correlates with {with_what}" if with_what else ""))
        if len(lines) >= top:
            break
    return lines


@dataclass(frozen=True, eq=False)
class LocalisationStage:
    """Localisation of the calibrated model and of the final one.

    Attributes:
        before, after: structure before / after the added effects.
        R_calibrated: the calibrated residual with the calibration re-fitted linearly.
        R_after: the final residual (= ``R_calibrated`` when nothing was added).
        theta_linear: θ of that linear re-fit.
        measurement_noise: channel → σ_meas of one sample (:func:`measurement_noise`),
            used by the practical-size test of both localisations.
    """

    before: Localization
    after: Localization
    R_calibrated: np.ndarray
    R_after: np.ndarray
    theta_linear: Mapping[str, float]
    measurement_noise: Mapping[str, float] = field(default_factory=dict)


def localise_models(problem: Problem, res: Residuals, regression: Regression,
                    nuisance: Sequence[Column], final_preds: Sequence[dict] | None,
                    n_fitted: int, *, seed: int = 0) -> LocalisationStage:
    """Localise the calibrated model (its calibration re-fitted linearly on the regression's
    rows) and the final model (replayed ``final_preds``; None: nothing was added).

    Each model is judged against its *own* stance-to-stance scatter σ_c: the calibrated
    model against the residual stage's (``res.sigma``), the final model against the
    scatter of its own residual (:func:`.residuals.channel_sigma` of ``R_after``). A large
    misfit the additions removed (a late-stance knee error that varies from stance to
    stance) inflates the calibrated model's σ_c and would hide, in units of it, a cell the
    additions left — the structure an addition must explain (``docs/validation.md`` §3.7).

    Args:
        nuisance: the calibration's columns (the regression's base columns).
        n_fitted: parameters of the final model (Ljung–Box degrees of freedom).
    """
    base_keys = [c.key for c in nuisance]
    beta_n, _ = regression.fit(base_keys)
    R_cal = res.R - sum(b * res.sens[k] for k, b in zip(base_keys, beta_n))
    theta_lin = {c.param: float(c.neutral + b) for c, b in zip(nuisance, beta_n)}
    noise = measurement_noise(problem.windows, problem.channels)
    before = localize(problem.windows, R_cal, problem.channels, problem.edges, res.sigma,
                      model_df=len(base_keys), seed=seed, noise=noise)
    if final_preds is None:
        return LocalisationStage(before, before, R_cal, R_cal, theta_lin, noise)
    R_after = residual_cube(problem.windows, final_preds, problem.channels, problem.edges)
    after, _ = localize_final(problem.windows, R_after, problem.channels, problem.edges,
                              model_df=n_fitted, seed=seed, noise=noise)
    return LocalisationStage(before, after, R_cal, R_after, theta_lin, noise)


def localize_final(windows: Sequence[StanceWindow], R_after: np.ndarray,
                   channels: Sequence[str], edges: np.ndarray, *, model_df: int = 0,
                   seed: int = 0, noise: Mapping[str, float] | None = None
                   ) -> tuple[Localization, dict[str, float]]:
    """Localise the final model's residual ``R_after`` (W, C, B) against its own
    stance-to-stance scatter (:func:`.residuals.channel_sigma` within trial × side groups,
    as the residual stage does for the calibrated model).

    Returns:
        the localisation and channel → σ_c of ``R_after`` (channel units).
    """
    sigma = channel_sigma(R_after, channels, group_keys(windows))
    return (localize(windows, R_after, channels, edges, sigma, model_df=model_df, seed=seed,
                     noise=noise), sigma)


__all__ = ["localize", "where_summary", "spearman", "Localization", "LocalisationStage",
           "localise_models", "localize_final", "measurement_noise", "practical_floor",
           "MAX_LISTED_CELLS", "average_ranks"]
