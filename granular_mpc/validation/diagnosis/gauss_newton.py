"""Gauss–Newton on the replays: refine the selected effects' magnitudes (and the
calibration) with sensitivities recomputed at the current values (``docs/validation.md``
§3.3, "refined")."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..replay.model import Variant, effect_variant
from ..replay.pool import ReplayPool
from .candidates import CandidateSet, Column
from .cubes import group_keys, pred_cube, residual_cube
from .design import GeometryRows, build_design
from .problem import Problem
from .regression import fit_bounded
from .residuals import Residuals, guard_jumps
from .result import RefineIteration

#: secant step as a share of the current distance from neutral
SECANT_SHARE = 0.25
#: after the requested iterations, at most this many more while the fit still moves …
MAX_EXTRA_ITERATIONS = 3
#: … by more than this share of a column's distance from neutral (or of its range)
MOVING_SHARE = 0.1


@dataclass(frozen=True, eq=False)
class GaussNewtonFit:
    """A refined model.

    Attributes:
        fitted: effect name → its parameters (neutral ones for columns not refined).
        theta: the calibration θ refined with them.
        preds: per-window replay outputs of the refined model.
        log: the iterations and the final values.
        sens_selected: the selected columns' sensitivities at the last iteration.
    """

    fitted: Mapping[str, Mapping[str, float]]
    theta: Mapping[str, float]
    preds: tuple[dict, ...]
    log: tuple[RefineIteration, ...]
    sens_selected: Mapping[str, np.ndarray]


def still_moving(cols: Sequence[Column], before: Mapping[str, float],
                 after: Mapping[str, float]) -> bool:
    """Whether the last Gauss–Newton step moved some column by more than
    :data:`MOVING_SHARE` of its distance from neutral (the larger of before and after; at
    least that share of 1 % of its range). A fit started far from its optimum (a
    screening estimate linearised at a small default) takes secant steps of growing size
    and is not converged after the requested iterations: :func:`refine_replays` then goes
    on, at most :data:`MAX_EXTRA_ITERATIONS` more."""
    for c in cols:
        scale = max(abs(before[c.key] - c.neutral), abs(after[c.key] - c.neutral),
                    0.01 * (c.upper - c.lower))
        if abs(after[c.key] - before[c.key]) > MOVING_SHARE * scale:
            return True
    return False


def refine_replays(problem: Problem, pool: ReplayPool, res: Residuals, candidates: CandidateSet,
                   selected: Sequence[str], start_values: Mapping[str, float],
                   nuisance: Sequence[Column], *, iterations: int) -> GaussNewtonFit:
    """Gauss–Newton on the replays for the selected effects' magnitude columns (and the
    calibration), on the stance-averaged rows: the sensitivities are recomputed at the
    current values (a secant of 25 % of the current magnitude). After ``iterations``
    iterations it goes on while the fit still moves (:func:`still_moving`), at most
    :data:`MAX_EXTRA_ITERATIONS` more.

    Args:
        start_values: column key → starting value (default: the column's neutral).
        nuisance: the calibration's columns at their current values.
    """
    windows, channels, edges = problem.windows, problem.channels, problem.edges
    base, sens, geo = res.base, res.sens, res.geometry
    cols = [c for s in selected for c in candidates.columns[s]]
    values = {c.key: float(start_values.get(c.key, c.neutral)) for c in cols}
    neutral = {c.key: c.neutral for c in cols}
    theta_nuis = {c.param: c.neutral for c in nuisance}
    S_sel: dict[str, np.ndarray] = {}
    log = []
    gkeys = group_keys(windows)

    def variant_with(vals, nuis) -> Variant:
        specs = [(candidates.infos[s], candidates.params_at(s, vals)) for s in selected]
        return effect_variant(specs, Variant(theta={**base.theta, **nuis}))

    it = 0
    while True:
        variants = {"cur": variant_with(values, theta_nuis)}
        steps = {}
        for c in cols:
            v = dict(values)
            cur = v[c.key]
            step = SECANT_SHARE * (cur - c.neutral) if abs(cur - c.neutral) > 1e-9 else c.step
            if not (c.lower <= cur + step <= c.upper):
                step = -step
            v[c.key] = cur + step
            steps[c.key] = step
            if candidates.needs_replay(c.candidate):
                variants[c.key] = variant_with(v, theta_nuis)
        out = pool.run(variants)
        Rc = residual_cube(windows, out["cur"], channels, edges)
        Pc = pred_cube(windows, out["cur"], channels, edges)
        S = {}
        for c in cols:
            if not candidates.needs_replay(c.candidate):
                S[c.key] = sens[c.key]       # a map of the outputs: its base sensitivity
            else:
                S[c.key] = guard_jumps((pred_cube(windows, out[c.key], channels, edges) - Pc)
                                       / steps[c.key], gkeys)[0]
        S_sel = {c.key: S[c.key] for c in cols}
        for c in nuisance:
            S[c.key] = sens[c.key]
        # geometry rows at the current values (linear in the geometry parameters)
        geo_now = GeometryRows(geo.shifted(values, neutral).y, geo.sigma, geo.sens)
        d = build_design("group", windows, Rc, S, channels, res.sigma, geo_now)
        keys = [c.key for c in nuisance] + [c.key for c in cols]
        A = np.column_stack([d.X[k] for k in keys])
        ok = np.isfinite(d.y) & np.isfinite(A).all(axis=1)
        lb, ub = [], []
        for c in nuisance:
            lb.append(c.lower - theta_nuis[c.param])
            ub.append(c.upper - theta_nuis[c.param])
        for c in cols:
            lb.append(c.lower - values[c.key])
            ub.append(c.upper - values[c.key])
        delta = fit_bounded(A[ok], d.y[ok], np.array(lb), np.array(ub))
        log.append(RefineIteration(it + 1, float(np.sum(d.y[ok] ** 2)),
                                   float(np.sum((d.y[ok] - A[ok] @ delta) ** 2)), dict(values)))
        for c, dlt in zip(nuisance, delta[:len(nuisance)]):
            theta_nuis[c.param] = float(np.clip(theta_nuis[c.param] + dlt, c.lower, c.upper))
        before_step = dict(values)
        for c, dlt in zip(cols, delta[len(nuisance):]):
            values[c.key] = float(np.clip(values[c.key] + dlt, c.lower, c.upper))
        it += 1
        if it >= max(1, iterations) + MAX_EXTRA_ITERATIONS or (
                it >= max(1, iterations) and not still_moving(cols, before_step, values)):
            break
    final = pool.run({"final": variant_with(values, theta_nuis)})["final"]
    log.append(RefineIteration("final", values=dict(values), calibration=dict(theta_nuis)))
    fitted = {s: candidates.params_at(s, values) for s in selected}
    return GaussNewtonFit(fitted, theta_nuis, tuple(final), tuple(log), S_sel)


__all__ = ["GaussNewtonFit", "refine_replays", "still_moving", "SECANT_SHARE",
           "MAX_EXTRA_ITERATIONS", "MOVING_SHARE"]
