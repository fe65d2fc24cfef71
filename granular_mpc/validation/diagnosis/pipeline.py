"""``diagnose``: calibrate, then find, rank and localise the effect the model is missing.

The stages, each a function returning a frozen result (``docs/validation.md`` §3):
:func:`.calibration.calibrate_model` → :func:`.residuals.compute_residuals` →
:func:`.screen.screen` → :func:`.refine.refine` → :func:`.localise.localise_models` →
:func:`.verdict.decide` → :mod:`.report`.
"""

from __future__ import annotations

import time as _time
from dataclasses import replace
from pathlib import Path
from typing import Any, Mapping, Sequence

from ...config import SimConfig
from ...effects import load_effect_file
from ...output import make_output_folder
from ..dataformat import load_dataset
from ..replay.pool import ReplayPool
from ..restarts import check_segments
from .calibration import calibrate_model
from .candidates import (CandidateSet, build_candidates, check_sensor_candidates, drop_dead_candidates,
                         drop_uninvertible_sensor_candidates,
                         drop_diverged_candidates, kept_sensitivities)
from .coverage import (assess_candidates, calibration_text, can_calibrate,
                       drop_unreadable_sensor_candidates, fixed_calibration, measured_problem,
                       write_coverage)
from .force_leftover import ForceLeftover, force_leftover, inapplicable
from .force_start import force_starts
from .joint_proposal import equation_rows
from .localise import localise_models, where_summary
from .problem import Problem, load_problem
from .proposal import pointed_proposal, propose_terms
from .refine import refine
from .sinking_law import law_preferred
from .report import figures as make_figures
from .report import write_outputs
from .residuals import compute_residuals, replay_rmse
from .result import (CalibrationReport, Diagnosis, DesignSummary, LocalizationReport,
                     NEffFactor, Recommended)
from .screen import screen, screening_design
from .strength import add_strength_sensitivity, not_twins, strength_models, twin_suspects
from .untested import with_untested
from .verdict import VerdictInputs, best_candidate_statement, decide


def added_force_leftover(problem: Problem, cands: CandidateSet, theta: Mapping[str, float],
                         selected: Sequence[str], fitted: Mapping[str, Mapping[str, float]],
                         *, seed: int) -> tuple[ForceLeftover, ...]:
    """:func:`.force_leftover.force_leftover` of the added effects at their fitted values;
    () when nothing was added or an addition changes what the equation error reads."""
    if not selected or inapplicable(selected, cands):
        return ()
    values = []
    for name in selected:
        p = cands.infos[name].neutral_params()
        p.update(fitted.get(name, {}))
        values.append((cands.infos[name], p))
    return force_leftover(problem, theta, values, seed=seed)


def diagnose(data_dir: str | Path, out_dir: str | Path | None = None, *,
             candidates: Sequence[str] | None = None, seed: int = 0,
             terrain: Any = "dry_sand", sim: SimConfig | None = None,
             workers: int | None = None, n_boot: int = 200, phase_bins: int = 10,
             max_effects: int = 2, refine_iterations: int = 2,
             calibrate_params: Sequence[str] = ("zeta",), max_contenders: int = 2,
             effect_files: Sequence[str | Path] = (), figures: bool = True,
             replay_segments: int = 1) -> Diagnosis:
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
        replay_segments: replays per stance: each stance is replayed again from the
            measured state ``replay_segments − 1`` times (multiple shooting within the
            stance, :mod:`~granular_mpc.validation.restarts`; needs measured intrusion).
            Shorter replays drift less from noisy first states; ``docs/validation.md``
            §5.3.14 measures what that does to the diagnosis (default 1: whole stances).

    Returns:
        :class:`~.result.Diagnosis`.
    """
    t_start = _time.perf_counter()
    timing: dict[str, float] = {}
    replay_segments = check_segments(replay_segments)
    for f in effect_files:
        load_effect_file(str(f))
    ds = load_dataset(data_dir)
    # checked before the replays, so that a bad folder does not cost the computation
    out = make_output_folder(out_dir) if out_dir is not None else None
    cands = build_candidates(candidates)
    problem = load_problem(data_dir, terrain=terrain, sim=sim, phase_bins=phase_bins, dataset=ds,
                           segments=replay_segments)
    # declared channels (coverage.py): score the measured ones; sensor candidates reading
    # an unmeasured column cannot be assessed
    problem = measured_problem(problem, ds)
    # the joint-torque equation error a joint term's torque is judged on (torque_evidence.py)
    problem = replace(problem, joint_rows=equation_rows(ds, problem.biped,
                                                        problem.sample_rate_hz))
    cands, unreadable = drop_unreadable_sensor_candidates(cands, problem.windows[0],
                                                          problem.joint_names, ds)
    # every sensor candidate tried on the data's columns before any replay
    cands = check_sensor_candidates(cands, problem.windows[0], problem.joint_names)
    cands, uninvertible = drop_uninvertible_sensor_candidates(cands, problem.windows[0],
                                                              problem.joint_names)
    timing["prepare"] = _time.perf_counter() - t_start

    t0 = _time.perf_counter()
    cal = (calibrate_model(problem, cands, params=calibrate_params, seed=seed)
           if can_calibrate(ds) else fixed_calibration(problem, cands, calibrate_params,
                                                       intrusion=ds.has("intrusion")))
    timing["calibrate"] = _time.perf_counter() - t0
    # a term outside the library, from the force equation error (proposal.py)
    t0 = _time.perf_counter()
    proposal = (propose_terms(problem, cal.theta, seed=seed, dataset=ds)
                if can_calibrate(ds) else None)
    timing["proposal"] = _time.perf_counter() - t0
    # the user's and proposed terrain forces fitted with ζ on the same error (force_start.py)
    starts = force_starts(problem, cands, cal.theta) if can_calibrate(ds) else ()
    with ReplayPool(cal.replay_model, problem.windows, workers=workers) as pool:
        t0 = _time.perf_counter()
        res = compute_residuals(problem, cands, cal, pool)
        res = add_strength_sensitivity(problem, cal, res, pool)     # φ_s, contact: tested against
        computed = cands
        cands, warns = drop_dead_candidates(cands, res.sens, problem.channels)
        cands, diverged = drop_diverged_candidates(cands, res.sens, res.R)
        warns = tuple(warns) + uninvertible + diverged
        cands, coverage = assess_candidates(problem, ds, cands, res, unreadable,
                                            calibration_text(ds), nuisance=cal.nuisance)
        warns = tuple(warns) + coverage.warnings
        # a dropped candidate's undefined cells must not take rows from the others
        res = replace(res, sens=kept_sensitivities(res.sens, computed, cands))
        timing["replays"] = _time.perf_counter() - t0
        t0 = _time.perf_counter()
        sd = screening_design(problem, cands, cal.nuisance, res, seed=seed,
                              strength=cal.strength)
        # the terrain file's φ_s and contact regime refined by replays, group by group, the
        # candidates that could pass replayed there: tested against (strength.py)
        suspects = twin_suspects(sd.regression, sd.base_keys, cands.keys)
        if suspects:
            sd = replace(sd, strength_models=strength_models(problem, cands.without(
                [n for n in cands.keys if n not in suspects]), cal, res, pool, seed=seed))
        timing["design"] = _time.perf_counter() - t0
        t0 = _time.perf_counter()
        scr = screen(problem, cands, sd, n_boot=n_boot, seed=seed, max_effects=max_effects,
                     not_twins=not_twins(cands, proposal))
        timing["rank"] = _time.perf_counter() - t0
        t0 = _time.perf_counter()
        ref = refine(problem, cands, cal, res, scr, pool, n_boot=n_boot, seed=seed,
                     max_effects=max_effects, max_contenders=max_contenders,
                     refine_iterations=refine_iterations,
                     starts=[s for s in starts if s.passes and s.effect in cands.infos])
        timing["refine"] = _time.perf_counter() - t0
    t0 = _time.perf_counter()
    n_fitted = len(cal.nuisance) + sum(len(cands.columns[s]) for s in ref.selected)
    loc = localise_models(problem, res, scr.regression, cal.nuisance,
                          ref.final_preds if ref.selected else None, n_fitted, seed=seed)
    timing["localize"] = _time.perf_counter() - t0
    theta = dict(ref.theta) if ref.selected else dict(loc.theta_linear)
    t0 = _time.perf_counter()
    force_left = added_force_leftover(problem, cands, cal.theta, ref.selected, ref.fitted,
                                      seed=seed) if proposal is not None else ()
    # an added term whose own law fits the sinking-sample force worse (sinking_law.py)
    law_pref = law_preferred(problem, cands, cal.theta, ref.selected, proposal)
    timing["force_leftover"] = _time.perf_counter() - t0
    vin = VerdictInputs(ref.selected, ref.ranking, ref.refined_heldout, loc.after, loc.before,
                        ref.acceptance, scr.indistinguishable, coverage.indistinguishable,
                        scr.strength_twins, force_left, ref.steps, law_pref)
    verdict = decide(vin)
    best = best_candidate_statement(vin)
    verdict, proposal = pointed_proposal(verdict, best, proposal, out, str(data_dir))
    verdict = with_untested(verdict, best, cands.infos)
    reg = scr.regression
    design = DesignSummary(
        len(problem.windows), problem.n_trials, problem.channels, phase_bins, int(reg.y.size),
        int(reg.stance.y.size),
        NEffFactor(scr.regressions.systematic.n_eff_factor, scr.regressions.stance.n_eff_factor),
        dict(scr.regressions.systematic.sigma), scr.builder.group_unit, len(reg.splits),
        res.diverged, res.jumps, {n: i.kind for n, i in cands.infos.items()}, pool.n_replays,
        ref.steps, replay_segments)
    timing["total"] = _time.perf_counter() - t_start
    diag = Diagnosis(
        str(data_dir), verdict,
        CalibrationReport(cal.calibration, cal.free_phi_s, theta, loc.theta_linear),
        ref.ranking, scr.indistinguishable, ref.fitted,
        ref.refined_heldout.by_channel if ref.refined_heldout else {}, ref.refined_heldout,
        replay_rmse(problem, res.base_preds, ref.final_preds) if ref.selected else {},
        LocalizationReport(tuple(where_summary(loc.before, 6)), loc.before, loc.after,
                           tuple(where_summary(loc.after, 6)), loc.before.n_significant_cells,
                           loc.after.n_significant_cells, loc.before.n_major_cells,
                           loc.after.n_major_cells),
        design, Recommended.for_fit(theta, ref.fitted), timing, (), warns, ref.acceptance,
        best, out, proposal, strength_twins=tuple(scr.strength_twins),
        not_twins=scr.not_twins, force_left=force_left, force_starts=starts,
        law_preferred=law_pref)
    if out is None:
        return diag
    figs = (make_figures(out, loc.before, loc.after, ref.ranking, problem.channels,
                         problem.edges, res.R, loc.R_after, ref.selected) if figures else [])
    diag = replace(diag, figures=tuple(p.name for p in figs))
    write_coverage(out, coverage)                # read by the report's channel section
    write_outputs(diag, figs)
    return diag


__all__ = ["diagnose"]
