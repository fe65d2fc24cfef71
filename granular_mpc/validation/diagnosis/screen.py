"""Stage 3, rank and screen: every candidate's statistics against the calibrated model by
bounded least squares on the sensitivity columns (held-out error reduction, ΔAICc,
bootstrap inclusion, effect size), and the pairs the data cannot tell apart
(``docs/validation.md`` §3.3)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Collection, Mapping, Sequence

import numpy as np

from ..prepare import StanceWindow, channel_unit
from .candidates import CandidateSet, Column
from .cubes import bin_means
from .localise import spearman
from .problem import Problem
from .ranking_records import CandidateStats, ParamEstimate
from .regression import (Regression, RegressionBuilder, Regressions, fit_bounded,
                         forward_selection)
from .residuals import Residuals
from .result import ChannelChange, IndistinguishablePair
from .strength import StrengthModel, StrengthTwin, first_twin
from .thresholds import (FEATURE_EXPERIMENTS, LARGE_HELDOUT_REDUCTION, MAX_DELTA_AICC,
                         MIN_EFFECT_SIZE, MIN_HELDOUT_REDUCTION, MIN_INCLUSION,
                         MIN_STANCE_REDUCTION)

#: leading candidates whose contributions correlate at least this much are indistinguishable
INDISTINGUISHABLE_CORRELATION = 0.9
#: a candidate taking at least this share of the bootstrap selections shares a decision
MIN_SHARED_INCLUSION = 0.25
#: … when the leader's inclusion is below MIN_INCLUSION + this (a near tie)
NEAR_TIE = 0.2


def practically_large(heldout_error_reduction: float, effect_size: float,
                      heldout_error_reduction_stance: float) -> bool:
    """Whether a statistically supported candidate also matters in practice: it removes
    ≥ LARGE_HELDOUT_REDUCTION of the held-out (trial-grouped, stance-averaged) error, or it
    moves some channel × phase mean by ≥ MIN_EFFECT_SIZE σ *and* its fit helps held-out
    stances one by one (≥ MIN_STANCE_REDUCTION). The stance score uses each stance's own
    finite-difference sensitivities, which carry the open-loop replays' chaotic noise: for
    a true sideways term with half the held-out error to remove it measured −3 %, so a
    large held-out reduction does not need it. Without stance rows (the stance score is
    then 0) only the held-out test can pass."""
    if heldout_error_reduction >= LARGE_HELDOUT_REDUCTION:
        return True
    return bool(not effect_size < MIN_EFFECT_SIZE
                and heldout_error_reduction_stance >= MIN_STANCE_REDUCTION)


def candidate_stats(reg: Regression, base_keys: Sequence[str],
                    cand_keys: Mapping[str, list[str]],
                    cand_cols: Mapping[str, Sequence[Column]], infos: Mapping, *, n_boot: int,
                    seed: int, max_effects: int,
                    strength_models: Sequence[StrengthModel] = (),
                    not_twins: Collection[str] = ()) -> list[CandidateStats]:
    """Statistics of every candidate in ``cand_keys`` against the model ``base_keys``:
    held-out error reduction (systematic rows; stance rows under the same fit), ΔAICc,
    bootstrap inclusion probability, fitted parameters with intervals, significance.
    Sorted by held-out error reduction (``rank`` 1 first). ``strength_models``: the model
    replayed at the terrain-file parameters the data ask for, per tested group
    (:func:`.strength.strength_models`), against which a candidate that passes is tested
    again (a group without one: the group's columns of ``reg``, if any)."""
    base_keys = list(base_keys)
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
            params[col.param] = dict(
                value=val, se=se, ci_lo=None if se is None else val - 1.96 * se,
                ci_hi=None if se is None else val + 1.96 * se, unit=col.unit,
                neutral=col.neutral, lower=col.lower, upper=col.upper,
                at_bound=bool(np.isclose(val, col.lower) or np.isclose(val, col.upper)))
        improved = sum(1 for f0, f1 in zip(cv0.folds, cv.folds) if f1 < f0)
        size = reg.practical_size(keys, beta[len(base_keys):])
        red_st = (1.0 - cv.sse_stance / cv0.sse_stance
                  if cv0.sse_stance == cv0.sse_stance and cv0.sse_stance > 0 else 0.0)
        rows.append(dict(effect=n, kind=infos[n].kind,
                         heldout_error_reduction=1.0 - cv.sse / cv0.sse if cv0.sse > 0 else 0.0,
                         heldout_error_reduction_stance=red_st,
                         delta_aicc=reg.aicc(base_keys + keys) - a0,
                         folds_improved=f"{improved}/{len(cv.folds)}", effect_size=size,
                         params=params, main=infos[n].main,
                         depends_on=tuple(infos[n].depends_on), doc=infos[n].summary))
    # a candidate that a terrain-strength mismatch explains as well is not significant
    # (strength.py; only when the regression has the strength columns)
    for r in rows:
        if r["effect"] not in not_twins and passes_but_inclusion(r) and first_twin(
                reg, base_keys, r["effect"], cand_keys[r["effect"]],
                r["heldout_error_reduction"], {}, strength_models) is not None:
            r["strength_twin"] = True
    # bootstrap inclusion probability: forward selection by AICc on resamples of trials
    rng = np.random.default_rng(seed)
    gs = np.unique(reg.groups)
    members = {g: np.flatnonzero(reg.groups == g) for g in gs}
    counts = {n: 0 for n in cand_keys}
    boot_params: dict[str, list] = {n: [] for n in cand_keys}
    B = int(n_boot) if gs.size >= 2 else 0
    # a twin does not vote: the terrain file's parameters explain its evidence, so the
    # selections it would take go to the candidates that remain (a plant's soft bed, the
    # user's term, got 50 % of them beside twins and was never refined)
    twins = {r["effect"] for r in rows if r.get("strength_twin")}
    voters = {n: k for n, k in cand_keys.items() if n not in twins}
    for _ in range(B):
        pick = rng.choice(gs, gs.size, replace=True)
        rws = np.concatenate([members[g] for g in pick])
        for n in forward_selection(reg, voters, base_keys, rws, max_terms=max_effects):
            counts[n] += 1
        for n, keys in cand_keys.items():
            beta, _ = reg.fit(base_keys + keys, rws)
            boot_params[n].append(beta[len(base_keys):])
    out = []
    for r in rows:
        n = r["effect"]
        inclusion = counts[n] / B if B else None
        bp = np.array(boot_params[n]) if boot_params[n] else None
        for k, col in enumerate(cand_cols[n]):
            if bp is not None and len(bp):
                vals = col.neutral + bp[:, k]
                r["params"][col.param]["boot_ci_lo"] = float(np.percentile(vals, 2.5))
                r["params"][col.param]["boot_ci_hi"] = float(np.percentile(vals, 97.5))
        r["params"] = {p: ParamEstimate(**v) for p, v in r["params"].items()}
        out.append(dict(r, inclusion_probability=inclusion,
                        significant=passes_but_inclusion(r) and (inclusion if B else 1.0)
                        >= MIN_INCLUSION))
    out.sort(key=lambda r: -r["heldout_error_reduction"])
    if B:
        share_inclusion(out)
    return [CandidateStats(**{k: v for k, v in r.items() if k != "strength_twin"}, rank=i + 1)
            for i, r in enumerate(out)]


def passes_but_inclusion(r: Mapping) -> bool:
    """The held-out, AICc and practical tests (every test but the bootstrap inclusion), and
    not a terrain-strength mismatch in disguise (``r["strength_twin"]``, :mod:`.strength`)."""
    return bool(not r.get("strength_twin")
                and r["heldout_error_reduction"] >= MIN_HELDOUT_REDUCTION
                and r["delta_aicc"] <= MAX_DELTA_AICC
                and practically_large(r["heldout_error_reduction"], r["effect_size"],
                                      r["heldout_error_reduction_stance"]))


def share_inclusion(rows: list[dict]) -> None:
    """Candidates that pass every test but the inclusion and split the bootstrap
    selections between them (each ≥ MIN_SHARED_INCLUSION, together ≥ MIN_INCLUSION, the
    leader below MIN_INCLUSION + NEAR_TIE) are one decision the data cannot make: each
    row gets ``inclusion_shared_with``, and when none of them passes alone, the one with
    the largest held-out reduction becomes significant (the replays of the refinement
    then choose). Adding an unrelated candidate that takes some selections can then no
    longer undo another's acceptance. ``rows`` sorted by held-out reduction, changed in
    place."""
    group = [r for r in rows if passes_but_inclusion(r)
             and (r["inclusion_probability"] or 0.0) >= MIN_SHARED_INCLUSION]
    if len(group) < 2:
        return
    incs = [r["inclusion_probability"] for r in group]
    if sum(incs) < MIN_INCLUSION or max(incs) >= MIN_INCLUSION + NEAR_TIE:
        return
    names = [r["effect"] for r in group]
    for r in group:
        r["inclusion_shared_with"] = tuple(n for n in names if n != r["effect"])
    if not any(r["significant"] for r in group):
        group[0]["significant"] = True


def inclusion_ties(ranking: Sequence[CandidateStats]) -> list[tuple[str, str]]:
    """The pairs of candidates that split the bootstrap selections (:func:`share_inclusion`)."""
    out = []
    for r in ranking:
        for other in r.inclusion_shared_with:
            pair = (r.effect, other)
            if (other, r.effect) not in out and pair not in out:
                out.append(pair)
    return out


def separating_experiment(a: str, b: str, reg: Regression, cand_keys: Mapping[str, list[str]],
                          windows: Sequence[StanceWindow], infos: Mapping) -> str:
    """The measured variable along which the two candidates' columns differ most
    (stance-level rows: rank correlation of |column| with each binned feature), as an
    experiment to run."""
    ok = reg.ok
    wid = reg.design.window[ok]
    pb = reg.design.phase_bin[ok]
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
                vals = bin_means(w, w.features, [f], edges)[0]
                x[m] = vals[np.clip(pb[m], 0, vals.size - 1)]
        ra, _ = spearman(x, va)
        rb, _ = spearman(x, vb)
        if ra == ra and rb == rb and abs(ra - rb) > gap:
            best, gap = f, abs(ra - rb)
    da = ", ".join(infos[a].depends_on) or "its own signature"
    db = ", ".join(infos[b].depends_on) or "its own signature"
    where = FEATURE_EXPERIMENTS.get(best, "a wider range of conditions") if best else \
        "a wider range of speeds and depths"
    return (f"{a} scales with {da}; {b} with {db}. In this data their effects differ most "
            f"along '{best}'; an experiment with {where} would separate them.")


def indistinguishable(reg: Regression, base_keys: Sequence[str],
                      cand_keys: Mapping[str, list[str]], ranking: Sequence[CandidateStats],
                      windows: Sequence[StanceWindow], infos: Mapping,
                      reg_stance: Regression) -> list[IndistinguishablePair]:
    """Pairs of leading candidates whose fitted contributions are nearly collinear, and
    every pair that split the bootstrap selections in a near tie (:func:`inclusion_ties`)."""
    if not ranking or ranking[0].heldout_error_reduction <= 0:
        return []
    base_keys = list(base_keys)
    top = ranking[0]
    contenders = [r for r in ranking[1:6]
                  if r.heldout_error_reduction >= 0.5 * top.heldout_error_reduction]
    Xn, _, _ = reg.matrix(base_keys)

    def contribution(name):
        beta, _ = reg.fit(base_keys + cand_keys[name])
        X, _, _ = reg.matrix(cand_keys[name])
        v = X @ beta[len(base_keys):]
        if Xn.shape[1]:
            v = v - Xn @ np.linalg.lstsq(Xn, v, rcond=None)[0]
        return v

    by_name = {r.effect: r for r in ranking}

    def correlation(a, b):
        va, vb = contribution(a), contribution(b)
        den = float(np.linalg.norm(va) * np.linalg.norm(vb))
        return float(va @ vb / den) if den > 0 else 0.0

    def pair(a, b, corr):
        return IndistinguishablePair(
            (a, b), corr, (by_name[a].heldout_error_reduction, by_name[b].heldout_error_reduction),
            separating_experiment(a, b, reg_stance, cand_keys, windows, infos))

    out = []
    for r in contenders:
        corr = correlation(top.effect, r.effect)
        if abs(corr) >= INDISTINGUISHABLE_CORRELATION:
            out.append(pair(top.effect, r.effect, corr))
    # near-tie bootstrap decisions are indistinguishable whatever their correlation
    seen = {frozenset(p.effects) for p in out}
    for a, b in inclusion_ties(ranking):
        if frozenset((a, b)) not in seen:
            out.append(pair(a, b, correlation(a, b)))
            seen.add(frozenset((a, b)))
    return out


def channel_heldout(reg: Regression, base_keys: Sequence[str], add_keys: Sequence[str],
                    channels: Sequence[str], *, stance: bool) -> dict[str, ChannelChange]:
    """Per channel: held-out (trial-grouped CV) RMS of the residual before and after adding
    ``add_keys`` (linearised; fitted on the systematic rows of the training trials), on the
    stance rows (``stance``) or the stance-averaged rows, in channel units."""
    if stance and reg.stance is None:
        return {}
    base_keys, add_keys = list(base_keys), list(add_keys)
    chan = reg.stance_channel if stance else reg.design.channel[reg.ok]
    before = {c: 0.0 for c in list(channels) + ["touchdown_z"]}
    after = dict(before)
    count = dict(before)
    X0, lb0, ub0 = reg.matrix(base_keys)
    X1, lb1, ub1 = reg.matrix(base_keys + add_keys)
    if stance:
        X0s, _, _ = reg.matrix(base_keys, cols=reg.stance.cols)
        X1s, _, _ = reg.matrix(base_keys + add_keys, cols=reg.stance.cols)
    for k, (tr, te) in enumerate(reg.splits):
        b0 = fit_bounded(X0[tr], reg.y[tr], lb0, ub0)
        b1 = fit_bounded(X1[tr], reg.y[tr], lb1, ub1)
        if stance:
            ste = reg.stance_splits[k]
            y = reg.stance.y[ste]
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
        s = reg.design.sigma.get(c, 1.0)
        rb = s * math.sqrt(before[c] / count[c])
        ra = s * math.sqrt(after[c] / count[c])
        out[c] = ChannelChange(rb, ra, 1.0 - ra / rb,
                               channel_unit(c) if c != "touchdown_z" else "m")
    return out


@dataclass(frozen=True, eq=False)
class ScreeningDesign:
    """The regressions on the calibrated residual.

    Attributes:
        builder: builds regressions on this data set (used again by the refinement).
        regressions: systematic rows (scored also on stance rows) on the calibrated model.
        bounds: column key → coefficient bounds.
        base_keys: the nuisance column keys.
        strength: the terrain-strength columns in the regressions (not in ``base_keys``:
            only tested against, :mod:`.strength`).
        strength_models: the model replayed at the terrain-file parameters the data ask
            for, the candidates replayed there, one per tested group that moved
            (:func:`.strength.strength_models`; empty: the data ask for the file's
            values, or they were not computed).
    """

    builder: RegressionBuilder
    regressions: Regressions
    bounds: Mapping[str, tuple[float, float]]
    base_keys: tuple[str, ...]
    strength: tuple[Column, ...] = ()
    strength_models: tuple[StrengthModel, ...] = ()

    @property
    def regression(self) -> Regression:
        return self.regressions.regression


@dataclass(frozen=True, eq=False)
class Screening(ScreeningDesign):
    """The first screening: the design plus every candidate's statistics.

    Attributes:
        ranking: candidate statistics by held-out error reduction.
        indistinguishable: nearly collinear leading pairs.
        strength_twins: candidates that pass every test but are explained as well by a
            terrain-strength mismatch (not significant, :mod:`.strength`).
        not_twins: candidates the twin test was not applied to (:func:`.strength.not_twins`).
    """

    ranking: tuple[CandidateStats, ...] = ()
    indistinguishable: tuple[IndistinguishablePair, ...] = ()
    strength_twins: tuple[StrengthTwin, ...] = ()
    not_twins: tuple[str, ...] = ()


def screening_design(problem: Problem, candidates: CandidateSet, nuisance: Sequence[Column],
                     res: Residuals, *, seed: int, strength: Sequence[Column] = (),
                     strength_models: Sequence[StrengthModel] = ()) -> ScreeningDesign:
    """The regressions on the calibrated residual with every column (bounds = the
    parameters' physical ranges around their neutral values); ``strength``: the
    terrain-strength columns (their sensitivities in ``res.sens``), tested against only;
    ``strength_models``: the models at the values the data ask for (tested against)."""
    strength = tuple(c for c in strength if c.key in res.sens)
    bounds = {c.key: c.bounds for c in tuple(nuisance) + strength}
    for cols in candidates.columns.values():
        for col in cols:
            bounds[col.key] = col.bounds
    base_keys = [c.key for c in nuisance]
    group_unit = "trial" if problem.n_trials >= 3 else "stance"
    builder = RegressionBuilder(problem.windows, problem.channels, res.sigma, group_unit, seed)
    regs = builder.build(res.R, res.sens, res.geometry, bounds, base_keys)
    return ScreeningDesign(builder, regs, bounds, tuple(base_keys), strength,
                           tuple(strength_models))


def screen(problem: Problem, candidates: CandidateSet, design: ScreeningDesign, *,
           n_boot: int, seed: int, max_effects: int,
           not_twins: Collection[str] = ()) -> Screening:
    """Rank every candidate against the calibrated model and find the indistinguishable
    leading pairs; ``not_twins``: candidates not tested as terrain-strength twins
    (:func:`.strength.not_twins`)."""
    base_keys = list(design.base_keys)
    reg = design.regression
    cand_keys = candidates.keys
    ranking = candidate_stats(reg, base_keys, cand_keys, candidates.columns, candidates.infos,
                              n_boot=n_boot, seed=seed, max_effects=max_effects,
                              strength_models=design.strength_models, not_twins=not_twins)
    pairs = indistinguishable(reg, base_keys, cand_keys, ranking, problem.windows,
                              candidates.infos,
                              Regression(design.regressions.stance, design.bounds, base_keys,
                                         seed=seed))
    neutral = {c.key: c.neutral for c in design.strength}
    twins = []
    for r in ranking:
        stats = dict(heldout_error_reduction=r.heldout_error_reduction,
                     delta_aicc=r.delta_aicc, effect_size=r.effect_size,
                     heldout_error_reduction_stance=r.heldout_error_reduction_stance)
        if neutral and r.effect not in not_twins and passes_but_inclusion(stats):
            tw = first_twin(reg, base_keys, r.effect, cand_keys[r.effect],
                            r.heldout_error_reduction, neutral, design.strength_models,
                            {c.key: c.step for c in design.strength})
            if tw is not None:
                twins.append(tw)
    # a twin must not come back as a leader's indistinguishable partner (refine refines
    # partners whether significant or not): a strength twin is no contender
    gone = {t.effect for t in twins}
    pairs = [p for p in pairs if not gone & set(p.effects)]
    return Screening(design.builder, design.regressions, design.bounds, design.base_keys,
                     design.strength, design.strength_models, ranking=tuple(ranking),
                     indistinguishable=tuple(pairs), strength_twins=tuple(twins),
                     not_twins=tuple(sorted(set(not_twins) & set(cand_keys))))

__all__ = ["Screening", "ScreeningDesign", "screening_design", "screen", "candidate_stats",
           "practically_large", "indistinguishable", "separating_experiment", "channel_heldout",
           "INDISTINGUISHABLE_CORRELATION", "passes_but_inclusion", "share_inclusion",
           "inclusion_ties", "MIN_SHARED_INCLUSION", "NEAR_TIE"]
