"""Proposed terms when nothing in the library fits (``docs/validation.md`` §3.6).

From the force equation error on the sinking samples (:mod:`.features`: measured foot
force − the calibrated model's closed-form force at the measured state), a sparse model
of the missing force is fitted per axis, first on the axis's physical velocity laws
alone (:data:`LAW_FEATURES`, :func:`law_fit`), else on the library of physically named features
(:mod:`.sparse`: STLSQ, threshold by trial-grouped cross-validation, stability selection
over resampled stances). The selected features become a terrain-force effect written as
a readable effect file in the plugin format (:func:`effect_source`), with units, the
expected held-out reduction and the evidence, which the user may rename, edit and pass
back with ``--effect-file``: it is then a candidate like any other, refitted on the
replays and judged by honest acceptance. The proposal itself is never added.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Mapping

import numpy as np

from ..dataformat import Dataset, load_dataset
from .features import (AXES, FEATURES, LIBRARY_INDEX, ForceSamples, feature, feature_names,
                       force_samples)
from .joint_proposal import joint_effect_names, joint_effect_source, propose_joint_terms
from .problem import Problem
from .proposal_records import AxisFit, Proposal, ProposedTerm, change_text
from .result import Verdict
from .sparse import SparseFit, sparse_fit

#: the proposed effect's name and its file in the diagnosis folder
PROPOSED_EFFECT = "proposed_force"
PROPOSAL_FILE = "proposed_effect.py"
#: an axis contributes terms when its stable refit removes this share of the held-out
#: equation error, and the fold-by-fold selection at least half of it
MIN_PROPOSAL_REDUCTION = 0.15
#: ... and when the force it explains, √(RMS_before² − RMS_after²) [N, foot level], is at
#: least this. Chosen on data sets without any missing foot force (seed 1, 7 stances × 3
#: trials, noise 1; ``docs/validation.md`` §3.6): five nulls (seed 201, 202 with the
#: model's plant; φ_s 33°, layer 4 cm, contact stiffness 1e5 at seed 201) explain
#: z 2.2–4.0 N, h 6.1–6.4 N with held-out reductions up to 83 %; the joint and
#: torque/encoder-sensor forms of ``bench/out_of_library.py`` (whose foot force law is
#: the model's) z 0.3–3.6 N, h 2.9–8.8 N. The forward axis carries a systematic
#: 6–9 N pattern of the closed form on null data, so a relative test alone proposed a
#: forward force on every data set (its replays diverge when it is fed back). The
#: out-of-library terrain forms explain z 8.8–16 N (vertical damping, hard layer),
#: h 10.0–11.5 N (quadratic shear drag, sole Coulomb friction)
MIN_EXPLAINED_FORCE = {"z": 5.0, "h": 9.5}
#: the physical velocity laws tried first on each axis, alone (ζ the only other column):
#: linear and quadratic damping of the sinking, and viscous, Coulomb and quadratic drag
#: along the heading. All are dissipative, so a coefficient must oppose the motion (≤ 0);
#: one of the wrong sign is dropped and the rest refitted. Fitted beside the whole library
#: instead, the law shared its force with the null pattern's features (depth, depth²,
#: time in stance: collinear with the sinking rate), and those were what the feedback run
#: then refitted (docs/validation.md §3.6)
LAW_FEATURES = {"z": ("v_z", "v_z_abs_v_z"), "h": ("v_h", "sign_v_h", "v_h_abs_v_h")}
#: the per-foot law tried beside them, alone (ζ the only other column): the right foot's
#: share of the terrain law's own force on the axis — a right track of other sand or a
#: worn right sole (either sign; ζ carries the left foot). Of the two stages that pass,
#: the one with the larger held-out reduction is proposed
PER_FOOT_FEATURES = {"z": ("right_law_z",), "h": ("right_law_h",)}
#: the depth-layer laws (:data:`~.features.LAYER_DEPTHS`), each tried alone on the vertical
#: axis (ζ the only other column; either sign, a share above −1): a layer of other
#: stiffness below an interface depth. The one with the largest held-out reduction competes
#: with the other stages
LAYER_FEATURES = {"z": tuple(f.name for f in FEATURES if not f.in_library), "h": ()}
#: ... tried only where at least this share of the sinking samples lies on each side of
#: the interface: a layer whose interface lies above (nearly) every sample is the law's
#: own depth profile reshaped (ζ and a 1/d share), one below (nearly) every sample a
#: handful of deep samples
MIN_LAYER_SHARE = 0.1
#: ... proposed when they pass :func:`axis_passes` with these least explained forces [N].
#: Set on null data (sand_walk, 3 trials × 7 stances, noise 1, the model's plant at seeds
#: 201, 202 and φ_s 33°, layer 4 cm, contact stiffness 1e5 at seed 201): the laws explain
#: z ≤ 2.3 N, h 3.6–4.5 N (a viscous −10 N·s/m per patch: the closed form's forward
#: pattern); the out-of-library forms of ``bench/out_of_library.py`` at seed 1: vertical
#: damping z 8.2–8.5 N, quadratic shear drag h 8.1–8.8 N, sole Coulomb offset h 7.1 N.
#: Held out (seeds 203–205; the three mismatches at seed 202): z ≤ 2.2 N, h 3.8–5.1 N
MIN_LAW_FORCE = {"z": 5.0, "h": 6.0}
#: fewest sinking samples a proposal is fitted on
MIN_SAMPLES = 50
#: a parameter's bounds in the effect file: this many times the proposed value
BOUND_FACTOR = 20.0
AXIS_WORDS = {"z": "vertical force (W z, up)", "h": "forward force (along the sole's heading)"}

NOTE = ("equation error of the foot force on the sinking samples (measured − the calibrated "
        "closed-form RFT force at the measured depth, pitch and direction of motion), fitted "
        "per axis by sequentially thresholded least squares with ζ unpenalised, the threshold "
        "chosen by trial-grouped cross-validation and the terms kept by stability selection "
        "over resampled stances. A hypothesis, never added: pass the file back with "
        "--effect-file to have it refitted on the replays and judged like any candidate. "
        "It sees only sinking (on rising or resting feet it is extrapolated).")


def propose_terms(problem: Problem, theta: Mapping[str, float], *, seed: int = 0,
                  dataset: Dataset | None = None) -> Proposal:
    """Fit the missing force on the feature library, and the joint torque equation error
    on the joint features (:mod:`.joint_proposal`).

    Args:
        problem: the diagnosis problem.
        theta: the calibrated parameters (``zeta``; ``phi_s`` if calibrated).
        seed: seed of the stability resamples.
        dataset: the problem's data set, if the caller has it loaded (None: loaded from
            ``problem.data_dir``).
    """
    p = _force_proposal(problem, theta, seed=seed)
    ds = dataset if dataset is not None else load_dataset(problem.data_dir)
    jt, jf, jnote = propose_joint_terms(ds, problem.biped, problem.sample_rate_hz, seed=seed,
                                        rows=problem.joint_rows)
    return replace(p, joint_terms=jt, joint_fits=jf, joint_note=jnote)


def explained_rms(rms_before: float, rms_after: float) -> float:
    """The RMS the terms explain, √(RMS_before² − RMS_after²) (0 when they explain none)."""
    return float(math.sqrt(max(rms_before ** 2 - rms_after ** 2, 0.0)))


def axis_passes(heldout_reduction: float, heldout_reduction_selected: float,
                rms_before: float, rms_after: float, axis: str,
                min_force: Mapping[str, float] = MIN_EXPLAINED_FORCE) -> bool:
    """The evidence rule of a force axis: the stable refit removes ≥
    :data:`MIN_PROPOSAL_REDUCTION` of the held-out equation error, the per-fold selection
    half of that, **and** the force explained is ≥ :data:`MIN_EXPLAINED_FORCE` [N] of the
    axis (above what data without any missing force explain)."""
    return bool(heldout_reduction_selected >= MIN_PROPOSAL_REDUCTION
                and heldout_reduction >= 0.5 * MIN_PROPOSAL_REDUCTION
                and explained_rms(rms_before, rms_after) >= min_force[axis])


def law_fit(fs: ForceSamples, axis: str, *, seed: int = 0,
            laws: Mapping[str, tuple[str, ...]] = LAW_FEATURES,
            dissipative: bool = True) -> SparseFit | None:
    """The sparse fit of one axis on its physical laws alone (``laws[axis]``, ζ
    unpenalised); when ``dissipative``, coefficients of the wrong physical sign (> 0) are
    dropped and the rest refitted; arrays over all of :data:`FEATURES` (0 / unselected
    outside the laws).

    Args:
        fs: the equation-error samples.
        axis: ``z`` or ``h``.
        seed: seed of the stability resamples.
        laws: axis → feature names (:data:`LAW_FEATURES`, :data:`PER_FOOT_FEATURES`).
        dissipative: whether a coefficient must oppose the motion (≤ 0).

    Returns:
        The fit, or None when no law is left.
    """
    idx = [feature_names().index(n) for n in laws[axis]]
    while idx:
        fit = sparse_fit(fs.features[:, idx], fs.nuisance[axis][:, None], fs.target[axis],
                         fs.trial, fs.window, seed=seed)
        wrong = {i for j, i in enumerate(idx)
                 if dissipative and fit.selected[j] and fit.coef[j] > 0}
        if not wrong:
            return _on_all_features(fit, np.array(idx))
        idx = [i for i in idx if i not in wrong]
    return None


def physical_shares(fit: SparseFit) -> bool:
    """Whether every selected share of the law's own force (:attr:`Feature.relative`) is
    above −1: a foot cannot lose more than all of the law's force (on the forward axis,
    where the law's force is small, a share of −5 has been fitted: not a worn sole)."""
    return all(fit.coef[k] > -1.0 for k in np.flatnonzero(fit.selected)
               if FEATURES[k].relative)


def law_stages(axis: str) -> tuple[tuple[str, Mapping[str, tuple[str, ...]], bool], ...]:
    """The law fits tried on ``axis`` before the whole library: (stage, laws, dissipative)
    — the velocity laws together, the per-foot law, and each depth-layer law alone."""
    return ((("law", LAW_FEATURES, True), ("per_foot", PER_FOOT_FEATURES, False))
            + tuple(("layer", {axis: (name,)}, False) for name in LAYER_FEATURES[axis]))


def layer_splits(fs: ForceSamples, name: str) -> bool:
    """Whether the layer feature ``name`` splits the sinking samples: at least
    :data:`MIN_LAYER_SHARE` of them on each side of its interface."""
    below = float(np.mean(fs.features[:, feature_names().index(name)] != 0.0)) if fs.n else 0.0
    return MIN_LAYER_SHARE <= below <= 1.0 - MIN_LAYER_SHARE


def library_fit(fs: ForceSamples, axis: str, *, seed: int = 0) -> SparseFit:
    """The sparse fit of one axis on the whole library (the features with
    ``in_library``), arrays over all of :data:`FEATURES`."""
    fit = sparse_fit(fs.features[:, LIBRARY_INDEX], fs.nuisance[axis][:, None],
                     fs.target[axis], fs.trial, fs.window, seed=seed)
    return _on_all_features(fit, LIBRARY_INDEX)


def best_law(fs: ForceSamples, axis: str, *, seed: int = 0) -> tuple[SparseFit | None, str]:
    """The best passing law fit of an axis (:func:`law_stages`): of the velocity laws,
    the per-foot law and the depth-layer laws, the one that removes most of the held-out
    error; (None, "") when none passes."""
    best: tuple[SparseFit | None, str] = (None, "")
    for stage, laws, dissipative in law_stages(axis):
        if stage == "layer" and not layer_splits(fs, laws[axis][0]):
            continue
        fit = law_fit(fs, axis, seed=seed, laws=laws, dissipative=dissipative)
        ok = fit is not None and bool(fit.selected.any()) and axis_passes(
            fit.heldout_reduction, fit.heldout_reduction_selected, fit.rmse_before,
            fit.rmse_after, axis, MIN_LAW_FORCE) and physical_shares(fit)
        if ok and (best[0] is None or fit.heldout_reduction_selected
                   > best[0].heldout_reduction_selected):
            best = (fit, stage)
    return best


def _on_all_features(fit: SparseFit, idx: np.ndarray) -> SparseFit:
    """A fit on the columns ``idx`` of :data:`FEATURES` spread over all of them."""
    F = len(FEATURES)

    def spread(v, fill):
        out = np.full(F, fill, dtype=np.asarray(v).dtype)
        out[idx] = v
        return out

    return replace(fit, coef=spread(fit.coef, 0.0), frequency=spread(fit.frequency, 0.0),
                   selected=spread(fit.selected, False), stderr=spread(fit.stderr, np.nan))


def _force_proposal(problem: Problem, theta: Mapping[str, float], *, seed: int = 0) -> Proposal:
    """The foot-force part of :func:`propose_terms`."""
    n_slices = int(problem.biped.config.foot.slices)
    fs = force_samples(problem.windows, problem.replay_model.terrain, theta, n_slices=n_slices)
    n_st = int(np.unique(fs.window).size) if fs.n else 0
    if fs.n < MIN_SAMPLES:
        return Proposal(PROPOSED_EFFECT, "", (), (), fs.n, n_st,
                        note=f"{fs.n} sinking samples (< {MIN_SAMPLES}): nothing proposed")
    terms: list[ProposedTerm] = []
    axes: list[AxisFit] = []
    hidden: list[str] = []
    for ax in AXES:
        # the physical laws first; the whole library only when no law passes
        fit, stage = best_law(fs, ax, seed=seed)
        ok = fit is not None
        if not ok:
            fit, stage = library_fit(fs, ax, seed=seed), "library"
            ok = axis_passes(fit.heldout_reduction, fit.heldout_reduction_selected,
                             fit.rmse_before, fit.rmse_after, ax) and any(
                FEATURES[k].expressible for k in np.flatnonzero(fit.selected))
        axes.append(AxisFit(ax, fit.heldout_reduction, fit.heldout_reduction_selected,
                            fit.rmse_before, fit.rmse_after, fit.threshold, bool(ok), stage))
        if not ok:
            continue
        for k in np.flatnonzero(fit.selected):
            f = FEATURES[k]
            if not f.expressible:
                hidden.append(f"{ax}:{f.name}")
            c = float(fit.coef[k])
            unit = "N" if f.unit == "1" else "-" if f.relative else f"N/({f.unit})"
            terms.append(ProposedTerm(ax, f.name, f.description, c,
                                      c if f.relative else c / n_slices,
                                      float(fit.stderr[k]), unit, float(fit.frequency[k]),
                                      f.expressible))
    return Proposal(PROPOSED_EFFECT, "", tuple(terms), tuple(axes), fs.n, n_st, note=NOTE,
                    not_expressible=tuple(hidden))


def _param_name(t: ProposedTerm) -> str:
    return f"{t.axis}_{t.feature}"


def effect_source(p: Proposal, data: str = "") -> str:
    """The whole proposal (force, joint and torque-sensor effects) as one Python effect
    file in the plugin format (:data:`PROPOSAL_FILE`)."""
    return force_effect_source(p, data) + joint_effect_source(p.joint_terms, p.joint_fits,
                                                              _joint_names(p))


def force_effect_source(p: Proposal, data: str = "") -> str:
    """The force proposal alone as a Python effect file in the plugin format (empty when
    no expressible force term is proposed)."""
    terms = [t for t in p.terms if t.expressible]
    if not terms:
        return ""
    lines = ['"""A term proposed by `granular-mpc diagnose`' + (f" for {data}" if data else "")
             + ".", "", "What it is: the force the calibrated model lacks, per contact patch "
             "(world frame, SI units), as", "a sparse combination of physically named "
             "features of the sole's state:", ""]
    for ax in AXES:
        sel = [t for t in terms if t.axis == ax]
        if sel:
            lines.append(f"  {AXIS_WORDS[ax]} = " + " + ".join(
                f"{_param_name(t)}·[{t.description}]" for t in sel))
    lines += ["", "Evidence (trial-grouped cross-validation of the foot-force equation error):"]
    for a in p.axes:
        lines.append(f"  {a.axis}: held-out error "
                     f"{change_text(a.heldout_error_reduction_selected)} (selection redone "
                     f"per fold: {change_text(a.heldout_error_reduction)}), "
                     f"RMS {a.rms_before:.2f} → {a.rms_after:.2f} N"
                     + ("" if a.proposed else "  [not proposed]"))
    for t in terms:
        lines.append(f"  {_param_name(t)}: foot {t.coefficient_foot:.4g} ± "
                     f"{t.std_error:.2g} {t.unit}, selected in {100 * t.selection_frequency:.0f} % "
                     "of the stability resamples")
    if p.not_expressible:
        lines.append("  also selected but not readable by a terrain force: "
                     + ", ".join(p.not_expressible))
    lines += [f"  {p.n_samples} sinking samples from {p.n_stances} stances.", "",
              "Rename it, edit it, then pass it back (it is refitted on the replays and "
              "judged like any candidate):", "",
              f"    granular-mpc diagnose DATA --effect-file {p.effect}.py --out DIAG2",
              "", "Method: " + p.note, '"""', "",
              "from granular_mpc.effects import Param, describe_effect, register_effect", "",
              f"@register_effect({p.effect!r}, replace=True, params={{"]
    for t in terms:
        c = t.coefficient_patch
        bound = BOUND_FACTOR * abs(c) if c != 0 else 1.0
        # a share of the law's own force cannot take away more than all of it
        low = max(-bound, -1.0) if feature(t.feature).relative else -bound
        phys = (0.0, bound) if c > 0 else (low, 0.0)
        doc = f"{AXIS_WORDS[t.axis]} per {t.description}, per patch"
        lines.append(f"    {_param_name(t)!r}: Param({c:.6g}, {-bound:.6g}, {bound:.6g}, "
                     f"{t.unit!r}, {doc!r}, physical=({phys[0]:.6g}, {phys[1]:.6g})),")
    lines += ["})", f"def {p.effect}(o, s, p):",
              '    """The proposed force on one contact patch [N], world frame."""']
    for ax in AXES:
        sel = [t for t in terms if t.axis == ax]
        expr = " + ".join(f"p[{_param_name(t)!r}] * {feature(t.feature).patch_expression}"
                          for t in sel) or "0.0"
        lines.append(f"    f_{ax} = ({expr}) * s.in_contact")
    lines += ["    return (f_h * s.heading[0], f_h * s.heading[1], f_z)", "", "",
              # every term switches off at 0 (else "off" would keep all but the main term
              # on: a wrong base model and only the main term refitted)
              f"describe_effect({p.effect!r}, neutral={{"
              + ", ".join(f"{_param_name(t)!r}: 0.0" for t in terms) + "}, depends_on=("
              + ", ".join(repr(feature(t.feature).description) for t in terms)
              + ("," if len(terms) == 1 else "") + "))", ""]
    return "\n".join(lines)


def effect_sources(p: Proposal, data: str = "") -> dict[str, str]:
    """One effect file per proposed effect (file name → source): each passes back alone."""
    out = {}
    force = force_effect_source(p, data)
    if force:
        out[f"{p.effect}.py"] = force
    for name in joint_effect_names(p.joint_terms):
        out[f"{name}.py"] = joint_effect_source(p.joint_terms, p.joint_fits, _joint_names(p),
                                                effects=(name,), data=data).lstrip("\n")
    return out


def _joint_names(p: Proposal) -> tuple[str, ...]:
    return tuple(f.joint for f in p.joint_fits)


def proposed_effects(p: Proposal | None) -> tuple[str, ...]:
    """The effects the proposal's file registers (force, joint, torque sensor)."""
    if p is None:
        return ()
    force = (p.effect,) if any(t.expressible for t in p.terms) else ()
    return force + joint_effect_names(p.joint_terms)


def write_proposal(out_dir: Path, p: Proposal, data: str = "") -> Proposal:
    """Write the effect files into ``out_dir`` (when anything expressible is proposed):
    one per proposed effect (``<effect>.py``, each met its evidence rule and passes back
    alone) and all of them together in :data:`PROPOSAL_FILE`."""
    if not proposed_effects(p):
        return p
    files = []
    for name, text in effect_sources(p, data).items():
        (Path(out_dir) / name).write_text(text, encoding="utf-8")
        files.append(name)
    (Path(out_dir) / PROPOSAL_FILE).write_text(effect_source(p, data), encoding="utf-8")
    return replace(p, file=PROPOSAL_FILE, files=tuple(files))


def proposal_sentence(p: Proposal | None) -> str:
    """One sentence pointing to the proposal (empty: none)."""
    if p is None or not p.file:
        return ""
    red = max([a.heldout_error_reduction_selected for a in p.axes if a.proposed]
              + [f.heldout_error_reduction_selected for f in p.joint_fits if f.proposed],
              default=math.nan)
    names = ", ".join([f"{t.axis}:{t.feature}" for t in p.terms if t.expressible]
                      + [f"{t.joint}:{t.feature}" for t in p.joint_terms])
    files = " or ".join(p.files) or p.file
    return (f"A term outside the library is proposed in {files} ({names}; held-out foot-force "
            f"or joint-torque equation error {change_text(red)}): read it, then pass it back with "
            f"--effect-file {p.files[0] if len(p.files) == 1 else 'FILE'}"
            + (f" (one file per effect; all of them: {p.file})" if len(p.files) > 1 else ""))


#: verdicts that point to a proposal (and a best candidate that is only a proxy)
POINTING_VERDICTS = ("unexplained_structure", "partially_explained")


def not_a_clean_answer(verdict: Verdict, best_candidate: str) -> bool:
    """Whether the verdict is one of :data:`POINTING_VERDICTS` or its best candidate is
    only the closest proxy: the verdicts that point beyond the candidates."""
    return verdict.status in POINTING_VERDICTS or "only the closest proxy" in best_candidate


def pointed_proposal(verdict: Verdict, best_candidate: str, p: Proposal | None,
                     out_dir: Path | None, data: str = "") -> tuple[Verdict, Proposal | None]:
    """Write the proposal's effect file into ``out_dir`` and, when the verdict is
    ``unexplained_structure`` / ``partially_explained`` or the best candidate is only the
    closest proxy, point the verdict's text to it."""
    if p is None or not p.proposed:
        return verdict, p
    if out_dir is not None:
        p = write_proposal(out_dir, p, data)
    sentence = proposal_sentence(p)
    if not (not_a_clean_answer(verdict, best_candidate) and sentence):
        return verdict, p
    return replace(verdict, text=f"{verdict.text}. {sentence}"), replace(p, pointed_to=True)


__all__ = ["proposed_effects", "pointed_proposal", "POINTING_VERDICTS", "not_a_clean_answer",
           "propose_terms",
           "effect_source", "force_effect_source", "effect_sources", "write_proposal",
           "proposal_sentence", "axis_passes", "law_fit", "physical_shares", "LAW_FEATURES",
           "PER_FOOT_FEATURES", "LAYER_FEATURES", "MIN_LAYER_SHARE", "layer_splits",
           "law_stages", "best_law", "library_fit", "MIN_LAW_FORCE", "explained_rms",
           "PROPOSED_EFFECT", "PROPOSAL_FILE", "MIN_PROPOSAL_REDUCTION", "MIN_EXPLAINED_FORCE"]
