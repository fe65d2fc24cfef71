"""Proposed terms when nothing in the library fits (``docs/validation.md`` §3.6).

From the force equation error on the sinking samples (:mod:`.features`: measured foot
force − the calibrated model's closed-form force at the measured state), a sparse model
of the missing force is fitted per axis on the library of physically named features
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

from ..dataformat import load_dataset
from .features import AXES, FEATURES, force_samples
from .joint_proposal import joint_effect_names, joint_effect_source, propose_joint_terms
from .problem import Problem
from .proposal_records import AxisFit, Proposal, ProposedTerm
from .result import Verdict
from .sparse import sparse_fit

#: the proposed effect's name and its file in the diagnosis folder
PROPOSED_EFFECT = "proposed_force"
PROPOSAL_FILE = "proposed_effect.py"
#: an axis contributes terms when its stable refit removes this share of the held-out
#: equation error, and the fold-by-fold selection at least half of it
MIN_PROPOSAL_REDUCTION = 0.15
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


def propose_terms(problem: Problem, theta: Mapping[str, float], *, seed: int = 0) -> Proposal:
    """Fit the missing force on the feature library, and the joint torque equation error
    on the joint features (:mod:`.joint_proposal`).

    Args:
        problem: the diagnosis problem.
        theta: the calibrated parameters (``zeta``; ``phi_s`` if calibrated).
        seed: seed of the stability resamples.
    """
    p = _force_proposal(problem, theta, seed=seed)
    jt, jf, jnote = propose_joint_terms(load_dataset(problem.data_dir), problem.biped,
                                        problem.sample_rate_hz, seed=seed)
    return replace(p, joint_terms=jt, joint_fits=jf, joint_note=jnote)


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
        fit = sparse_fit(fs.features, fs.nuisance[ax][:, None], fs.target[ax], fs.trial,
                         fs.window, seed=seed)
        ok = (fit.heldout_reduction_selected >= MIN_PROPOSAL_REDUCTION
              and fit.heldout_reduction >= 0.5 * MIN_PROPOSAL_REDUCTION
              and any(FEATURES[k].expressible for k in np.flatnonzero(fit.selected)))
        axes.append(AxisFit(ax, fit.heldout_reduction, fit.heldout_reduction_selected,
                            fit.rmse_before, fit.rmse_after, fit.threshold, bool(ok)))
        if not ok:
            continue
        for k in np.flatnonzero(fit.selected):
            f = FEATURES[k]
            if not f.expressible:
                hidden.append(f"{ax}:{f.name}")
            c = float(fit.coef[k])
            unit = "N" if f.unit == "1" else f"N/({f.unit})"
            terms.append(ProposedTerm(ax, f.name, f.description, c, c / n_slices,
                                      float(fit.stderr[k]), unit, float(fit.frequency[k]),
                                      f.expressible))
    return Proposal(PROPOSED_EFFECT, "", tuple(terms), tuple(axes), fs.n, n_st, note=NOTE,
                    not_expressible=tuple(hidden))


def _param_name(t: ProposedTerm) -> str:
    return f"{t.axis}_{t.feature}"


def effect_source(p: Proposal, data: str = "") -> str:
    """The proposal as a Python effect file in the plugin format."""
    from .features import feature

    terms = [t for t in p.terms if t.expressible]
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
        lines.append(f"  {a.axis}: held-out error −{100 * a.heldout_error_reduction_selected:.0f} % "
                     f"(selection redone per fold: −{100 * a.heldout_error_reduction:.0f} %), "
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
              "    granular-mpc diagnose DATA --effect-file proposed_effect.py --out DIAG2",
              "", "Method: " + p.note, '"""', "",
              "from granular_mpc.effects import Param, describe_effect, register_effect", "",
              f"@register_effect({p.effect!r}, replace=True, params={{"]
    for t in terms:
        c = t.coefficient_patch
        bound = BOUND_FACTOR * abs(c) if c != 0 else 1.0
        phys = (0.0, bound) if c > 0 else (-bound, 0.0)
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
    if not terms:          # only joint-axis terms: no terrain force is registered
        lines = lines[:lines.index("from granular_mpc.effects import Param, describe_effect, "
                                   "register_effect")]
    return "\n".join(lines) + joint_effect_source(p.joint_terms, p.joint_fits,
                                                  _joint_names(p))


def _joint_names(p: Proposal) -> tuple[str, ...]:
    return tuple(f.joint for f in p.joint_fits)


def proposed_effects(p: Proposal | None) -> tuple[str, ...]:
    """The effects the proposal's file registers (force, joint, torque sensor)."""
    if p is None:
        return ()
    force = (p.effect,) if any(t.expressible for t in p.terms) else ()
    return force + joint_effect_names(p.joint_terms)


def write_proposal(out_dir: Path, p: Proposal, data: str = "") -> Proposal:
    """Write the effect file into ``out_dir`` (when anything expressible is proposed)."""
    if not proposed_effects(p):
        return p
    path = Path(out_dir) / PROPOSAL_FILE
    path.write_text(effect_source(p, data), encoding="utf-8")
    return replace(p, file=path.name)


def proposal_sentence(p: Proposal | None) -> str:
    """One sentence pointing to the proposal (empty: none)."""
    if p is None or not p.file:
        return ""
    red = max([a.heldout_error_reduction_selected for a in p.axes if a.proposed]
              + [f.heldout_error_reduction_selected for f in p.joint_fits if f.proposed],
              default=math.nan)
    names = ", ".join([f"{t.axis}:{t.feature}" for t in p.terms if t.expressible]
                      + [f"{t.joint}:{t.feature}" for t in p.joint_terms])
    return (f"A term outside the library is proposed in {p.file} ({names}; held-out foot-force "
            f"or joint-torque equation error −{100 * red:.0f} %): read it, then pass it back with "
            f"--effect-file {p.file}")


#: verdicts that point to a proposal (and a best candidate that is only a proxy)
POINTING_VERDICTS = ("unexplained_structure", "partially_explained")


def pointed_proposal(verdict: Verdict, best_candidate: str, p: Proposal | None,
                     out_dir: Path | None, data: str = "") -> tuple[Verdict, Proposal | None]:
    """Write the proposal's effect file into ``out_dir`` and, when the verdict is
    ``unexplained_structure`` / ``partially_explained`` or the best candidate is only the
    closest proxy, point the verdict's text to it."""
    if p is None or not p.proposed:
        return verdict, p
    if out_dir is not None:
        p = write_proposal(out_dir, p, data)
    point = verdict.status in POINTING_VERDICTS or "only the closest proxy" in best_candidate
    sentence = proposal_sentence(p)
    if not (point and sentence):
        return verdict, p
    return replace(verdict, text=f"{verdict.text}. {sentence}"), replace(p, pointed_to=True)


__all__ = ["proposed_effects", "pointed_proposal", "POINTING_VERDICTS", "propose_terms", "effect_source", "write_proposal", "proposal_sentence",
           "PROPOSED_EFFECT", "PROPOSAL_FILE", "MIN_PROPOSAL_REDUCTION"]
