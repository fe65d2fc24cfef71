"""Calibrate, then diagnose: which physical effect is the model missing, and where?

``diagnose(DATA, out_dir=…)`` runs four stages (``docs/validation.md`` explains them):

1. **Calibrate** the model's own terrain parameters (ζ, φ_s) on equation-error residuals
   of the sinking samples with the exact CasADi Jacobian (:mod:`.calibrate`), with
   Gauss–Newton and trial-bootstrap intervals. A parameter that is merely off is
   absorbed here — and again by the nuisance columns below — never reported as an effect.
2. **Replay** every stance (multiple shooting, :mod:`.replay`) with the calibrated model;
   the residual (measured − replayed) of every channel, averaged in stance-phase bins, is
   the thing to explain. For every candidate effect (the effects library — terrain-force,
   joint, sensor and geometry kinds — plus any user-registered effect) one more replay
   with the effect switched on at a nominal magnitude gives its *sensitivity column*; the
   calibration parameters get sensitivity columns too (nuisance, always in the model).
   Touchdown heights give a second, geometric equation (surface height vs. footprint
   position, one free height per trial). Residuals are weighted by each channel's
   stance-to-stance scatter.
3. **Rank** the candidates by bounded least squares on these columns: held-out error
   reduction under trial-grouped cross-validation (``GroupKFold``, groups = trials),
   ΔAICc (N corrected for the autocorrelation of the bins) and the inclusion probability
   of a forward selection refitted on bootstrap resamples of whole trials. Candidates
   whose fitted columns are nearly collinear are reported together, with the experiment
   that would separate them. An effect is **added** only if it passes all three tests;
   otherwise the verdict is "no significant missing effect". Added effects are refined by
   Gauss–Newton on the replays (the linearisation is redone at the fitted values).
4. **Localise** the residual structure — by channel × stance phase (bias t-statistics
   across stances), by speed, by rank correlation and mutual information with the
   measured state (depth, sink/slip velocity, rise from the deepest point, acceleration,
   time in stance, joint and trunk speed, position), and Ljung–Box whiteness of the
   stance-to-stance sequence — before and after the added effects, so structure that no
   candidate explains is reported as such.

Outputs: ``diagnosis.json`` (``verdict``, ``calibration``, ``ranking``, ``localization``,
``fitted_effects``, ``indistinguishable`` …), ``report.md`` (one page) and figures.
"""

from __future__ import annotations

import json
import math
import time as _time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..config import SimConfig
from ..exceptions import GranularMpcError
from ..output import json_safe, make_output_folder
from ..terrain.effects_library import EffectInfo, all_effects, effect_info
from .prepare import StanceWindow, channel_names, channel_unit
from .replay import (ReplayPool, Variant, build_replay_model, effect_variant,
                     model_terrain)

#: decision thresholds (documented in docs/validation.md)
MIN_HELDOUT_REDUCTION = 0.02      # at least 2 % less held-out weighted SSE
MAX_DELTA_AICC = -10.0            # "strong" evidence (Burnham–Anderson)
MIN_INCLUSION = 0.6               # selected in most bootstrap refits
MIN_STANCE_REDUCTION = 0.01       # ≥ 1 % less held-out error stance by stance (see below)
T_CELL = 4.0                      # |t| of a channel × phase cell that counts as structure
MAJOR_BIAS = 1.0                  # … and |bias| ≥ this × the stance-to-stance scatter: major
JUMP_FACTOR = 10.0                # a stance's finite-difference response this × the median …
JUMP_SHARE = 0.1                  # … on at most this share of the stances: a jump (_guard_jumps)
# practically large (_practically_large): it removes ≥ LARGE_HELDOUT_REDUCTION of the
# held-out error, or it changes some cell's mean by ≥ MIN_EFFECT_SIZE σ and helps held-out
# stances (MIN_STANCE_REDUCTION)
MIN_EFFECT_SIZE = 1.0
LARGE_HELDOUT_REDUCTION = 0.25
# Both set from data sets where any addition is spurious (no hidden effect, or a second
# effect on single-effect data): there the fitted terms moved the stance-averaged
# predictions by at most 0.76 σ and cut the held-out error by at most 17 %; with 0.5 σ
# alone, 2 of 10 null sets got a term. A size test alone is fragile for an effect spread
# thinly over many cells (a sideways force measured 0.88–2.1 σ over 20 plant realisations
# of bench/user_term.py's data sets while removing 32–73 % of the held-out error),
# docs/validation.md §3.3, §5.

FEATURE_EXPERIMENTS = {
    "depth": "a wider range of sinkage (looser or deeper sand, a payload)",
    "sink_velocity": "different touchdown speeds (swing height or duration)",
    "rise_from_deepest": "different pull-out motions (higher foot lift, slower push-off)",
    "sink_acceleration": "harder or softer touchdown impacts",
    "slip_velocity": "more horizontal slip (turning, side steps, higher speed)",
    "v_h": "different forward sole speeds at touchdown and pull-out (speed, swing timing)",
    "v_l": "sideways sole motion (side steps, turning)",
    "vc_z": "different vertical sole speeds (swing height, touchdown speed)",
    "time_in_stance": "a different gait period (longer or shorter stance)",
    "joint_speed": "a wider range of joint speeds (speeds, swing durations)",
    "trunk_speed": "a wider range of commanded speeds",
    "grf_z": "different loads (payload)",
    "x_position": "walks over a longer distance / in both directions",
    "commanded_speed": "a wider range of commanded speeds",
}


# ======================================================================================
# Candidates and their columns
# ======================================================================================


@dataclass(frozen=True)
class Column:
    """One regression column: a magnitude parameter of a candidate (or a nuisance θ)."""

    candidate: str          # effect name, or "calibration"
    param: str              # parameter (θ name for nuisance)
    neutral: float          # value that switches it off (nuisance: the calibrated value)
    step: float             # finite-difference step of the sensitivity
    lower: float            # bounds of the parameter value
    upper: float
    unit: str = ""

    @property
    def key(self) -> str:
        return f"{self.candidate}.{self.param}"


def candidate_columns(info: EffectInfo) -> list[Column]:
    """Columns of one candidate: its parameters that switch it off (``neutral``)."""
    cols = []
    for p, neutral in info.neutral.items():
        spec = info.params[p]
        step = spec.default - neutral
        if abs(step) < 1e-12:
            step = 0.1 * (spec.upper - spec.lower)
            if neutral + step > spec.upper:
                step = -step
        cols.append(Column(info.name, p, float(neutral), float(step), spec.lower, spec.upper,
                           spec.unit))
    return cols


def _variant_for(info: EffectInfo, values: Mapping[str, float], base: Variant) -> Variant:
    p = info.neutral_params()
    p.update(values)
    return effect_variant([(info, p)], base)


# ======================================================================================
# Residual rows
# ======================================================================================


def _bin_means(w: StanceWindow, values: Mapping[str, np.ndarray], channels: Sequence[str],
               edges: np.ndarray) -> np.ndarray:
    """(C, B) phase-bin means of ``values`` over one window (NaN where empty)."""
    b = np.clip(np.searchsorted(edges, w.phase, side="right") - 1, 0, len(edges) - 2)
    out = np.full((len(channels), len(edges) - 1), np.nan)
    for c, ch in enumerate(channels):
        v = np.asarray(values[ch], dtype=float)
        for k in range(len(edges) - 1):
            m = (b == k) & np.isfinite(v)
            if m.any():
                out[c, k] = v[m].mean()
    return out


def _residual_cube(windows, preds, channels, edges) -> np.ndarray:
    """(W, C, B) binned residual measured − predicted."""
    out = np.empty((len(windows), len(channels), len(edges) - 1))
    for i, w in enumerate(windows):
        diff = {c: w.meas[c] - np.asarray(preds[i][c], dtype=float) for c in channels}
        out[i] = _bin_means(w, diff, channels, edges)
    return out


def _pred_cube(windows, preds, channels, edges) -> np.ndarray:
    out = np.empty((len(windows), len(channels), len(edges) - 1))
    for i, w in enumerate(windows):
        out[i] = _bin_means(w, preds[i], channels, edges)
    return out


@dataclass
class Design:
    """Stacked weighted regression problem (replay rows, then geometry rows)."""

    y: np.ndarray                     # weighted residual
    X: dict                           # column key → weighted column
    groups: np.ndarray                # trial of each row
    window: np.ndarray                # window index of each row (−1: none)
    channel: np.ndarray               # channel name of each row ("touchdown_z" for geometry)
    phase_bin: np.ndarray             # phase bin (−1 for geometry rows)
    sigma: dict                       # channel → weight scale (channel units)
    n_eff_factor: float               # N_eff / N


# ======================================================================================
# Linear fits, cross-validation, AICc, bootstrap
# ======================================================================================


def _fit(X: np.ndarray, y: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    from scipy.optimize import lsq_linear

    if X.shape[1] == 0:
        return np.zeros(0)
    scale = np.sqrt((X ** 2).sum(axis=0))
    scale[scale == 0] = 1.0
    res = lsq_linear(X / scale, y, bounds=(lb * scale, ub * scale), method="bvls")
    return res.x / scale


def _aicc(rss: float, n: float, k: int) -> float:
    n = max(n, k + 2.0)
    return n * math.log(max(rss, 1e-300) / n) + 2 * k + 2 * k * (k + 1) / (n - k - 1)


class Regression:
    """Bounded least squares on a :class:`Design` with CV, AICc and bootstrap tools.

    ``design`` holds the rows that are fitted (the systematic, stance-averaged rows);
    ``stance_design`` (optional) holds the stance-by-stance rows on which the same fit is
    also scored. Cross-validation folds are whole groups (trials) shared by both.
    """

    def __init__(self, design: Design, bounds: Mapping[str, tuple[float, float]],
                 nuisance: Sequence[str], *, stance_design: Design | None = None,
                 n_splits: int = 5, seed: int = 0) -> None:
        from sklearn.model_selection import GroupKFold

        self.d = design
        self.bounds = dict(bounds)
        self.nuisance = list(nuisance)
        self.ok, self.y, self.cols, self.groups = self._arrays(design)
        ug = np.unique(self.groups)
        self.splits, self.st_splits = [], []
        self.st = None
        if stance_design is not None:
            self.st = self._arrays(stance_design)
            self._st_channel = stance_design.channel[self.st[0]]
            self._st_bin = stance_design.phase_bin[self.st[0]]
        if ug.size >= 2:
            gkf = GroupKFold(n_splits=min(n_splits, ug.size))
            for _, te_g in gkf.split(ug, groups=ug):
                test = set(ug[te_g])
                te = np.array([g in test for g in self.groups])
                self.splits.append((np.flatnonzero(~te), np.flatnonzero(te)))
                if self.st is not None:
                    ste = np.array([g in test for g in self.st[3]])
                    self.st_splits.append(np.flatnonzero(ste))
        self.seed = seed

    @staticmethod
    def _arrays(design: Design):
        ok = np.isfinite(design.y)
        for v in design.X.values():
            ok &= np.isfinite(v)
        return ok, design.y[ok], {k: v[ok] for k, v in design.X.items()}, design.groups[ok]

    def matrix(self, keys: Sequence[str], rows=None, cols=None):
        cols = self.cols if cols is None else cols
        n = next(iter(cols.values())).size if cols else 0
        if not keys:
            return np.zeros((n if rows is None else len(rows), 0)), np.zeros(0), np.zeros(0)
        X = np.column_stack([cols[k] for k in keys])
        lb = np.array([self.bounds[k][0] for k in keys])
        ub = np.array([self.bounds[k][1] for k in keys])
        return (X if rows is None else X[rows]), lb, ub

    def fit(self, keys: Sequence[str], rows=None) -> tuple[np.ndarray, float]:
        X, lb, ub = self.matrix(keys, rows)
        y = self.y if rows is None else self.y[rows]
        beta = _fit(X, y, lb, ub)
        r = y - X @ beta if len(keys) else y
        return beta, float(r @ r)

    def cv(self, keys: Sequence[str]) -> dict:
        """Held-out SSE of the fitted rows (total and per fold) and, with a stance design,
        of the stance rows of the held-out trials under the same fit."""
        per, per_st = [], []
        X, lb, ub = self.matrix(keys)
        if self.st is not None:
            Xs, _, _ = self.matrix(keys, cols=self.st[2])
        for k, (tr, te) in enumerate(self.splits):
            beta = _fit(X[tr], self.y[tr], lb, ub)
            r = self.y[te] - X[te] @ beta if len(keys) else self.y[te]
            per.append(float(r @ r))
            if self.st is not None:
                ste = self.st_splits[k]
                rs = self.st[1][ste] - Xs[ste] @ beta if len(keys) else self.st[1][ste]
                per_st.append(float(rs @ rs))
        return {"sse": float(sum(per)), "folds": per,
                "sse_stance": float(sum(per_st)) if per_st else float("nan")}

    def practical_size(self, keys: Sequence[str], beta: np.ndarray) -> float:
        """Largest stance-averaged change of the prediction that ``beta`` on ``keys``
        makes in any channel × phase cell, in units of that channel's stance-to-stance
        scatter σ (geometry rows: RMS over the touchdowns)."""
        if self.st is None or not len(keys):
            return float("nan")
        X, _, _ = self.matrix(keys, cols=self.st[2])
        v = X @ beta
        out = 0.0
        for ch in np.unique(self._st_channel):
            m = self._st_channel == ch
            if ch == "touchdown_z":
                out = max(out, float(np.sqrt(np.mean(v[m] ** 2))))
                continue
            bins = self._st_bin[m]
            for b in np.unique(bins):
                out = max(out, abs(float(v[m][bins == b].mean())))
        return out

    def n_eff(self, rows=None) -> float:
        n = self.y.size if rows is None else len(rows)
        return n * self.d.n_eff_factor

    def aicc(self, keys: Sequence[str], rows=None) -> float:
        _, rss = self.fit(keys, rows)
        return _aicc(rss, self.n_eff(rows), len(keys))

    def covariance(self, keys: Sequence[str], beta: np.ndarray) -> np.ndarray:
        X, _, _ = self.matrix(keys)
        r = self.y - X @ beta
        dof = max(self.y.size - len(keys), 1)
        s2 = float(r @ r) / dof / max(self.d.n_eff_factor, 1e-3)
        try:
            return np.linalg.inv(X.T @ X) * s2
        except np.linalg.LinAlgError:
            return np.full((len(keys), len(keys)), np.nan)


def _forward(reg: Regression, cand_cols: Mapping[str, list[str]], base_keys: list[str],
             rows=None, max_terms: int = 3) -> list[str]:
    """Forward selection by AICc (entry: ΔAICc ≤ MAX_DELTA_AICC), on ``rows``."""
    chosen: list[str] = []
    keys = list(base_keys)
    cur = reg.aicc(keys, rows)
    for _ in range(max_terms):
        best, best_a = None, cur
        for name, cols in cand_cols.items():
            if name in chosen:
                continue
            a = reg.aicc(keys + cols, rows)
            if a - cur <= MAX_DELTA_AICC and a < best_a:
                best, best_a = name, a
        if best is None:
            break
        chosen.append(best)
        keys = keys + cand_cols[best]
        cur = best_a
    return chosen


# ======================================================================================
# Localisation
# ======================================================================================


def _spearman(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    from scipy.stats import spearmanr

    m = np.isfinite(x) & np.isfinite(y)
    if m.sum() < 10 or np.std(x[m]) == 0 or np.std(y[m]) == 0:
        return float("nan"), float("nan")
    r = spearmanr(x[m], y[m])
    return float(r.statistic), float(r.pvalue)


def localize(windows: Sequence[StanceWindow], R: np.ndarray, channels: Sequence[str],
             edges: np.ndarray, sigma: Mapping[str, float], *, model_df: int = 0,
             seed: int = 0) -> dict:
    """Where, when and with what the residual cube ``R`` (W, C, B) is structured."""
    from sklearn.feature_selection import mutual_info_regression
    from statsmodels.stats.diagnostic import acorr_ljungbox

    W, C, B = R.shape
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
                cells.append({"channel": ch, "side": side, "phase_lo": float(edges[b]),
                              "phase_hi": float(edges[b + 1]), "bias": mean, "sd": sd,
                              "rms": float(np.sqrt(np.mean(v ** 2))), "t": t, "n": int(v.size),
                              "unit": channel_unit(ch),
                              "normalised_bias": mean / sigma.get(ch, 1.0)})
    sig = [cl for cl in cells if abs(cl["t"]) >= T_CELL]
    for cl in sig:
        cl["major"] = bool(abs(cl["normalised_bias"]) >= MAJOR_BIAS)
    sig.sort(key=lambda cl: (not cl["major"], -abs(cl["t"])))
    # by channel: share of the systematic part
    by_channel = {}
    for c, ch in enumerate(channels):
        v = R[:, c, :]
        mean_profile = np.nanmean(v, axis=0)
        total = float(np.nanmean(v ** 2))
        syst = float(np.nanmean(mean_profile ** 2))
        by_channel[ch] = {"rms": math.sqrt(total) if total == total else None,
                          "systematic_rms": math.sqrt(syst) if syst == syst else None,
                          "systematic_share": syst / total if total > 0 else None,
                          "unit": channel_unit(ch)}
    # by speed
    speeds = np.array([w.speed for w in windows])
    by_speed = []
    for s in np.unique(speeds):
        m = speeds == s
        for c, ch in enumerate(channels):
            v = R[m, c, :]
            by_speed.append({"speed_mps": float(s), "channel": ch,
                             "bias": float(np.nanmean(v)), "rms": float(np.sqrt(np.nanmean(v ** 2))),
                             "n_stances": int(m.sum())})
    # correlates: binned features vs binned normalised residual
    feats = ["depth", "sink_velocity", "rise_from_deepest", "sink_acceleration",
             "slip_velocity", "v_h", "v_l", "vc_z", "time_in_stance", "joint_speed",
             "trunk_speed", "grf_z", "x_position"]
    Fcube = np.empty((W, len(feats), B))
    for i, w in enumerate(windows):
        Fcube[i] = _bin_means(w, w.features, feats, edges)
    spd = np.repeat(speeds[:, None], B, axis=1)
    correlates = {}
    rng = np.random.default_rng(seed)
    for c, ch in enumerate(channels):
        y = (R[:, c, :] / sigma.get(ch, 1.0)).ravel()
        out = []
        for k, f in enumerate(feats + ["commanded_speed"]):
            x = (spd if f == "commanded_speed" else Fcube[:, k, :]).ravel()
            rho, p = _spearman(x, y)
            out.append({"feature": f, "spearman": rho, "p_value": p})
        m = np.isfinite(y)
        X = np.column_stack([(spd if f == "commanded_speed" else Fcube[:, k, :]).ravel()
                             for k, f in enumerate(feats + ["commanded_speed"])])
        m &= np.isfinite(X).all(axis=1)
        if m.sum() > 30:
            idx = np.flatnonzero(m)
            if idx.size > 3000:
                idx = rng.choice(idx, 3000, replace=False)
            mi = mutual_info_regression(X[idx], y[idx], random_state=seed)
            for e, v in zip(out, mi):
                e["mutual_information"] = float(v)
        out.sort(key=lambda e: -(abs(e["spearman"]) if e["spearman"] == e["spearman"] else 0))
        correlates[ch] = out
    # whiteness of the stance-to-stance sequence (per channel: stance-mean residual in
    # time order, trials concatenated)
    order = sorted(range(W), key=lambda i: (windows[i].trial, windows[i].row_start))
    whiteness = {}
    for c, ch in enumerate(channels):
        seq = np.array([np.nanmean(R[i, c, :]) for i in order])
        seq = seq[np.isfinite(seq)]
        lags = int(min(10, max(1, seq.size // 5)))
        if seq.size > lags + model_df + 2:
            lb = acorr_ljungbox(seq - seq.mean(), lags=[lags], model_df=min(model_df, lags - 1)
                                if lags > 1 else 0)
            whiteness[ch] = {"lags": lags, "q": float(lb["lb_stat"].iloc[0]),
                             "p_value": float(lb["lb_pvalue"].iloc[0])}
    return {"cells": cells, "significant_cells": sig[:40], "n_significant_cells": len(sig),
            "n_major_cells": int(sum(cl["major"] for cl in sig)),
            "by_channel": by_channel, "by_speed": by_speed, "correlates": correlates,
            "whiteness_stance_sequence": whiteness}


def _where_summary(loc: dict, top: int = 5) -> list[str]:
    lines = []
    seen = set()
    for cl in loc["significant_cells"]:
        key = cl["channel"]
        if key in seen:
            continue
        seen.add(key)
        cor = [e for e in loc["correlates"].get(key, []) if e.get("p_value") == e.get("p_value")
               and e["p_value"] is not None and e["p_value"] < 1e-3 and abs(e["spearman"]) >= 0.2]
        with_what = ", ".join(f"{e['feature']} (ρ = {e['spearman']:+.2f})" for e in cor[:3])
        side = "" if cl.get("side", "all") == "all" else f" ({cl['side']} stances)"
        lines.append(f"{key}: bias {cl['bias']:+.3g} {cl['unit']} at {cl['phase_lo']:g}–"
                     f"{cl['phase_hi']:g} % of stance{side} (t = {cl['t']:+.1f})"
                     + (f"; correlates with {with_what}" if with_what else ""))
        if len(lines) >= top:
            break
    return lines


# ======================================================================================
# diagnose
# ======================================================================================


@dataclass(frozen=True)
class Diagnosis:
    """What :func:`diagnose` found (``result`` is the content of ``diagnosis.json``)."""

    result: dict
    out_dir: Path | None
    figures: tuple = ()

    @property
    def verdict(self) -> dict:
        return self.result["verdict"]

    @property
    def ranking(self) -> list:
        return self.result["ranking"]

    @property
    def added(self) -> list[str]:
        return list(self.result["verdict"]["added"])


def _guard_jumps(S: np.ndarray, groups: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Finite-difference sensitivities S (W, C, B) without isolated jumps.

    A replay perturbed by one step can cross a contact event (a touchdown a sample earlier,
    a slip that starts or not) that the unperturbed replay does not: its difference is then
    a jump, not a derivative, and one such stance can dominate a group mean — seen as a
    50× vertical-force response to a sideways force term. Per channel, a stance whose RMS
    response exceeds JUMP_FACTOR × the median over all stances is replaced by the mean of
    its group's other stances (its trial and side), provided such stances are isolated
    (≤ JUMP_SHARE of all); a response that is large on many stances is left alone.

    Returns the guarded copy and the (stance, channel) pairs replaced.
    """
    out = np.array(S, dtype=float, copy=True)
    W, C, _ = out.shape
    replaced: list[tuple[int, int]] = []
    if W < 4:
        return out, replaced
    with np.errstate(invalid="ignore"):
        rms = np.sqrt(np.nanmean(out ** 2, axis=2))              # (W, C)
    for c in range(C):
        r = rms[:, c]
        med = float(np.nanmedian(r)) if np.isfinite(r).any() else 0.0
        if not med > 0.0:
            continue
        jump = np.flatnonzero(r > JUMP_FACTOR * med)
        if jump.size == 0 or jump.size > JUMP_SHARE * W:
            continue
        good = np.ones(W, bool)
        good[jump] = False
        for i in jump:
            peers = good & (groups == groups[i])
            if not peers.any():
                peers = good
            out[i, c] = np.nanmean(out[peers, c], axis=0)
            replaced.append((int(i), c))
    return out, replaced


def _group_keys(windows: Sequence[StanceWindow]) -> np.ndarray:
    """Stance groups of the systematic-structure rows: (trial, stance side)."""
    return np.array([f"{w.trial}|{w.side}" for w in windows])


def _sigma(R: np.ndarray, channels, groups: np.ndarray) -> dict:
    """Per channel: stance-to-stance scatter of the binned residual within groups."""
    sigma = {}
    for c, ch in enumerate(channels):
        var = []
        for g in np.unique(groups):
            v = R[groups == g, c, :]
            if v.shape[0] >= 2:
                var.append(np.nanvar(v, axis=0, ddof=1))
        s = float(np.sqrt(np.nanmean(np.concatenate(var)))) if var else float(np.nanstd(R[:, c]))
        sigma[ch] = s if s > 0 and math.isfinite(s) else 1.0
    return sigma


def _lag1_factor(Z: np.ndarray) -> float:
    """N_eff / N from the lag-1 autocorrelation along the phase bins of Z (rows, C, B)."""
    Zc = Z - np.nanmean(Z, axis=(0, 2), keepdims=True)
    a, b = Zc[:, :, 1:], Zc[:, :, :-1]
    m = np.isfinite(a) & np.isfinite(b)
    den = float(np.nansum(Zc ** 2))
    rho = float(np.sum(a[m] * b[m]) / den) if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.95)
    return (1.0 - rho) / (1.0 + rho)


def build_design(level: str, windows: Sequence[StanceWindow], R: np.ndarray,
                 sens: Mapping[str, np.ndarray], channels: Sequence[str], sigma: Mapping[str, float],
                 geo: Mapping[str, Any]) -> Design:
    """Weighted rows for the regression.

    ``level="stance"``: one row per stance × channel × phase bin (weight 1/σ_c).
    ``level="group"``: one row per (trial, side) group × channel × bin, the mean over the
    group's stances (weight √n_g/σ_c) — the *systematic* structure: random replay drift
    (noisy initial states) averages out, so a term that only damps that drift gains
    nothing here. Geometry rows (touchdown heights) are appended in both.
    """
    W, C, B = R.shape
    trials = np.array([w.trial for w in windows])
    sig = np.array([sigma[ch] for ch in channels])
    if level == "stance":
        keys = np.arange(W).astype(str)
        Rg = R
        cubes = dict(sens)
        scale = np.ones(W)
        gtrial = trials
        gwin = np.arange(W)
    else:
        gk = _group_keys(windows)
        keys = np.unique(gk)
        Rg = np.stack([np.nanmean(R[gk == k], axis=0) for k in keys])
        cubes = {c: np.stack([np.nanmean(S[gk == k], axis=0) for k in keys]) for c, S in sens.items()}
        scale = np.array([math.sqrt((gk == k).sum()) for k in keys])
        gtrial = np.array([k.split("|")[0] for k in keys])
        gwin = np.full(len(keys), -1)
    G = Rg.shape[0]
    w_idx = np.repeat(np.arange(G), C * B)
    ch_idx = np.tile(np.repeat(np.arange(C), B), G)
    b_idx = np.tile(np.arange(B), G * C)
    wvec = scale[w_idx] / sig[ch_idx]
    y = np.concatenate([Rg.ravel() * wvec, geo["y"] / geo["sigma"]])
    X = {}
    for k, S in cubes.items():
        g = geo["sens"].get(k, np.zeros(W))
        X[k] = np.concatenate([S.ravel() * wvec, g / geo["sigma"]])
    groups = np.concatenate([gtrial[w_idx], trials])
    Z = Rg * scale[:, None, None] / sig[None, :, None]
    return Design(y, X, groups, np.concatenate([gwin[w_idx], np.arange(W)]),
                  np.concatenate([np.array(channels)[ch_idx], np.full(W, "touchdown_z")]),
                  np.concatenate([b_idx, np.full(W, -1)]), dict(sigma) | {"touchdown_z": geo["sigma"]},
                  _lag1_factor(Z))


def diagnose(data_dir: str | Path, out_dir: str | Path | None = None, *,
             candidates: Sequence[str] | None = None, seed: int = 0,
             terrain: Any = "dry_sand", sim: SimConfig | None = None,
             workers: int | None = None, n_boot: int = 200, phase_bins: int = 10,
             max_effects: int = 2, refine_iterations: int = 2,
             calibrate_params: Sequence[str] = ("zeta",), max_contenders: int = 2,
             effect_files: Sequence[str | Path] = (), figures: bool = True) -> Diagnosis:
    """Calibrate the model on a data set, then find, rank and localise missing effects.

    Args:
        data_dir: measurement data set (format v1).
        out_dir: folder for ``diagnosis.json``, ``report.md`` and figures (None: none).
        candidates: effect names to test (default: every registered effect of any kind,
            built-in and user-registered).
        seed: seed of the bootstrap and of the mutual-information estimates.
        terrain: the model's terrain (name/path or config) before calibration.
        sim: plant settings of the replays.
        workers: processes for the replays (default: all CPUs).
        n_boot: bootstrap resamples (inclusion probability, intervals).
        phase_bins: stance-phase bins of the residual rows.
        max_effects: at most this many effects are added.
        refine_iterations: Gauss–Newton replay iterations for the added effects.
        max_contenders: significant candidates refined by replays before one is added
            (the linear screening can misorder strong, nonlinear effects).
        calibrate_params: terrain parameters calibrated and kept free (nuisance) in the
            regression: ``("zeta",)`` (default) or ``("zeta", "phi_s")``. φ_s is always
            estimated for the report (``calibration.free_phi_s``), but left free it trades
            off against depth-dependent effects (it shapes the capacity–depth curve), so
            by default the model keeps the terrain file's value.
        effect_files: user Python files registering effects (imported first; their
            effects become candidates).
        figures: write figures and the one-page report.

    Returns:
        :class:`Diagnosis`.
    """
    from ..robot.model import load_biped
    from ..terrain.effects import load_effect_file
    from ..terrain.effects_library import SensorContext, apply_sensor_effects
    from .calibrate import CAL_PARAMS, calibrate
    from .dataformat import load_dataset
    from .prepare import stance_windows

    t_start = _time.perf_counter()
    timing: dict[str, float] = {}
    for f in effect_files:
        load_effect_file(str(f))
    ds = load_dataset(data_dir)
    # checked before the replays, so that a bad folder does not cost the computation
    out = make_output_folder(out_dir) if out_dir is not None else None
    biped = load_biped(ds.meta.robot, with_visuals=False)
    names = sorted(all_effects()) if candidates is None else list(dict.fromkeys(candidates))
    infos = {n: effect_info(n) for n in names}
    infos = {n: i for n, i in infos.items() if i.neutral}      # needs a way to switch off
    cfg0 = model_terrain(terrain)
    terrain_names = [n for n, i in infos.items() if i.kind == "terrain_force"]
    rm0 = build_replay_model(biped, cfg0, sample_rate_hz=ds.meta.sample_rate_hz, sim=sim)
    windows = stance_windows(ds, biped, contact_stiffness=rm0.contact_stiffness)
    if len(windows) < 4:
        raise GranularMpcError(f"{data_dir}: {len(windows)} complete stance phases; the "
                               "diagnosis needs at least 4")
    timing["prepare"] = _time.perf_counter() - t_start
    J = list(ds.joint_names)
    channels = channel_names(J)
    edges = np.linspace(0.0, 100.0, phase_bins + 1)
    W = len(windows)
    trials = np.array([w.trial for w in windows])
    gkeys = _group_keys(windows)
    # ---------------------------------------------------------------- 1. calibrate
    t0 = _time.perf_counter()
    cal = calibrate(windows, rm0.terrain, n_slices=biped.config.foot.slices, seed=seed,
                    params=tuple(calibrate_params))
    cal_free = (calibrate(windows, rm0.terrain, n_slices=biped.config.foot.slices, seed=seed,
                          params=("zeta", "phi_s"))
                if "phi_s" not in calibrate_params else cal)
    rm = build_replay_model(biped, cfg0, sample_rate_hz=ds.meta.sample_rate_hz, sim=sim,
                            terrain_effects=terrain_names)
    pool = ReplayPool(rm, windows, workers=workers)
    theta = dict(cal.values)
    theta["touchdown_depth"] = 0.0

    def nuis_columns(th):
        cols = []
        if "zeta" in th:
            lo, hi = CAL_PARAMS["zeta"]
            cols.append(Column("calibration", "zeta", th["zeta"], 0.08 * th["zeta"], lo, hi))
        if "phi_s" in th:
            plo, phi = CAL_PARAMS["phi_s"]
            cols.append(Column("calibration", "phi_s", th["phi_s"], math.radians(3.0), plo, phi,
                               "rad"))
        cols.append(Column("calibration", "touchdown_depth", th.get("touchdown_depth", 0.0),
                           5e-4, -1e-3, 2e-3, "m"))
        return cols

    timing["calibrate"] = _time.perf_counter() - t0
    # ---------------------------------------------------------------- 2. replays
    # the calibrated model, its calibration sensitivities (nuisance columns, always in the
    # regression) and one replay per candidate column at its nominal magnitude
    t0 = _time.perf_counter()
    theta_cal = dict(theta)
    nuis_cols = nuis_columns(theta_cal)
    base = Variant(theta=dict(theta_cal), label="calibrated")
    variants = {"base": base}
    for col in nuis_cols:
        variants[col.key] = base.with_theta(**{col.param: col.neutral + col.step})
    cand_cols: dict[str, list[Column]] = {}
    for n, info in infos.items():
        cand_cols[n] = candidate_columns(info)
        if info.kind == "sensor":
            continue
        for col in cand_cols[n]:
            variants[col.key] = _variant_for(info, {col.param: col.neutral + col.step}, base)
    preds = pool.run(variants)
    timing["replays"] = _time.perf_counter() - t0
    t0 = _time.perf_counter()
    R = _residual_cube(windows, preds["base"], channels, edges)
    Pb = _pred_cube(windows, preds["base"], channels, edges)
    sens: dict[str, np.ndarray] = {c.key: (_pred_cube(windows, preds[c.key], channels, edges)
                                           - Pb) / c.step for c in nuis_cols}
    for n, cols in cand_cols.items():
        info = infos[n]
        for col in cols:
            if info.kind == "sensor":
                p = info.neutral_params()
                p[col.param] = col.neutral + col.step
                shifted = []
                for w, pr in zip(windows, preds["base"]):
                    ctx = SensorContext(np.full(w.n, w.side, dtype=object), w.time, tuple(J))
                    shifted.append(apply_sensor_effects({c: pr[c] for c in channels},
                                                        [(info, p)], ctx))
                sens[col.key] = (_pred_cube(windows, shifted, channels, edges) - Pb) / col.step
            else:
                sens[col.key] = (_pred_cube(windows, preds[col.key], channels, edges) - Pb) / col.step
    jumps: dict[str, list[str]] = {}
    for key in list(sens):
        sens[key], rep = _guard_jumps(sens[key], gkeys)
        if rep:
            jumps[key] = [f"window {i} ({windows[i].trial}, {windows[i].side}): {channels[c]}"
                          for i, c in rep]
    diverged = [w.index for w, p in zip(windows, preds["base"]) if p["diverged"]]
    sigma = _sigma(R, channels, gkeys)
    geo = _geometry_rows(windows, trials, cand_cols, infos)
    bounds = {c.key: (c.lower - c.neutral, c.upper - c.neutral) for c in nuis_cols}
    for cols in cand_cols.values():
        for col in cols:
            bounds[col.key] = (col.lower - col.neutral, col.upper - col.neutral)
    base_keys = [c.key for c in nuis_cols]
    cand_keys = {n: [c.key for c in cols] for n, cols in cand_cols.items()}
    n_trials = np.unique(trials).size
    group_unit = "trial" if n_trials >= 3 else "stance"

    def make_reg(R_, sens_, geo_, bounds_, keys_):
        """Systematic rows (stance-averaged per trial and side) scored also stance by
        stance; with fewer than 3 trials, stances are the units (no averaging)."""
        d_s = build_design("stance", windows, R_, sens_, channels, sigma, geo_)
        if group_unit == "stance":
            d_s.groups = d_s.window.astype(str)
            return Regression(d_s, bounds_, keys_, stance_design=d_s, seed=seed), d_s, d_s
        d_g = build_design("group", windows, R_, sens_, channels, sigma, geo_)
        return Regression(d_g, bounds_, keys_, stance_design=d_s, seed=seed), d_g, d_s

    reg, d_grp, d_stn = make_reg(R, sens, geo, bounds, base_keys)
    timing["design"] = _time.perf_counter() - t0
    # ---------------------------------------------------------------- 3. rank, add, refine
    t0 = _time.perf_counter()
    ranking = _candidate_stats(reg, base_keys, cand_keys, cand_cols, infos, n_boot=n_boot,
                               seed=seed, max_effects=max_effects)
    indist = _indistinguishable(reg, base_keys, cand_keys, ranking, windows, infos,
                                Regression(d_stn, bounds, base_keys, seed=seed))
    timing["rank"] = _time.perf_counter() - t0
    t0 = _time.perf_counter()
    selected: list[str] = []
    fitted: dict[str, dict[str, float]] = {}
    steps_log: list[dict] = []
    final_preds = preds["base"]
    theta_final = dict(theta_cal)
    stats = ranking
    sens_sel: dict[str, np.ndarray] = {}
    R_cur = R
    n_nuis = len(base_keys)

    def refined_score(fit_, preds_, sel_):
        """AICc of the stance-averaged weighted residual of a refined (replayed) model."""
        R_ = _residual_cube(windows, preds_, channels, edges)
        gy = geo["y"].copy()
        for s_ in sel_:
            for c in cand_cols[s_]:
                if c.key in geo["sens"]:
                    gy = gy - geo["sens"][c.key] * (fit_[s_][c.param] - c.neutral)
        d_ = make_reg(R_, {}, {"y": gy, "sigma": geo["sigma"], "sens": {}}, {}, [])[1]
        y_ = d_.y[np.isfinite(d_.y)]
        k_ = n_nuis + sum(len(cand_cols[s_]) for s_ in sel_)
        return _aicc(float(y_ @ y_), y_.size * d_.n_eff_factor, k_), float(y_ @ y_)

    while len(selected) < max_effects:
        contenders = [r for r in stats if r["significant"] and r["effect"] not in selected]
        contenders = contenders[:max_contenders]
        if not contenders:
            break
        prev_vals = {(s_, c.param): fitted[s_][c.param] for s_ in selected
                     for c in cand_cols[s_]}
        trials_ = []
        for r in contenders:
            start_vals = dict(prev_vals)
            for p_, v in r["params"].items():
                start_vals[(r["effect"], p_)] = float(v["value"])
            sel_ = selected + [r["effect"]]
            its = 1 if len(contenders) > 1 else refine_iterations
            res_ = _refine(pool, base, windows, channels, edges, sigma, sel_, cand_cols, infos,
                           start_vals, nuis_columns(theta_final), sens, geo, iterations=its)
            score, rss = refined_score(res_[0], res_[2], sel_)
            trials_.append((score, r, res_, its))
            for e in ranking:
                if e["effect"] == r["effect"]:
                    e.setdefault("refined_fits", []).append(
                        {"given": list(selected), "aicc": score, "weighted_rss": rss,
                         "params": res_[0][r["effect"]]})
        trials_.sort(key=lambda t: t[0])
        score, best, res_, its = trials_[0]
        selected.append(best["effect"])
        if its < refine_iterations:          # finish the winner's refinement
            start_vals = {(s_, c.param): res_[0][s_][c.param] for s_ in selected
                          for c in cand_cols[s_]}
            res_ = _refine(pool, base, windows, channels, edges, sigma, selected, cand_cols,
                           infos, start_vals, nuis_columns(res_[1]), sens, geo,
                           iterations=refine_iterations - its)
        fitted, theta_final, final_preds, log, sens_sel = res_
        steps_log.append({"added": best["effect"], "contenders": [t[1]["effect"] for t in trials_],
                          "contender_aicc": [t[0] for t in trials_], "refine": log})
        if len(selected) >= max_effects:
            break
        # conditional test of the others against the refined model (linearised around it)
        R_cur = _residual_cube(windows, final_preds, channels, edges)
        sens_c = dict(sens)
        sens_c.update(sens_sel)
        geo_c = dict(geo)
        gy = geo["y"].copy()
        for s_ in selected:
            for c in cand_cols[s_]:
                if c.key in geo["sens"]:
                    gy = gy - geo["sens"][c.key] * (fitted[s_][c.param] - c.neutral)
        geo_c["y"] = gy
        b_c = dict(bounds)
        for s_ in selected:
            for c in cand_cols[s_]:
                cur = fitted[s_][c.param]
                b_c[c.key] = (c.lower - cur, c.upper - cur)
        nk = nuis_columns(theta_final)
        for c in nk:
            b_c[c.key] = (c.lower - c.neutral, c.upper - c.neutral)
        keys_fixed = base_keys + [k for s_ in selected for k in cand_keys[s_]]
        reg_c = make_reg(R_cur, sens_c, geo_c, b_c, keys_fixed)[0]
        rest = {n: k for n, k in cand_keys.items() if n not in selected}
        stats = _candidate_stats(reg_c, keys_fixed, rest, cand_cols, infos, n_boot=n_boot,
                                 seed=seed, max_effects=max_effects - len(selected))
        steps_log[-1]["conditional"] = [{k: r[k] for k in ("effect", "heldout_error_reduction",
                                                           "heldout_error_reduction_stance",
                                                           "delta_aicc", "inclusion_probability",
                                                           "effect_size", "significant")}
                                        for r in stats]
        for r in stats:
            for e in ranking:
                if e["effect"] == r["effect"]:
                    e.setdefault("conditional", []).append(
                        {"given": list(selected), "heldout_error_reduction":
                         r["heldout_error_reduction"], "significant": r["significant"]})
    for e in ranking:
        e["added"] = e["effect"] in selected
        e["linear_rank"] = e["rank"]
        if e["effect"] in fitted:
            e["refined_params"] = fitted[e["effect"]]
    # final order: the added effects (in the order the refined fits chose them), then the
    # others by their screening held-out error reduction
    order = {n: i for i, n in enumerate(selected)}
    ranking.sort(key=lambda e: (order.get(e["effect"], len(order)), e["linear_rank"]))
    for i, e in enumerate(ranking):
        e["rank"] = i + 1
    # held-out statistics of the added effects along the secant from the calibrated to the
    # refined model (both replayed): exact at both ends, linear in between
    refined_cv: dict = {}
    if selected:
        R_fin = _residual_cube(windows, final_preds, channels, edges)
        sens_f = dict(sens)
        sens_f["secant"] = R - R_fin                  # prediction change base → final
        g_sec = np.zeros(len(windows))
        for s_ in selected:
            for c in cand_cols[s_]:
                if c.key in geo["sens"]:
                    g_sec = g_sec + geo["sens"][c.key] * (fitted[s_][c.param] - c.neutral)
        geo_f = {"y": geo["y"], "sigma": geo["sigma"], "sens": {"secant": g_sec}}
        b_f = dict(bounds)
        b_f["secant"] = (0.0, 2.0)
        reg_f = make_reg(R, sens_f, geo_f, b_f, base_keys)[0]
        cv0, cv1 = reg_f.cv(base_keys), reg_f.cv(base_keys + ["secant"])
        refined_cv = {
            "heldout_error_reduction": 1.0 - cv1["sse"] / cv0["sse"] if cv0["sse"] > 0 else 0.0,
            "heldout_error_reduction_stance": (1.0 - cv1["sse_stance"] / cv0["sse_stance"]
                                               if cv0["sse_stance"] > 0 else 0.0),
            "by_channel": _channel_heldout(reg_f, base_keys, ["secant"], channels, stance=True),
            "note": "trial-grouped CV: the magnitude of the added effects (a scalar along the "
                    "replayed change from the calibrated to the refined model) and the "
                    "calibration are fitted on the training trials, the RMSE is scored on "
                    "the held-out trials, stance by stance"}
    timing["refine"] = _time.perf_counter() - t0
    pool.close()
    # ---------------------------------------------------------------- 4. localise
    t0 = _time.perf_counter()
    # the calibrated model as the regression sees it: the calibration re-fitted linearly
    beta_n, _ = reg.fit(base_keys)
    R_cal = R - sum(b * sens[k] for k, b in zip(base_keys, beta_n))
    theta_lin = {c.param: float(c.neutral + b) for c, b in zip(nuis_cols, beta_n)}
    if not selected:
        theta_final = theta_lin
    loc_before = localize(windows, R_cal, channels, edges, sigma, model_df=len(base_keys),
                          seed=seed)
    R_after = _residual_cube(windows, final_preds, channels, edges) if selected else R_cal
    n_fit = len(base_keys) + sum(len(cand_keys[s]) for s in selected)
    loc_after = localize(windows, R_after, channels, edges, sigma, model_df=n_fit, seed=seed)
    timing["localize"] = _time.perf_counter() - t0
    # ---------------------------------------------------------------- verdict
    unexplained = loc_after["n_major_cells"]
    if selected:
        status = "missing_effect"
        text = ("missing effect" + ("s" if len(selected) > 1 else "") + ": "
                + "; ".join(_effect_sentence(e) for e in ranking if e["effect"] in selected)
                + f"; refined fit: held-out error −"
                  f"{100 * refined_cv.get('heldout_error_reduction', 0.0):.1f} % (stance-averaged), "
                  f"−{100 * refined_cv.get('heldout_error_reduction_stance', 0.0):.1f} % "
                  "(stance by stance)")
        if unexplained:
            text += (f". After adding {', '.join(selected)}, {unexplained} channel × phase "
                     "cells still show structure (see localization.after)")
    elif unexplained:
        status = "unexplained_structure"
        text = ("no candidate effect explains the residual structure; it is localised in: "
                + " | ".join(_where_summary(loc_after, 4)))
    else:
        status = "no_significant_missing_effect"
        text = ("no significant missing effect: no candidate passes the held-out, AICc and "
                "bootstrap tests, and no channel × phase cell shows a systematic residual "
                f"larger than {MAJOR_BIAS:g} × the stance-to-stance scatter")
        if loc_after["n_significant_cells"]:
            text += (f" ({loc_after['n_significant_cells']} cells are statistically but not "
                     "practically significant, see localization)")
    channel_red = refined_cv.get("by_channel", {})
    replay_rmse = _replay_rmse(windows, preds["base"], final_preds, channels) if selected else {}
    cal_json = cal.to_json()
    cal_json["equation_error_values"] = dict(cal.values)
    cal_json["free_phi_s"] = {k: v for k, v in cal_free.to_json().items() if k != "method"}
    cal_json["values"] = dict(theta_final)
    cal_json["replay_refined"] = {
        "values": theta_final,
        "linear_values": theta_lin,
        "method": "the calibration's sensitivity columns (ζ, φ_s and the touchdown depth) are "
                  "fitted with the candidates on the stance-averaged replay residuals; with "
                  "added effects, jointly refined by Gauss–Newton replays"}
    cal_json["values_readable"] = {("phi_s_deg" if k == "phi_s" else k):
                                   (math.degrees(v) if k == "phi_s" else v)
                                   for k, v in theta_final.items()}
    result = {
        "data": str(data_dir),
        "verdict": {"status": status, "text": text, "added": list(selected),
                    "thresholds": {"min_heldout_error_reduction": MIN_HELDOUT_REDUCTION,
                                   "min_heldout_error_reduction_stance": MIN_STANCE_REDUCTION,
                                   "min_effect_size_sigma": MIN_EFFECT_SIZE,
                                   "or_min_heldout_error_reduction": LARGE_HELDOUT_REDUCTION,
                                   "max_delta_aicc": MAX_DELTA_AICC,
                                   "min_inclusion_probability": MIN_INCLUSION,
                                   "cell_t": T_CELL}},
        "calibration": cal_json,
        "ranking": ranking,
        "indistinguishable": indist,
        "fitted_effects": fitted,
        "heldout_reduction_by_channel": channel_red,
        "refined_heldout": refined_cv,
        "replay_rmse_by_channel": replay_rmse,
        "localization": {"where": _where_summary(loc_before, 6), "before": loc_before,
                         "after": loc_after, "unexplained_where": _where_summary(loc_after, 6),
                         "n_significant_cells_before": loc_before["n_significant_cells"],
                         "n_significant_cells_after": loc_after["n_significant_cells"],
                         "n_major_cells_before": loc_before["n_major_cells"],
                         "n_major_cells_after": unexplained},
        "design": {"n_stances": W, "n_trials": int(n_trials), "channels": channels,
                   "phase_bins": phase_bins, "rows_systematic": int(reg.y.size),
                   "rows_stance": int(reg.st[1].size),
                   "n_eff_factor": {"systematic": d_grp.n_eff_factor, "stance": d_stn.n_eff_factor},
                   "sigma": d_grp.sigma, "cv_groups": group_unit,
                   "cv_folds": len(reg.splits), "diverged_stances": diverged,
                   "sensitivity_jumps_replaced": jumps,
                   "candidates": {n: infos[n].kind for n in infos},
                   "replays": pool.n_replays, "steps": steps_log},
        "recommended": _recommend(theta_final, fitted),
    }
    timing["total"] = _time.perf_counter() - t_start
    result["timing_s"] = timing
    figs: list[Path] = []
    if out is not None:
        if figures:
            figs = _figures(out, loc_before, loc_after, ranking, channels, edges, R, R_after,
                            windows, selected)
        result["figures"] = [p.name for p in figs]
        (out / "diagnosis.json").write_text(json.dumps(json_safe(result), indent=1),
                                            encoding="utf-8")
        (out / "report.md").write_text(_markdown(result, figs), encoding="utf-8")
    return Diagnosis(result, out, tuple(figs))


def _geometry_rows(windows, trials, cand_cols, infos) -> dict:
    """Touchdown heights (one free surface height per trial) and the geometry
    candidates' predicted change of them."""
    W = len(windows)
    td = np.array([w.touchdown_W for w in windows])
    gy, gx, gyy = np.zeros(W), np.zeros(W), np.zeros(W)
    for t in np.unique(trials):
        m = trials == t
        gy[m] = td[m, 2] - td[m, 2].mean()
        gx[m] = td[m, 0] - td[m, 0].mean()
        gyy[m] = td[m, 1] - td[m, 1].mean()
    A = np.column_stack([gx, gyy])
    res = gy - A @ np.linalg.lstsq(A, gy, rcond=None)[0] if W > 3 else gy
    sig = float(1.4826 * np.median(np.abs(res - np.median(res)))) or 1e-3
    sens = {}
    for n, cols in cand_cols.items():
        info = infos[n]
        for col in cols:
            if info.kind != "geometry":
                continue
            p0 = info.neutral_params()
            p1 = dict(p0)
            p1[col.param] = col.neutral + col.step
            th0, th1 = info.fn(p0), info.fn(p1)

            def height(th):
                return (th.get("surface_height", 0.0) + th.get("surface_slope_x", 0.0) * gx
                        + th.get("surface_slope_y", 0.0) * gyy)
            sens[col.key] = (height(th1) - height(th0)) / col.step
    return {"y": gy, "sigma": max(sig, 1e-4), "sens": sens}


# ======================================================================================
# Ranking helpers
# ======================================================================================


def _practically_large(row: Mapping[str, Any]) -> bool:
    """Whether a statistically supported candidate also matters in practice: it removes
    ≥ LARGE_HELDOUT_REDUCTION of the held-out (trial-grouped, stance-averaged) error, or it
    moves some channel × phase mean by ≥ MIN_EFFECT_SIZE σ *and* its fit helps held-out
    stances one by one (≥ MIN_STANCE_REDUCTION). The stance score uses each stance's own
    finite-difference sensitivities, which carry the open-loop replays' chaotic noise: for
    a true sideways term with half the held-out error to remove it measured −3 %, so a
    large held-out reduction does not need it. Without stance rows (the stance score is
    then 0) only the held-out test can pass."""
    if row["heldout_error_reduction"] >= LARGE_HELDOUT_REDUCTION:
        return True
    return bool(not row["effect_size"] < MIN_EFFECT_SIZE
                and row["heldout_error_reduction_stance"] >= MIN_STANCE_REDUCTION)


def _candidate_stats(reg: Regression, base_keys, cand_keys, cand_cols, infos, *, n_boot,
                     seed, max_effects, values_now=None) -> list[dict]:
    """Statistics of every candidate in ``cand_keys`` against the model ``base_keys``:
    held-out error reduction (systematic rows; stance rows under the same fit), ΔAICc,
    bootstrap inclusion probability, fitted parameters with intervals, significance."""
    cv0 = reg.cv(base_keys)
    a0 = reg.aicc(base_keys)
    rows = []
    for n, keys in cand_keys.items():
        cv = reg.cv(base_keys + keys)
        beta, _ = reg.fit(base_keys + keys)
        cov = reg.covariance(base_keys + keys, beta)
        params = {}
        for k, col in enumerate(cand_cols[n]):
            j = len(base_keys) + k
            se = float(math.sqrt(cov[j, j])) if np.isfinite(cov[j, j]) and cov[j, j] >= 0 else None
            val = col.neutral + float(beta[j])
            params[col.param] = {"value": val, "se": se,
                                 "ci_lo": None if se is None else val - 1.96 * se,
                                 "ci_hi": None if se is None else val + 1.96 * se,
                                 "unit": col.unit, "neutral": col.neutral,
                                 "lower": col.lower, "upper": col.upper,
                                 "at_bound": bool(np.isclose(val, col.lower) or np.isclose(val, col.upper))}
        improved = sum(1 for f0, f1 in zip(cv0["folds"], cv["folds"]) if f1 < f0)
        size = reg.practical_size(keys, beta[len(base_keys):])
        red_st = (1.0 - cv["sse_stance"] / cv0["sse_stance"]
                  if cv0["sse_stance"] == cv0["sse_stance"] and cv0["sse_stance"] > 0 else 0.0)
        rows.append({"effect": n, "kind": infos[n].kind,
                     "heldout_error_reduction": 1.0 - cv["sse"] / cv0["sse"] if cv0["sse"] > 0 else 0.0,
                     "heldout_error_reduction_stance": red_st,
                     "delta_aicc": reg.aicc(base_keys + keys) - a0,
                     "folds_improved": f"{improved}/{len(cv['folds'])}",
                     "effect_size": size,
                     "params": params, "main": infos[n].main,
                     "depends_on": list(infos[n].depends_on), "doc": infos[n].summary})
    # bootstrap inclusion probability: forward selection by AICc on resamples of trials
    rng = np.random.default_rng(seed)
    gs = np.unique(reg.groups)
    members = {g: np.flatnonzero(reg.groups == g) for g in gs}
    counts = {n: 0 for n in cand_keys}
    boot_params: dict[str, list] = {n: [] for n in cand_keys}
    B = int(n_boot) if gs.size >= 2 else 0
    for _ in range(B):
        pick = rng.choice(gs, gs.size, replace=True)
        rws = np.concatenate([members[g] for g in pick])
        for n in _forward(reg, cand_keys, base_keys, rws, max_terms=max_effects):
            counts[n] += 1
        for n, keys in cand_keys.items():
            beta, _ = reg.fit(base_keys + keys, rws)
            boot_params[n].append(beta[len(base_keys):])
    for r in rows:
        n = r["effect"]
        r["inclusion_probability"] = counts[n] / B if B else None
        bp = np.array(boot_params[n]) if boot_params[n] else None
        for k, col in enumerate(cand_cols[n]):
            if bp is not None and len(bp):
                vals = col.neutral + bp[:, k]
                r["params"][col.param]["boot_ci_lo"] = float(np.percentile(vals, 2.5))
                r["params"][col.param]["boot_ci_hi"] = float(np.percentile(vals, 97.5))
        r["significant"] = bool(r["heldout_error_reduction"] >= MIN_HELDOUT_REDUCTION
                                and r["delta_aicc"] <= MAX_DELTA_AICC
                                and _practically_large(r)
                                and (r["inclusion_probability"] if B else 1.0) >= MIN_INCLUSION)
    rows.sort(key=lambda r: -r["heldout_error_reduction"])
    for i, r in enumerate(rows):
        r["rank"] = i + 1
    return rows


def _indistinguishable(reg: Regression, base_keys, cand_keys, ranking, windows, infos,
                       reg_st: Regression):
    """Pairs of leading candidates whose fitted contributions are nearly collinear."""
    if not ranking or ranking[0]["heldout_error_reduction"] <= 0:
        return []
    top = ranking[0]
    contenders = [r for r in ranking[1:6]
                  if r["heldout_error_reduction"] >= 0.5 * top["heldout_error_reduction"]]
    Xn, _, _ = reg.matrix(base_keys)

    def contribution(name):
        keys = base_keys + cand_keys[name]
        beta, _ = reg.fit(keys)
        X, _, _ = reg.matrix(cand_keys[name])
        v = X @ beta[len(base_keys):]
        if Xn.shape[1]:
            v = v - Xn @ np.linalg.lstsq(Xn, v, rcond=None)[0]
        return v

    v0 = contribution(top["effect"])
    out = []
    for r in contenders:
        v1 = contribution(r["effect"])
        den = float(np.linalg.norm(v0) * np.linalg.norm(v1))
        corr = float(v0 @ v1 / den) if den > 0 else 0.0
        if abs(corr) >= 0.9:
            out.append({"effects": [top["effect"], r["effect"]], "correlation": corr,
                        "heldout_error_reduction": [top["heldout_error_reduction"],
                                                    r["heldout_error_reduction"]],
                        "experiment": _separating_experiment(top["effect"], r["effect"], reg_st,
                                                             cand_keys, windows, infos)})
    return out


def _separating_experiment(a: str, b: str, reg: Regression, cand_keys, windows,
                           infos) -> str:
    """The measured variable along which the two candidates' columns differ most
    (stance-level rows: rank correlation of |column| with each binned feature)."""
    ok = reg.ok
    wid = reg.d.window[ok]
    pb = reg.d.phase_bin[ok]
    Xa, _, _ = reg.matrix(cand_keys[a])
    Xb, _, _ = reg.matrix(cand_keys[b])
    va, vb = np.abs(Xa).sum(axis=1), np.abs(Xb).sum(axis=1)
    edges = np.linspace(0, 100, int(max(pb.max(), 0)) + 2)
    best, gap = None, 0.0
    for f in FEATURE_EXPERIMENTS:
        x = np.full(va.size, np.nan)
        for i, w in enumerate(windows):
            m = (wid == i) & (pb >= 0)
            if not m.any():
                continue
            if f == "commanded_speed":
                x[m] = w.speed
            elif f in w.features:
                vals = _bin_means(w, w.features, [f], edges)[0]
                x[m] = vals[np.clip(pb[m], 0, vals.size - 1)]
        ra, _ = _spearman(x, va)
        rb, _ = _spearman(x, vb)
        if ra == ra and rb == rb and abs(ra - rb) > gap:
            best, gap = f, abs(ra - rb)
    da = ", ".join(infos[a].depends_on) or "its own signature"
    db = ", ".join(infos[b].depends_on) or "its own signature"
    where = FEATURE_EXPERIMENTS.get(best, "a wider range of conditions") if best else \
        "a wider range of speeds and depths"
    return (f"{a} scales with {da}; {b} with {db}. In this data their effects differ most "
            f"along '{best}'; an experiment with {where} would separate them.")


def _dominant(e: dict) -> str:
    """The fitted parameter furthest from its neutral value (relative to its range)."""
    fit = e.get("refined_params", {})

    def dist(p):
        v = e["params"][p]
        val = fit.get(p, v["value"])
        return abs(val - v["neutral"]) / max(v.get("upper", 1.0) - v.get("lower", 0.0), 1e-12)

    return max(e["params"], key=dist) if e["params"] else e["main"]


def _effect_sentence(e: dict) -> str:
    main = _dominant(e)
    p = e.get("refined_params", {}).get(main, e["params"].get(main, {}).get("value"))
    unit = e["params"].get(main, {}).get("unit", "")
    inc = e["inclusion_probability"]
    return (f"{e['effect']} ({e['kind']}; {main} = {p:.4g} {unit}; screening: held-out "
            f"error −{100 * e['heldout_error_reduction']:.1f} %, ΔAICc {e['delta_aicc']:.0f}, "
            f"inclusion {'–' if inc is None else f'{inc:.2f}'})")


def _channel_heldout(reg: Regression, base_keys, add_keys, channels, *, stance: bool) -> dict:
    """Per channel: held-out (trial-grouped CV) RMS of the residual before and after adding
    ``add_keys`` (linearised; fitted on the systematic rows of the training trials), on the
    stance rows (``stance``) or the stance-averaged rows, in channel units."""
    if stance and reg.st is None:
        return {}
    chan = (reg.d.channel[reg.ok] if not stance else None)
    if stance:
        # the stance design's channel labels
        chan = reg._st_channel
    before = {c: 0.0 for c in list(channels) + ["touchdown_z"]}
    after = dict(before)
    count = dict(before)
    X0, lb0, ub0 = reg.matrix(base_keys)
    X1, lb1, ub1 = reg.matrix(base_keys + add_keys)
    if stance:
        X0s, _, _ = reg.matrix(base_keys, cols=reg.st[2])
        X1s, _, _ = reg.matrix(base_keys + add_keys, cols=reg.st[2])
    for k, (tr, te) in enumerate(reg.splits):
        b0 = _fit(X0[tr], reg.y[tr], lb0, ub0)
        b1 = _fit(X1[tr], reg.y[tr], lb1, ub1)
        if stance:
            ste = reg.st_splits[k]
            y = reg.st[1][ste]
            r0, r1 = y - X0s[ste] @ b0, y - X1s[ste] @ b1
            labels = chan[ste]
        else:
            r0, r1 = reg.y[te] - X0[te] @ b0, reg.y[te] - X1[te] @ b1
            labels = chan[te]
        for c in before:
            m = labels == c
            before[c] += float(r0[m] @ r0[m])
            after[c] += float(r1[m] @ r1[m])
            count[c] += int(m.sum())
    out = {}
    for c in before:
        if count[c] == 0 or before[c] <= 0:
            continue
        s = reg.d.sigma.get(c, 1.0)
        rb = s * math.sqrt(before[c] / count[c])
        ra = s * math.sqrt(after[c] / count[c])
        out[c] = {"before": rb, "after": ra, "reduction": 1.0 - ra / rb,
                  "unit": channel_unit(c) if c != "touchdown_z" else "m"}
    return out


def _refine(pool, base: Variant, windows, channels, edges, sigma, selected, cand_cols, infos,
            start_values, nuis_cols, sens, geo, *, iterations: int):
    """Gauss–Newton on the replays for the selected effects' magnitude columns (and the
    calibration), on the stance-averaged rows: the sensitivities are recomputed at the
    current values (a secant of 25 % of the current magnitude).

    Returns:
        (fitted parameters per effect, calibration θ, final predictions, log, the
        sensitivities of the selected columns at the last iteration).
    """
    cols = [c for s in selected for c in cand_cols[s]]
    values = {(c.candidate, c.param): float(start_values.get((c.candidate, c.param), c.neutral))
              for c in cols}
    theta_nuis = {c.param: c.neutral for c in nuis_cols}
    S_sel: dict[str, np.ndarray] = {}
    log = []
    gkeys = _group_keys(windows)

    def variant_with(vals, nuis):
        specs = []
        for s in selected:
            info = infos[s]
            p = info.neutral_params()
            for c in cand_cols[s]:
                p[c.param] = vals[(s, c.param)]
            specs.append((info, p))
        return effect_variant(specs, Variant(theta={**base.theta, **nuis}))

    final = None
    for it in range(max(1, iterations)):
        variants = {"cur": variant_with(values, theta_nuis)}
        steps = {}
        for c in cols:
            v = dict(values)
            cur = v[(c.candidate, c.param)]
            step = 0.25 * (cur - c.neutral) if abs(cur - c.neutral) > 1e-9 else c.step
            if not (c.lower <= cur + step <= c.upper):
                step = -step
            v[(c.candidate, c.param)] = cur + step
            steps[c.key] = (step, v)
            if infos[c.candidate].kind != "sensor":
                variants[c.key] = variant_with(v, theta_nuis)
        out = pool.run(variants)
        cur_preds = out["cur"]
        Rc = _residual_cube(windows, cur_preds, channels, edges)
        Pc = _pred_cube(windows, cur_preds, channels, edges)
        S = {}
        for c in cols:
            step, v = steps[c.key]
            if infos[c.candidate].kind == "sensor":
                S[c.key] = sens[c.key]       # a measurement map: its base sensitivity
            else:
                S[c.key] = _guard_jumps((_pred_cube(windows, out[c.key], channels, edges)
                                         - Pc) / step, gkeys)[0]
        S_sel = {c.key: S[c.key] for c in cols}
        for c in nuis_cols:
            S[c.key] = sens[c.key]
        # geometry rows at the current values (linear in the geometry parameters)
        gy = geo["y"].copy()
        for c in cols:
            if c.key in geo["sens"]:
                gy = gy - geo["sens"][c.key] * (values[(c.candidate, c.param)] - c.neutral)
        d = build_design("group", windows, Rc, S, channels, sigma,
                         {"y": gy, "sigma": geo["sigma"], "sens": geo["sens"]})
        keys = [c.key for c in nuis_cols] + [c.key for c in cols]
        A = np.column_stack([d.X[k] for k in keys])
        ok = np.isfinite(d.y) & np.isfinite(A).all(axis=1)
        lb, ub = [], []
        for c in nuis_cols:
            lb.append(c.lower - theta_nuis[c.param])
            ub.append(c.upper - theta_nuis[c.param])
        for c in cols:
            cur = values[(c.candidate, c.param)]
            lb.append(c.lower - cur)
            ub.append(c.upper - cur)
        delta = _fit(A[ok], d.y[ok], np.array(lb), np.array(ub))
        log.append({"iteration": it + 1, "weighted_rss_before": float(np.sum(d.y[ok] ** 2)),
                    "weighted_rss_linear_after": float(np.sum((d.y[ok] - A[ok] @ delta) ** 2)),
                    "values": {f"{a}.{b}": v for (a, b), v in values.items()}})
        for c, dlt in zip(nuis_cols, delta[:len(nuis_cols)]):
            theta_nuis[c.param] = float(np.clip(theta_nuis[c.param] + dlt, c.lower, c.upper))
        for c, dlt in zip(cols, delta[len(nuis_cols):]):
            values[(c.candidate, c.param)] = float(np.clip(
                values[(c.candidate, c.param)] + dlt, c.lower, c.upper))
    final = pool.run({"final": variant_with(values, theta_nuis)})["final"]
    log.append({"iteration": "final", "values": {f"{a}.{b}": v for (a, b), v in values.items()},
                "calibration": dict(theta_nuis)})
    fitted: dict[str, dict[str, float]] = {}
    for s in selected:
        p = infos[s].neutral_params()
        for c in cand_cols[s]:
            p[c.param] = values[(s, c.param)]
        fitted[s] = p
    return fitted, theta_nuis, final, log, S_sel


def _replay_rmse(windows, before, after, channels) -> dict:
    """RMSE of the raw samples (all stances) of the calibrated and the final model."""
    out = {}
    for c in channels:
        e0 = np.concatenate([w.meas[c] - np.asarray(p[c], float) for w, p in zip(windows, before)])
        e1 = np.concatenate([w.meas[c] - np.asarray(p[c], float) for w, p in zip(windows, after)])
        r0 = float(np.sqrt(np.nanmean(e0 ** 2)))
        r1 = float(np.sqrt(np.nanmean(e1 ** 2)))
        out[c] = {"before": r0, "after": r1, "reduction": 1.0 - r1 / r0 if r0 > 0 else 0.0,
                  "unit": channel_unit(c)}
    return out


def _recommend(theta: Mapping[str, float], fitted: Mapping[str, Mapping[str, float]]) -> dict:
    eff = [f"{n}:" + ",".join(f"{k}={v:.6g}" for k, v in p.items()) for n, p in fitted.items()]
    params = dict(theta)
    return {"effects": eff, "calibrated_params": params,
            "validate_command": ("granular-mpc validate DATA --params DIAG_DIR/diagnosis.json "
                                 + " ".join(f"--effect {n}" for n in fitted)).strip()}


# ======================================================================================
# Report
# ======================================================================================


def _figures(out: Path, loc_before, loc_after, ranking, channels, edges, R, R_after, windows,
             selected) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    paths = []
    # 1. t-statistics heatmap before / after
    fig = Figure(figsize=(11, 5), constrained_layout=True)
    axes = fig.subplots(1, 2)
    for ax, loc, title in ((axes[0], loc_before, "calibrated model"),
                           (axes[1], loc_after, "after added effects" if selected
                            else "(nothing added)")):
        T = np.zeros((len(channels), len(edges) - 1))
        for cl in loc["cells"]:
            if cl.get("side", "all") != "all":
                continue
            c = channels.index(cl["channel"])
            b = int(np.searchsorted(edges, cl["phase_lo"] + 1e-9) - 1)
            T[c, b] = cl["t"]
        lim = max(T_CELL * 2, float(np.nanmax(np.abs(T))) if T.size else 1.0)
        im = ax.imshow(T, aspect="auto", cmap="RdBu_r", vmin=-lim, vmax=lim)
        ax.set_yticks(range(len(channels)), labels=channels, fontsize=7)
        ax.set_xticks(range(len(edges) - 1), labels=[f"{edges[i]:g}" for i in range(len(edges) - 1)],
                      fontsize=7)
        ax.set_xlabel("stance phase bin start [%]")
        ax.set_title(f"residual bias t-statistic: {title}", fontsize=9)
    fig.colorbar(im, ax=axes, label="t (|t| ≥ %g: structure)" % T_CELL)
    p = out / "residual_tstat.png"
    fig.savefig(p, dpi=110)
    paths.append(p)
    # 2. ranking
    fig = Figure(figsize=(7, 0.35 * max(len(ranking), 3) + 1.2), constrained_layout=True)
    ax = fig.subplots()
    names = [r["effect"] for r in ranking][::-1]
    vals = [100 * r["heldout_error_reduction"] for r in ranking][::-1]
    colors = ["tab:green" if r["added"] else ("tab:orange" if r["significant"] else "tab:gray")
              for r in ranking][::-1]
    ax.barh(names, vals, color=colors)
    ax.axvline(100 * MIN_HELDOUT_REDUCTION, color="k", ls="--", lw=0.8)
    ax.set_xlabel("held-out error reduction [%] (green: added)")
    ax.set_title("candidate effects, trial-grouped cross-validation", fontsize=9)
    p = out / "ranking.png"
    fig.savefig(p, dpi=110)
    paths.append(p)
    # 3. mean residual profiles of the most structured channels, before / after
    top = []
    for cl in loc_before["significant_cells"]:
        if cl["channel"] not in top:
            top.append(cl["channel"])
        if len(top) == 4:
            break
    if not top:
        top = channels[:4]
    fig = Figure(figsize=(10, 2.6 * ((len(top) + 1) // 2)), constrained_layout=True)
    axes = np.atleast_2d(fig.subplots((len(top) + 1) // 2, 2))
    mid = 0.5 * (edges[1:] + edges[:-1])
    for k, ch in enumerate(top):
        ax = axes[k // 2, k % 2]
        c = channels.index(ch)
        for cube, lab, col in ((R, "calibrated", "tab:red"), (R_after, "after", "tab:blue")):
            m = np.nanmean(cube[:, c, :], axis=0)
            s = np.nanstd(cube[:, c, :], axis=0) / math.sqrt(max(cube.shape[0], 1))
            ax.errorbar(mid, m, yerr=1.96 * s, label=lab, color=col, capsize=2)
        ax.axhline(0, color="k", lw=0.6)
        ax.set_title(f"{ch}: mean residual (measured − model)", fontsize=9)
        ax.set_xlabel("stance phase [%]")
        ax.set_ylabel(channel_unit(ch))
        ax.legend(fontsize=7)
    for k in range(len(top), axes.size):
        axes[k // 2, k % 2].set_visible(False)
    p = out / "residual_profiles.png"
    fig.savefig(p, dpi=110)
    paths.append(p)
    return paths


def _markdown(res: dict, figs: Sequence[Path]) -> str:
    v = res["verdict"]
    cal = res["calibration"]
    lines = [f"# Diagnosis of `{res['data']}`", "",
             f"**Verdict ({v['status'].replace('_', ' ')}):** {v['text']}", "",
             "## Calibration (own parameters)", "",
             "| parameter | before | equation error | 95 % CI (Gauss–Newton) "
             "| 95 % CI (trial bootstrap) | after replay refit |",
             "|---|---|---|---|---|---|"]
    for k, val in cal["values"].items():
        conv = (math.degrees if k == "phi_s" else (lambda x: 1e3 * x) if k == "touchdown_depth"
                else (lambda x: x))
        name = {"phi_s": "phi_s [deg]", "touchdown_depth": "touchdown depth [mm]"}.get(k, k)
        gn = cal["ci_gn"].get(k, [None, None])
        bt = cal["ci_bootstrap"].get(k, [None, None])

        def fmt(iv):
            return "–" if iv[0] is None else f"[{conv(iv[0]):.4g}, {conv(iv[1]):.4g}]"
        init = cal["initial"].get(k, 0.0)
        eq = cal.get("equation_error_values", {}).get(k)
        eq_txt = "–" if eq is None else f"{conv(eq):.4g}"
        lines.append(f"| {name} | {conv(init):.4g} | {eq_txt} | {fmt(gn)} | {fmt(bt)} "
                     f"| {conv(val):.4g} |")
    lines += ["", f"{cal['n_samples']} sinking samples from {cal['n_stances']} stances; "
              f"force residual {cal['rmse_before_N']:.2f} N → {cal['rmse_after_N']:.2f} N. "
              + cal.get("note", ""), "",
              "## Candidate effects", "",
              "| rank | effect | kind | held-out error reduction | ΔAICc | inclusion | main coefficient | added |",
              "|---|---|---|---|---|---|---|---|"]
    for r in res["ranking"]:
        main = _dominant(r)
        p = r["params"].get(main, {})
        val = r.get("refined_params", {}).get(main, p.get("value"))
        ci = (f" [{p.get('boot_ci_lo', float('nan')):.3g}, {p.get('boot_ci_hi', float('nan')):.3g}]"
              if "boot_ci_lo" in p else "")
        inc = r["inclusion_probability"]
        lines.append(f"| {r['rank']} | {r['effect']} | {r['kind']} | "
                     f"{100 * r['heldout_error_reduction']:.1f} % | {r['delta_aicc']:.0f} | "
                     f"{'–' if inc is None else f'{inc:.2f}'} | {main} = {val:.4g}{ci} {p.get('unit', '')} | "
                     f"{'**yes**' if r['added'] else 'no'} |")
    if res["indistinguishable"]:
        lines += ["", "## Candidates the data cannot tell apart", ""]
        for g in res["indistinguishable"]:
            lines.append(f"* {' vs '.join(g['effects'])} (correlation {g['correlation']:.2f}): "
                         f"{g['experiment']}")
    loc = res["localization"]
    lines += ["", "## Where the calibrated model fails", ""]
    lines += [f"* {s}" for s in loc["where"]] or ["* no channel × phase cell with |t| ≥ "
                                                   f"{T_CELL:g}"]
    if v["added"]:
        lines += ["", "## After adding " + ", ".join(v["added"]), ""]
        lines += [f"* {s}" for s in loc["unexplained_where"]] or ["* no structure left"]
        red = res.get("heldout_reduction_by_channel", {})
        if red:
            lines += ["", "| channel | held-out RMS before | after | reduction |", "|---|---|---|---|"]
            for c, d in red.items():
                lines.append(f"| {c} | {d['before']:.4g} {d['unit']} | {d['after']:.4g} | "
                             f"{100 * d['reduction']:.0f} % |")
    lines += ["", "## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs]
    rec = res["recommended"]
    lines += ["", "## Next step", "", f"`{rec['validate_command']}`", ""]
    return "\n".join(lines)


__all__ = ["diagnose", "Diagnosis", "localize", "candidate_columns", "Column",
           "MIN_HELDOUT_REDUCTION", "MAX_DELTA_AICC", "MIN_INCLUSION", "T_CELL", "MIN_EFFECT_SIZE",
           "LARGE_HELDOUT_REDUCTION"]
