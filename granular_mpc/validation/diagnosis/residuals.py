"""Stage 2, residuals: replay the calibrated model, and once per candidate column at its
nominal magnitude; the binned residual and the sensitivity columns (``docs/validation.md``
§3.2)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..prepare import StanceWindow, channel_unit
from ..replay.model import Variant
from ..replay.outputs import apply_variant_sensors
from ..replay.pool import ReplayPool
from .calibration import CalibrationStage
from .candidates import CandidateSet, variant_for
from .cubes import group_keys, pred_cube, residual_cube
from .design import GeometryRows
from .problem import Problem
from .result import ChannelChange
from .thresholds import JUMP_FACTOR, JUMP_SHARE


def guard_jumps(S: np.ndarray, groups: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
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


def channel_sigma(R: np.ndarray, channels: Sequence[str], groups: np.ndarray) -> dict[str, float]:
    """Per channel: stance-to-stance scatter of the binned residual within groups
    (channel units; 1 where it cannot be estimated)."""
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


def geometry_rows(windows: Sequence[StanceWindow], candidates: CandidateSet) -> GeometryRows:
    """Touchdown heights (one free surface height per trial) and the geometry
    candidates' predicted change of them."""
    trials = np.array([w.trial for w in windows])
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

    def height(th):
        return (th.get("surface_height", 0.0) + th.get("surface_slope_x", 0.0) * gx
                + th.get("surface_slope_y", 0.0) * gyy)

    sens = {}
    for n, cols in candidates.columns.items():
        info = candidates.infos[n]
        for col in cols:
            if info.kind != "geometry":
                continue
            p0 = info.neutral_params()
            p1 = dict(p0)
            p1[col.param] = col.neutral + col.step
            sens[col.key] = (height(info.fn(p1)) - height(info.fn(p0))) / col.step
    return GeometryRows(gy, max(sig, 1e-4), sens)


@dataclass(frozen=True, eq=False)
class Residuals:
    """The calibrated model's residual and every column's sensitivity.

    Attributes:
        base: the calibrated model's variant.
        base_preds: its per-window replay outputs.
        R: residual cube (W, C, B), measured − replayed (channel units).
        sens: column key → sensitivity cube (W, C, B) per unit parameter (jump-guarded).
        jumps: column key → the replaced (window, channel) cells, in words.
        diverged: indices of the windows whose calibrated replay diverged.
        sigma: channel → stance-to-stance scatter (channel units).
        geometry: the touchdown-height rows.
    """

    base: Variant
    base_preds: tuple[dict, ...]
    R: np.ndarray
    sens: Mapping[str, np.ndarray]
    jumps: Mapping[str, tuple[str, ...]]
    diverged: tuple[int, ...]
    sigma: Mapping[str, float]
    geometry: GeometryRows


def sensor_sensitivity(problem: Problem, info, col, base_preds: Sequence[dict],
                       Pb: np.ndarray) -> np.ndarray:
    """A sensor column's sensitivity: its measurement map applied to the calibrated
    replay's outputs (no replay; for a sensor effect on the outputs only). The effect sees
    every column of the data format: the replayed channels and the window's measured
    columns for the others."""
    p = info.neutral_params()
    p[col.param] = col.neutral + col.step
    variant = Variant(sensors=((info, p),))
    shifted = []
    for w, pr in zip(problem.windows, base_preds):
        shifted.append(apply_variant_sensors({c: pr[c] for c in problem.channels}, variant, w,
                                             problem.joint_names))
    return (pred_cube(problem.windows, shifted, problem.channels, problem.edges) - Pb) / col.step


def compute_residuals(problem: Problem, candidates: CandidateSet, cal: CalibrationStage,
                      pool: ReplayPool) -> Residuals:
    """Replay the calibrated model, its calibration columns and every candidate column
    that needs a replay (:meth:`~.candidates.CandidateSet.needs_replay`) at its nominal
    step (a sensor effect on the outputs only: its map on the calibrated replay); bin,
    difference and guard the results."""
    windows, channels, edges = problem.windows, problem.channels, problem.edges
    base = Variant(theta=dict(cal.theta), label="calibrated")
    variants = {"base": base}
    for col in cal.nuisance:
        variants[col.key] = base.with_theta(**{col.param: col.neutral + col.step})
    for n, info in candidates.infos.items():
        if not candidates.needs_replay(n):
            continue
        for col in candidates.columns[n]:
            variants[col.key] = variant_for(info, {col.param: col.neutral + col.step}, base)
    preds = pool.run(variants)
    R = residual_cube(windows, preds["base"], channels, edges)
    Pb = pred_cube(windows, preds["base"], channels, edges)
    sens: dict[str, np.ndarray] = {c.key: (pred_cube(windows, preds[c.key], channels, edges)
                                           - Pb) / c.step for c in cal.nuisance}
    for n, cols in candidates.columns.items():
        info = candidates.infos[n]
        for col in cols:
            if not candidates.needs_replay(n):
                sens[col.key] = sensor_sensitivity(problem, info, col, preds["base"], Pb)
            else:
                sens[col.key] = (pred_cube(windows, preds[col.key], channels, edges) - Pb) / col.step
    gkeys = group_keys(windows)
    jumps: dict[str, tuple[str, ...]] = {}
    for key in list(sens):
        sens[key], rep = guard_jumps(sens[key], gkeys)
        if rep:
            jumps[key] = tuple(f"window {i} ({windows[i].trial}, {windows[i].side}): "
                               f"{channels[c]}" for i, c in rep)
    diverged = tuple(w.index for w, p in zip(windows, preds["base"]) if p["diverged"])
    return Residuals(base, tuple(preds["base"]), R, sens, jumps, diverged,
                     channel_sigma(R, channels, gkeys), geometry_rows(windows, candidates))


def replay_rmse(problem: Problem, before: Sequence[dict],
                after: Sequence[dict]) -> dict[str, ChannelChange]:
    """Per channel: RMSE of the raw samples (all stances) of two replays (channel units)."""
    out = {}
    for c in problem.channels:
        e0 = np.concatenate([w.meas[c] - np.asarray(p[c], float)
                             for w, p in zip(problem.windows, before)])
        e1 = np.concatenate([w.meas[c] - np.asarray(p[c], float)
                             for w, p in zip(problem.windows, after)])
        r0 = float(np.sqrt(np.nanmean(e0 ** 2)))
        r1 = float(np.sqrt(np.nanmean(e1 ** 2)))
        out[c] = ChannelChange(r0, r1, 1.0 - r1 / r0 if r0 > 0 else 0.0, channel_unit(c))
    return out


__all__ = ["Residuals", "compute_residuals", "guard_jumps", "channel_sigma", "geometry_rows",
           "sensor_sensitivity", "replay_rmse"]
