"""Stage 4, refine: add effects one at a time — the best significant contenders, and the
indistinguishable partners of the leading one against the current model (significant or
not), are each refined by the same number of Gauss–Newton replay iterations; the one with
the lowest AICc of its replayed residual that passes honest acceptance (:mod:`.acceptance`:
its replays improve its credited channels, its coefficient is physical) is added, the
others are re-tested conditionally on the refined model; then every earlier addition is
judged again against the final model (:func:`rejudge_earlier`) and each contest is run
again against it (:func:`exchange_terms`) — then the final ranking and the refined
model's held-out statistics (``docs/validation.md`` §3.3)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Collection, Mapping, Sequence

import numpy as np

from ..replay.model import Variant, effect_variant
from ..replay.pool import ReplayPool
from .acceptance import Acceptance, judge
from .calibration import CalibrationStage, nuisance_columns
from .candidates import CandidateSet
from .cubes import residual_cube
from .design import GeometryRows
from .gauss_newton import GaussNewtonFit, refine_replays
from .problem import Problem
from .ranking_records import CandidateStats, ConditionalResult, ForceStart, Ranked, RefinedFit
from .regression import Regression, aicc
from .residuals import Residuals
from .result import ConditionalRow, IndistinguishablePair, RefinedHeldout, SelectionStep
from .screen import (INDISTINGUISHABLE_CORRELATION, Screening, candidate_stats,
                     channel_heldout, indistinguishable, passes_but_inclusion)
from .torque_evidence import torque_evidence

#: how many times an earlier addition may be dropped (:func:`rejudge_earlier`) and the
#: forward selection resumed against the reduced model
MAX_DROPS = 1
#: bounds of the scale along the secant from the calibrated to the refined model
SECANT_BOUNDS = (0.0, 2.0)
REFINED_HELDOUT_NOTE = (
    "trial-grouped CV: the magnitude of the added effects (a scalar along the replayed change "
    "from the calibrated to the refined model) and the calibration are fitted on the training "
    "trials, the RMSE is scored on the held-out trials, stance by stance")


@dataclass(frozen=True, eq=False)
class Refinement:
    """What the selection added and the final ranking.

    Attributes:
        selected: the added effects, in order.
        fitted: their refined parameters.
        theta: the calibration θ refined with them (the calibrated θ if nothing was added).
        final_preds: per-window replay outputs of the final model.
        ranking: every candidate, the added ones first.
        steps: one record per addition.
        refined_heldout: held-out statistics of the refined model (None: nothing added).
        acceptance: the acceptance decision of every refined contender (:mod:`.acceptance`),
            in the order they were judged.
    """

    selected: tuple[str, ...]
    fitted: Mapping[str, Mapping[str, float]]
    theta: Mapping[str, float]
    final_preds: tuple[dict, ...]
    ranking: tuple[Ranked, ...]
    steps: tuple[SelectionStep, ...]
    refined_heldout: RefinedHeldout | None
    acceptance: tuple[Acceptance, ...] = ()


def _values(fitted: Mapping[str, Mapping[str, float]], candidates: CandidateSet,
            selected) -> dict[str, float]:
    """Column key → fitted value of the selected effects' columns."""
    return {c.key: fitted[s][c.param] for s in selected for c in candidates.columns[s]}


def _neutral(candidates: CandidateSet, selected) -> dict[str, float]:
    return {c.key: c.neutral for s in selected for c in candidates.columns[s]}


def refined_aicc(problem: Problem, candidates: CandidateSet, res: Residuals, scr: Screening,
                 preds: Sequence[dict], fitted: Mapping[str, Mapping[str, float]],
                 selected: Sequence[str]) -> tuple[float, float]:
    """AICc and weighted RSS of the stance-averaged residual of a refined (replayed) model:
    ``selected`` at ``fitted``, per-window replay outputs ``preds``."""
    sel = list(selected)
    R_ = residual_cube(problem.windows, preds, problem.channels, problem.edges)
    geo = res.geometry
    gy = geo.shifted(_values(fitted, candidates, sel), _neutral(candidates, sel)).y
    d_ = scr.builder.build(R_, {}, GeometryRows(gy, geo.sigma, {}), {}, []).systematic
    y_ = d_.y[np.isfinite(d_.y)]
    k_ = len(scr.base_keys) + sum(len(candidates.columns[s]) for s in sel)
    return aicc(float(y_ @ y_), y_.size * d_.n_eff_factor, k_), float(y_ @ y_)


def contenders_for(stats: Sequence[CandidateStats], selected: Sequence[str],
                   rejected: Collection[str], max_contenders: int,
                   pairs: Sequence[IndistinguishablePair] = (),
                   twins: Collection[str] = (), with_rivals: bool = True
                   ) -> list[CandidateStats]:
    """The candidates the replays refine before one is added.

    The first ``max_contenders`` significant candidates not yet added or rejected, then
    every candidate the screening could not tell from the *leading* contender (``pairs``:
    its nearly collinear or bootstrap-splitting partners, :func:`.screen.indistinguishable`)
    that is not among them, significant or not. A partner that splits the bootstrap
    selections with the leader is not significant by construction (neither reaches the
    inclusion threshold), so without this rule the nonlinear comparison that can separate
    the two — their refined replays' AICc — never runs and the linear leader is added by
    default. The partner still has to win that comparison and pass the acceptance
    (:mod:`.acceptance`) to be added. Without a significant leader nothing is refined, so
    the rule adds nothing on data where the screening finds nothing. Last, at most
    ``max_contenders`` rivals (:func:`is_rival`: every test passed but the inclusion),
    for the same reason and under the same conditions.

    Args:
        stats: the current candidate statistics, best first.
        selected: the effects already added.
        rejected: the effects the acceptance rejected against the current model
            (:func:`rejected_against`).
        max_contenders: significant candidates refined.
        pairs: the indistinguishable pairs against the current model: the screening's
            before any addition (collinear or a near tie of the bootstrap), then the
            collinear ones of the last conditional test.
        twins: terrain-strength twins (never rivals, :mod:`.strength`).
        with_rivals: append the rivals (False: the significant contenders and partners).

    Returns:
        The contenders, in the order of ``stats``, then the partners, then the rivals.
    """
    free = [r for r in stats if r.effect not in selected and r.effect not in rejected]
    out = [r for r in free if r.significant][:max_contenders]
    if not out:
        return out
    lead = out[0].effect
    partners = {b for p in pairs for a, b in (p.effects, p.effects[::-1]) if a == lead}
    have = {r.effect for r in out}
    out += [r for r in free if r.effect in partners and r.effect not in have]
    have = {r.effect for r in out}
    if with_rivals:
        out += [r for r in free
                if r.effect not in have and is_rival(r, twins)][:max_contenders]
    return out


def is_rival(r: CandidateStats, twins: Collection[str] = ()) -> bool:
    """A candidate that passes every screening test but the bootstrap inclusion (and is
    no terrain-strength twin): the linear fits' vote went to another candidate, but its
    own evidence is strong. The bootstrap votes with the *linearised* model, which
    misorders strong nonlinear effects (a torque-sensing gain linearised at a small gain,
    a stiction law beside the library's Coulomb friction), so such a rival is refined by
    replays beside the leader and may win on its refined AICc — only win: a rival is
    added only when its refined AICc is below every other contender's (:func:`refine`),
    never as the fallback of a rejected leader."""
    if r.significant or r.effect in twins:
        return False
    return passes_but_inclusion({f: getattr(r, f) for f in (
        "heldout_error_reduction", "delta_aicc", "effect_size",
        "heldout_error_reduction_stance")})


def replay_with(pool: ReplayPool, res: Residuals, candidates: CandidateSet,
                fitted: Mapping[str, Mapping[str, float]], theta: Mapping[str, float],
                effects: Sequence[str]) -> tuple[dict, ...]:
    """Per-window replay outputs of the calibrated model at θ ``theta`` with ``effects``
    at their ``fitted`` values (the others left out)."""
    specs = [(candidates.infos[s], dict(fitted[s])) for s in effects]
    variant = effect_variant(specs, Variant(theta={**res.base.theta, **theta}))
    return tuple(pool.run({"without": variant})["without"])


def without_term(pool: ReplayPool, res: Residuals, candidates: CandidateSet,
                 fit: GaussNewtonFit, previous: Sequence[str]) -> tuple[dict, ...]:
    """Per-window replay outputs of a refined model without its newest term: the
    calibration θ refined with it (``fit.theta``) and the ``previous`` effects at their
    refined values, the term left out.

    The acceptance compares this with ``fit.preds``, so that a term is credited with — and
    judged on — what *its own* replays change: the co-refitted calibration moves other
    channels too (a force-sensor bias refitted with ζ shifts ``grf_x`` by ~1 %), which is
    no evidence for or against the term.
    """
    return replay_with(pool, res, candidates, fit.fitted, fit.theta, previous)


def judge_in_model(problem: Problem, pool: ReplayPool, res: Residuals,
                   candidates: CandidateSet, name: str, selected: Sequence[str],
                   fitted: Mapping[str, Mapping[str, float]], theta: Mapping[str, float],
                   preds: Sequence[dict]) -> Acceptance:
    """The acceptance of ``name`` inside the model ``selected`` at ``fitted`` and θ
    ``theta`` (per-window replay outputs ``preds``): that model against itself without
    ``name`` (the others at the same values), ``given`` the others."""
    others = [s for s in selected if s != name]
    before = replay_with(pool, res, candidates, fitted, theta, others)
    info = candidates.infos[name]
    return replace(judge(problem.windows, problem.channels, res.sigma, info, fitted[name],
                         before, preds, torque_evidence(problem.joint_rows, info, fitted[name])),
                   given=tuple(others))


def rejected_against(acceptance: Sequence[Acceptance], selected: Sequence[str]) -> set[str]:
    """The candidates the acceptance rejected against the model with exactly ``selected``
    added. A rejection holds against the model it was judged on — its replays, its
    co-refitted coefficients: after a further addition the rejected candidate may be
    refined and judged again (a knee spring whose replays raised ``grf_z`` while a
    force-sensor bias was unmodelled passes once the bias is added)."""
    given = tuple(selected)
    return {a.effect for a in acceptance if not a.accepted and tuple(a.given) == given}


def rejudge_earlier(problem: Problem, pool: ReplayPool, res: Residuals,
                    candidates: CandidateSet, selected: list[str],
                    fitted: Mapping[str, Mapping[str, float]], theta: Mapping[str, float],
                    preds: Sequence[dict], acceptance: list[Acceptance],
                    refine_iterations: int
                    ) -> tuple[list[str], Mapping, dict, Sequence[dict], GaussNewtonFit | None]:
    """Judge every effect added before the last again, against the final model: an
    acceptance holds against the model it was judged on, as a rejection does
    (:func:`rejected_against`). Its own replays — the final model with and without it, at
    the final θ and the others' refined values — must still improve the channels it is
    credited with and its coefficients stay physical; if not, a later addition explains
    what it was added for (a both-feet force-sensor bias added for a left-only one, a
    joint friction standing in for a stiction), and it is dropped: the others are refined
    again without it. Each judgement is appended to ``acceptance`` (``given``: the others).

    Returns:
        The effects kept, their refined parameters, θ, per-window replay outputs, and the
        refit without the dropped effects (None: nothing dropped).
    """
    refit = None
    for name in list(selected[:-1]):
        others = [s for s in selected if s != name]
        acc = judge_in_model(problem, pool, res, candidates, name, selected, fitted, theta,
                             preds)
        if acc.accepted:
            acceptance.append(acc)
            continue
        acceptance.append(replace(acc, dropped=True))
        refit = refine_replays(problem, pool, res, candidates, others,
                               _values(fitted, candidates, others), nuisance_columns(theta),
                               iterations=refine_iterations)
        selected = others
        fitted, theta, preds = refit.fitted, dict(refit.theta), refit.preds
    return selected, fitted, dict(theta), preds, refit


def exchange_terms(problem: Problem, pool: ReplayPool, res: Residuals, scr: Screening,
                   candidates: CandidateSet, selected: Sequence[str],
                   fitted: Mapping[str, Mapping[str, float]], theta: Mapping[str, float],
                   preds: Sequence[dict],
                   rivals_of: Mapping[str, Sequence[tuple[str, Mapping[str, float]]]],
                   acceptance: list[Acceptance], refine_iterations: int
                   ) -> tuple[list[str], GaussNewtonFit, SelectionStep, float] | None:
    """The exchange step of a stepwise selection: each added effect A competed, when it was
    added, with the other refined contenders against the model *of that moment*; a later
    addition may change that contest (a joint friction that beat a stiction while a depth
    hardening was still unmodelled, because it also took part of the hardening's force
    error). So, against the final model, each contender B that A beat (``rivals_of[A]``:
    name and its refined parameters then) takes A's place, is refined with the others, and
    replaces A when the model with B has the lower refined AICc (:func:`refined_aicc`) and
    passes the acceptance — B's own replays and every other term's given B (:func:`judge`).
    One exchange at most (the first found, in the order of ``selected`` and of A's contest);
    each judgement is appended to ``acceptance``; A's entry says it was exchanged.

    Returns:
        The new selection (B in A's place), its refined fit, the contest as a selection
        step (B added; contenders B and A, the AICc of the model with each) and the new
        model's weighted RSS; None: no exchange.
    """
    current, _ = refined_aicc(problem, candidates, res, scr, preds, fitted, selected)
    for i, a in enumerate(selected):
        others = [s for s in selected if s != a]
        for b, b_params in rivals_of.get(a, ()):
            if b in selected:
                continue
            sel = list(selected[:i]) + [b] + list(selected[i + 1:])
            start = _values(fitted, candidates, others)     # a fresh dict per rival
            start.update({c.key: float(b_params[c.param]) for c in candidates.columns[b]
                          if c.param in b_params})
            fit = refine_replays(problem, pool, res, candidates, sel, start,
                                 nuisance_columns(theta), iterations=refine_iterations)
            score, rss = refined_aicc(problem, candidates, res, scr, fit.preds, fit.fitted,
                                      sel)
            if not score < current:
                continue
            judged = [judge_in_model(problem, pool, res, candidates, name, sel, fit.fitted,
                                     fit.theta, fit.preds) for name in sel]
            acceptance.extend(judged)
            if not all(j.accepted for j in judged):
                continue
            why = (f"exchanged for {b}: the model with {b} in its place has the lower refined "
                   f"AICc ({current:.1f} → {score:.1f}) and passes the acceptance")
            acceptance.append(Acceptance(a, False, {}, (), (why,), given=tuple(others),
                                         dropped=True))
            return sel, fit, SelectionStep(b, (b, a), (score, current), fit.log), rss
    return None


def one_per_effect(tried: Sequence[tuple], chosen: GaussNewtonFit) -> list[tuple]:
    """The refined contenders of a contest, one per effect (an effect refined from its
    screening estimate and from its force start has two): the added one's ``chosen`` fit,
    each other's lowest AICc; in AICc order."""
    added = next(t[1].effect for t in tried if t[2] is chosen)
    out: dict[str, tuple] = {}
    for t in sorted(tried, key=lambda t: t[0]):
        effect = t[1].effect
        if t[2] is chosen or (effect != added and effect not in out):
            out[effect] = t
    return sorted(out.values(), key=lambda t: t[0])


def judging_order(scored: Sequence[tuple[float, str]], rivals: Collection[str]) -> list[str]:
    """The refined contenders the acceptance judges, by refined AICc (``scored``: (AICc,
    effect)): every contender that is not a rival, and a rival only when its AICc is
    below every other contender's (it beat them on the replays, :func:`is_rival`)."""
    best_other = min((a for a, e in scored if e not in rivals), default=np.inf)
    return [e for a, e in sorted(scored, key=lambda t: t[0])
            if e not in rivals or a < best_other]


def _conditional_row(r: CandidateStats) -> ConditionalRow:
    return ConditionalRow(r.effect, r.heldout_error_reduction, r.heldout_error_reduction_stance,
                          r.delta_aicc, r.inclusion_probability, r.effect_size, r.significant)


def refine(problem: Problem, candidates: CandidateSet, cal: CalibrationStage, res: Residuals,
           scr: Screening, pool: ReplayPool, *, n_boot: int, seed: int, max_effects: int,
           max_contenders: int, refine_iterations: int,
           starts: Sequence[ForceStart] = ()) -> Refinement:
    """Add at most ``max_effects`` effects: ``max_contenders`` significant candidates, and
    the indistinguishable partners of the leading one (:func:`contenders_for`; measured
    against the calibrated model for the first addition, against the current model after
    one), are each refined by ``refine_iterations`` replay Gauss–Newton iterations; the
    lowest refined AICc that passes the acceptance is added.

    ``starts``: force starts (:mod:`.force_start`) that met their evidence rule; before
    the first addition is judged each is refined from its start too (its value and ζ),
    and competes as a rival unless it is a contender already (then both refinements are
    judged in AICc order, and the first that passes counts). Like a rival it only wins:
    it is not tried again as the fallback of rejected contenders."""
    windows, channels, edges = problem.windows, problem.channels, problem.edges
    geo = res.geometry
    base_keys = list(scr.base_keys)
    cand_keys = candidates.keys
    selected: list[str] = []
    fitted: Mapping[str, Mapping[str, float]] = {}
    theta_final = dict(cal.theta)
    final_preds = res.base_preds
    stats = list(scr.ranking)
    steps: list[SelectionStep] = []
    acceptance: list[Acceptance] = []
    refined_fits: dict[str, list[RefinedFit]] = {r.effect: [] for r in scr.ranking}
    conditional: dict[str, list[ConditionalResult]] = {r.effect: [] for r in scr.ranking}

    def conditional_test(fit: GaussNewtonFit) -> list[CandidateStats]:
        """The candidates not added, re-tested against the current model (``selected`` at
        ``fitted``, linearised around it; the sensitivities of the added ones from ``fit``);
        each result is recorded in ``conditional``, and the collinear pairs against that
        model in ``step_pairs`` (the next step's partners)."""
        nonlocal step_pairs
        R_cur = residual_cube(windows, final_preds, channels, edges)
        sens_c = dict(res.sens)
        sens_c.update(fit.sens_selected)
        geo_c = geo.shifted(_values(fitted, candidates, selected), _neutral(candidates, selected))
        b_c = dict(scr.bounds)
        for s in selected:
            for c in candidates.columns[s]:
                cur = fitted[s][c.param]
                b_c[c.key] = (c.lower - cur, c.upper - cur)
        for c in nuisance_columns(theta_final):
            b_c[c.key] = c.bounds
        keys_fixed = base_keys + [k for s in selected for k in cand_keys[s]]
        regs_c = scr.builder.build(R_cur, sens_c, geo_c, b_c, keys_fixed)
        reg_c = regs_c.regression
        rest = {n: k for n, k in cand_keys.items() if n not in selected}
        out = candidate_stats(reg_c, keys_fixed, rest, candidates.columns, candidates.infos,
                              n_boot=n_boot, seed=seed, max_effects=max_effects - len(selected),
                              not_twins=scr.not_twins)
        # collinear pairs only: a near tie of the bootstrap among what an addition left is
        # weak evidence, and its partner would be the fallback of a refused leader
        step_pairs = tuple(p for p in indistinguishable(
            reg_c, keys_fixed, rest, out, windows, candidates.infos,
            Regression(regs_c.stance, b_c, keys_fixed, seed=seed))
            if abs(p.correlation) >= INDISTINGUISHABLE_CORRELATION
            and not twins & set(p.effects))
        for r in out:
            conditional[r.effect].append(ConditionalResult(tuple(selected),
                                                           r.heldout_error_reduction,
                                                           r.significant))
        return out

    twins = {t.effect for t in scr.strength_twins}
    step_pairs: tuple[IndistinguishablePair, ...] = ()
    rivals_of: dict[str, list[tuple[str, dict[str, float]]]] = {}
    for _ in range(1 + MAX_DROPS):     # a drop (rejudge_earlier) makes room again
        while len(selected) < max_effects:
            rejected = rejected_against(acceptance, selected)
            # the leader's partners: against the calibrated model, then the current one
            pairs = scr.indistinguishable if not selected else step_pairs
            contenders = contenders_for(stats, selected, rejected, max_contenders, pairs, twins)
            # the force starts: once, for the first addition (against the calibrated model)
            fresh = ([s for s in starts if s.effect not in twins]
                     if not selected and not acceptance else [])
            if not contenders and not fresh:
                break
            rivals = {r.effect for r in contenders} - {r.effect for r in contenders_for(
                stats, selected, rejected, max_contenders, pairs, twins, with_rivals=False)}
            prev_vals = _values(fitted, candidates, selected)
            tried = []
            for r in contenders:
                start = dict(prev_vals)
                for p, est in r.params.items():
                    start[f"{r.effect}.{p}"] = float(est.value)
                sel = selected + [r.effect]
                # every contender fully refined: AICc compares the models at their optima,
                # not after one step from the linear estimates (which favours the faster-
                # converging)
                fit = refine_replays(problem, pool, res, candidates, sel, start,
                                     nuisance_columns(theta_final),
                                     iterations=refine_iterations)
                score, rss = refined_aicc(problem, candidates, res, scr, fit.preds,
                                          fit.fitted, sel)
                tried.append((score, r, fit))
                refined_fits[r.effect].append(RefinedFit(tuple(selected), score, rss,
                                                         dict(fit.fitted[r.effect])))
            for st in fresh:
                r = next(r for r in stats if r.effect == st.effect)
                fit = refine_replays(problem, pool, res, candidates, [st.effect],
                                     {f"{st.effect}.{st.param}": st.value},
                                     nuisance_columns({**theta_final, "zeta": st.zeta}),
                                     iterations=refine_iterations)
                score, rss = refined_aicc(problem, candidates, res, scr, fit.preds,
                                          fit.fitted, [st.effect])
                refined_fits[st.effect].append(RefinedFit((), score, rss,
                                                          dict(fit.fitted[st.effect])))
                if all(t[1].effect != st.effect for t in tried):
                    rivals.add(st.effect)
                tried.append((score, r, fit))       # beside its screening path, if any
            tried.sort(key=lambda t: t[0])
            chosen = None
            judged = set(judging_order([(t[0], t[1].effect) for t in tried], rivals))
            for _, cand, fit in tried:            # by AICc; the first that passes is added
                if cand.effect not in judged:
                    continue                      # a rival only wins, it is no fallback
                # the term's own replays: with and without it at the same (co-refitted) θ
                before = without_term(pool, res, candidates, fit, selected)
                info = candidates.infos[cand.effect]
                acc = replace(judge(windows, channels, res.sigma, info,
                                    fit.fitted[cand.effect], before, fit.preds,
                                    torque_evidence(problem.joint_rows, info,
                                                    fit.fitted[cand.effect])),
                              given=tuple(selected))
                acceptance.append(acc)
                if acc.accepted:
                    chosen = (cand, fit)
                    break
            if chosen is None:
                continue                          # the next significant candidates, if any
            best, fit = chosen
            selected.append(best.effect)
            fitted, theta_final, final_preds = fit.fitted, dict(fit.theta), fit.preds
            tried = one_per_effect(tried, fit)
            rivals_of[best.effect] = [(t[1].effect, dict(t[2].fitted[t[1].effect]))
                                      for t in tried if t[1].effect != best.effect]
            step = dict(added=best.effect, contenders=tuple(t[1].effect for t in tried),
                        contender_aicc=tuple(t[0] for t in tried), refine=fit.log)
            if len(selected) >= max_effects:
                steps.append(SelectionStep(**step))
                break
            stats = conditional_test(fit)
            steps.append(SelectionStep(**step,
                                       conditional=tuple(_conditional_row(r) for r in stats)))
        if len(selected) < 2:
            break
        selected, fitted, theta_final, final_preds, refit = rejudge_earlier(
            problem, pool, res, candidates, selected, fitted, theta_final, final_preds,
            acceptance, refine_iterations)
        if refit is None:
            break
        stats = conditional_test(refit)   # room again: the rest against the reduced model
    if len(selected) >= 2:
        swap = exchange_terms(problem, pool, res, scr, candidates, selected, fitted,
                              theta_final, final_preds, rivals_of, acceptance,
                              refine_iterations)
        if swap is not None:
            selected, fit, step, rss = swap
            steps.append(step)
            fitted, theta_final, final_preds = fit.fitted, dict(fit.theta), fit.preds
            score = step.contender_aicc[0]
            for name in selected:
                refined_fits[name].append(RefinedFit(tuple(s for s in selected if s != name),
                                                     score, rss, dict(fit.fitted[name])))
    return Refinement(tuple(selected), fitted, theta_final, tuple(final_preds),
                      _final_ranking(scr.ranking, selected, fitted, refined_fits, conditional,
                                     acceptance),
                      tuple(steps),
                      _refined_heldout(problem, candidates, res, scr, selected, fitted,
                                       final_preds) if selected else None,
                      tuple(acceptance))


def _final_ranking(ranking, selected, fitted, refined_fits, conditional,
                   acceptance=()) -> tuple[Ranked, ...]:
    """The added effects (in the order the refined fits chose them), then the others by
    their screening held-out error reduction."""
    order = {n: i for i, n in enumerate(selected)}
    why = {a.effect: a.reasons for a in acceptance
           if not a.accepted and a.effect not in selected}     # the last judgement
    entries = sorted(ranking, key=lambda e: (order.get(e.effect, len(order)), e.rank))
    out = []
    for i, e in enumerate(entries):
        base = {f: getattr(e, f) for f in CandidateStats.__dataclass_fields__}
        base["rank"] = i + 1
        out.append(Ranked(**base, refined_fits=tuple(refined_fits[e.effect]),
                          conditional=tuple(conditional[e.effect]), added=e.effect in selected,
                          linear_rank=e.rank,
                          refined_params=dict(fitted[e.effect]) if e.effect in fitted else None,
                          not_added_because=tuple(why.get(e.effect, ()))))
    return tuple(out)


def _refined_heldout(problem, candidates, res, scr, selected, fitted,
                     final_preds) -> RefinedHeldout:
    """Held-out statistics of the added effects along the secant from the calibrated to
    the refined model (both replayed): exact at both ends, linear in between."""
    geo = res.geometry
    base_keys = list(scr.base_keys)
    R_fin = residual_cube(problem.windows, final_preds, problem.channels, problem.edges)
    sens_f = dict(res.sens)
    sens_f["secant"] = res.R - R_fin                  # prediction change base → final
    g_sec = np.zeros(len(problem.windows))
    for s in selected:
        for c in candidates.columns[s]:
            if c.key in geo.sens:
                g_sec = g_sec + geo.sens[c.key] * (fitted[s][c.param] - c.neutral)
    geo_f = GeometryRows(geo.y, geo.sigma, {"secant": g_sec})
    b_f = dict(scr.bounds)
    b_f["secant"] = SECANT_BOUNDS
    reg_f = scr.builder.build(res.R, sens_f, geo_f, b_f, base_keys).regression
    cv0, cv1 = reg_f.cv(base_keys), reg_f.cv(base_keys + ["secant"])
    return RefinedHeldout(
        1.0 - cv1.sse / cv0.sse if cv0.sse > 0 else 0.0,
        1.0 - cv1.sse_stance / cv0.sse_stance if cv0.sse_stance > 0 else 0.0,
        channel_heldout(reg_f, base_keys, ["secant"], problem.channels, stance=True),
        REFINED_HELDOUT_NOTE)


__all__ = ["Refinement", "refine", "refined_aicc", "exchange_terms", "judge_in_model",
           "contenders_for", "is_rival", "judging_order", "rejected_against",
           "rejudge_earlier", "replay_with", "MAX_DROPS", "without_term", "SECANT_BOUNDS"]
