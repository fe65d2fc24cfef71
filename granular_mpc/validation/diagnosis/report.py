"""Stage 7, report: ``diagnosis.json``, the one-page ``report.md`` and its figures
(``docs/validation.md`` §3.5)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from ..prepare import channel_unit
from .acceptance_records import force_leftover_sentence
from .coverage import coverage_section
from .joint_proposal import joint_report_lines
from .localization_records import Localization
from .proposal import MIN_EXPLAINED_FORCE
from .proposal_records import Proposal, change_text
from .ranking_records import Ranked
from .result import DIAGNOSIS_FILE, REPORT_FILE, Diagnosis
from .thresholds import MIN_HELDOUT_REDUCTION, T_CELL

FIGURE_DPI = 110


def figures(out: Path, loc_before: Localization, loc_after: Localization,
            ranking: Sequence[Ranked], channels: Sequence[str], edges: np.ndarray,
            R: np.ndarray, R_after: np.ndarray, selected: Sequence[str]) -> list[Path]:
    """``residual_tstat.png`` (bias t-statistic, channel × phase, before/after),
    ``ranking.png`` and ``residual_profiles.png`` (mean residual of the most structured
    channels with 95 % bands) in ``out``.

    The layouts are fixed (margins from the longest tick label), not constrained: the
    constrained layout measured every text twice per figure (≈ 40 % of the drawing)."""
    matplotlib.use("Agg")
    channels = list(channels)
    return [tstat_figure(out / "residual_tstat.png", loc_before, loc_after, channels, edges,
                         bool(selected)),
            ranking_figure(out / "ranking.png", ranking),
            profiles_figure(out / "residual_profiles.png", loc_before, channels, edges, R,
                            R_after)]


def _label_width_in(labels: Sequence[str], fontsize: float) -> float:
    """Width [in] a tick label column of ``labels`` needs at ``fontsize`` [pt] (≈ 0.55 em
    per character, plus the ticks' padding)."""
    n = max((len(t) for t in labels), default=0)
    return 0.55 * fontsize / 72.0 * n + 0.12


def tstat_figure(path: Path, loc_before: Localization, loc_after: Localization,
                 channels: list[str], edges: np.ndarray, added: bool) -> Path:
    """The bias t-statistic heatmaps (channel × phase bin) before and after, at ``path``."""
    w, h = 11.0, 5.0
    fig = Figure(figsize=(w, h))
    lab = _label_width_in(channels, 7)
    left = (lab + 0.1) / w
    gap = lab + 0.35                       # [in] between the panels: the 2nd panel's labels
    cbar = 1.0                             # [in] colour bar and its label
    panel = (w - lab - 0.1 - gap - cbar - 0.15) / 2
    axes = [fig.add_axes((left, 0.12, panel / w, 0.8)),
            fig.add_axes((left + (panel + gap) / w, 0.12, panel / w, 0.8))]
    for ax, loc, title in ((axes[0], loc_before, "calibrated model"),
                           (axes[1], loc_after, "after added effects" if added
                            else "(nothing added)")):
        T = np.zeros((len(channels), len(edges) - 1))
        for cl in loc.cells:
            if cl.side != "all":
                continue
            c = channels.index(cl.channel)
            b = int(np.searchsorted(edges, cl.phase_lo + 1e-9) - 1)
            T[c, b] = cl.t
        lim = max(T_CELL * 2, float(np.nanmax(np.abs(T))) if T.size else 1.0)
        im = ax.imshow(T, aspect="auto", cmap="RdBu_r", vmin=-lim, vmax=lim)
        ax.set_yticks(range(len(channels)), labels=channels, fontsize=7)
        ax.set_xticks(range(len(edges) - 1), labels=[f"{edges[i]:g}" for i in range(len(edges) - 1)],
                      fontsize=7)
        ax.set_xlabel("stance phase bin start [%]")
        ax.set_title(f"residual bias t-statistic: {title}", fontsize=9)
    cax = fig.add_axes(((w - cbar + 0.05) / w, 0.12, 0.18 / w, 0.8))
    fig.colorbar(im, cax=cax, label="t (|t| ≥ %g: structure)" % T_CELL)
    fig.savefig(path, dpi=FIGURE_DPI)
    return path


def ranking_figure(path: Path, ranking: Sequence[Ranked]) -> Path:
    """The candidates' held-out error reduction as horizontal bars, at ``path``."""
    w, h = 7.0, 0.35 * max(len(ranking), 3) + 1.2
    fig = Figure(figsize=(w, h))
    names = [r.effect for r in ranking][::-1]
    left = _label_width_in(names, 10) + 0.1
    ax = fig.add_axes((left / w, 0.55 / h, 1 - (left + 0.2) / w, 1 - 0.9 / h))
    vals = [100 * r.heldout_error_reduction for r in ranking][::-1]
    colors = ["tab:green" if r.added else ("tab:orange" if r.significant else "tab:gray")
              for r in ranking][::-1]
    ax.barh(names, vals, color=colors)
    ax.axvline(100 * MIN_HELDOUT_REDUCTION, color="k", ls="--", lw=0.8)
    ax.set_xlabel("held-out error reduction [%] (green: added)")
    ax.set_title("candidate effects, trial-grouped cross-validation", fontsize=9)
    fig.savefig(path, dpi=FIGURE_DPI)
    return path


def profiles_figure(path: Path, loc_before: Localization, channels: list[str],
                    edges: np.ndarray, R: np.ndarray, R_after: np.ndarray) -> Path:
    """Mean residual profiles (95 % bands) of the most structured channels, before and
    after, at ``path``."""
    top: list[str] = []
    for cl in loc_before.significant_cells:
        if cl.channel not in top:
            top.append(cl.channel)
        if len(top) == 4:
            break
    if not top:
        top = channels[:4]
    rows = (len(top) + 1) // 2
    fig = Figure(figsize=(10, 2.6 * rows))
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.5 / (2.6 * rows),
                        top=1 - 0.3 / (2.6 * rows), wspace=0.22, hspace=0.55)
    axes = np.atleast_2d(fig.subplots(rows, 2))
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
    fig.savefig(path, dpi=FIGURE_DPI)
    return path


def _calibration_lines(d: Diagnosis) -> list[str]:
    cal = d.calibration
    eq = cal.equation_error
    lines = []
    for k, val in cal.values.items():
        conv = (math.degrees if k == "phi_s" else (lambda x: 1e3 * x) if k == "touchdown_depth"
                else (lambda x: x))
        name = {"phi_s": "phi_s [deg]", "touchdown_depth": "touchdown depth [mm]"}.get(k, k)
        gn = eq.ci_gn.get(k, [None, None])
        bt = eq.ci_boot.get(k, [None, None])

        def fmt(iv):
            return "–" if iv[0] is None else f"[{conv(iv[0]):.4g}, {conv(iv[1]):.4g}]"
        init = eq.initial.get(k, 0.0)
        eqv = eq.values.get(k)
        eq_txt = "–" if eqv is None else f"{conv(eqv):.4g}"
        lines.append(f"| {name} | {conv(init):.4g} | {eq_txt} | {fmt(gn)} | {fmt(bt)} "
                     f"| {conv(val):.4g} |")
    return lines


def coefficient_text(r: Ranked) -> str:
    """The main coefficient, each number with its own label: the refined value (when the
    candidate was refined) and the screening estimate with its bootstrap interval (the
    interval belongs to the screening estimate, not to the refined value)."""
    main = r.dominant_param()
    p = r.params.get(main)
    unit = f" {p.unit}" if p is not None and p.unit else ""
    if p is None:
        return main
    ci = (f" [{p.boot_ci_lo:.4g}, {p.boot_ci_hi:.4g}]" if p.boot_ci_lo is not None else "")
    screening = f"screening estimate {p.value:.4g}{ci}{unit}"
    refined = (r.refined_params or {}).get(main)
    if refined is None:
        return f"{main}: {screening}"
    return f"{main}: refined value {refined:.4g}{unit}; {screening}"


def proposal_section(p: Proposal | None) -> list[str]:
    """The report's lines on the proposed term (empty when none was fitted)."""
    if p is None:
        return []
    lines = ["", "## A term outside the library (proposed from the foot-force equation error)", ""]
    lines += [f"* axis {a.axis}: held-out equation error "
              f"{change_text(a.heldout_error_reduction_selected)} "
              f"(selection redone per fold {change_text(a.heldout_error_reduction)}), RMS "
              f"{a.rms_before:.2f} → {a.rms_after:.2f} N (explains {a.explained_rms:.1f} N; "
              f"needed: {MIN_EXPLAINED_FORCE[a.axis]:g} N, above what data without a missing "
              "force explain)"
              f"{'' if a.proposed else ' — nothing proposed'}" for a in p.axes]
    joint = joint_report_lines(p.joint_terms, p.joint_fits, p.joint_note)
    each = ", ".join(f"`{f}`" for f in p.files)
    file_line = ["", f"Effect files: {each} (one per proposed effect; all of them in "
                     f"`{p.file}`) — hypotheses, not added; pass back the one you believe "
                     "with `--effect-file FILE` to have it refitted and judged."] if p.file else []
    if not p.terms:
        return (lines + [f"* nothing proposed ({p.n_samples} sinking samples)"] + joint
                + (file_line if p.joint_terms else []))
    lines += ["", "| axis | feature | coefficient (foot) | per patch | selected in |",
              "|---|---|---|---|---|"]
    lines += [f"| {t.axis} | {t.feature}: {t.description} | {t.coefficient_foot:.4g} ± "
              f"{t.std_error:.2g} {t.unit} | {t.coefficient_patch:.4g} | "
              f"{100 * t.selection_frequency:.0f} % |" for t in p.terms]
    return lines + joint + file_line


def markdown(d: Diagnosis, figs: Sequence[Path]) -> str:
    """The one-page ``report.md``."""
    v = d.verdict
    eq = d.calibration.equation_error
    lines = [f"# Diagnosis of `{d.data}`", "",
             f"**Verdict ({v.status.replace('_', ' ')}):** {v.text}", ""]
    if d.best_candidate:
        lines += [f"**Best candidate:** {d.best_candidate}", ""]
    if d.warnings:
        lines += ["**Warnings:**", ""] + [f"* {w}" for w in d.warnings] + [""]
    lines += coverage_section(d.out_dir)       # measured / missing channels (coverage.py)
    lines += ["## Calibration (own parameters)", "",
              "| parameter | before | equation error | 95 % CI (Gauss–Newton) "
              "| 95 % CI (trial bootstrap) | after replay refit |",
              "|---|---|---|---|---|---|"]
    lines += _calibration_lines(d)
    fitted = eq.n_samples > 0 and math.isfinite(eq.rmse_before)
    lines += ["", (f"{eq.n_samples} sinking samples from {eq.n_stances} stances; "
                   f"force residual {eq.rmse_before:.2f} N → {eq.rmse_after:.2f} N. "
                   if fitted else "No equation-error fit: ") + (
                       eq.note or "no sinking samples with a measured foot force."), "",
              "## Candidate effects", "",
              "| rank | effect | kind | held-out error reduction | ΔAICc | inclusion | main coefficient | added |",
              "|---|---|---|---|---|---|---|---|"]
    for r in d.ranking:
        inc = r.inclusion_probability
        added = "**yes**" if r.added else ("reported, not added" if r.not_added_because else "no")
        lines.append(f"| {r.rank} | {r.effect} | {r.kind} | "
                     f"{100 * r.heldout_error_reduction:.1f} % | {r.delta_aicc:.0f} | "
                     f"{'–' if inc is None else f'{inc:.2f}'} | {coefficient_text(r)} | "
                     f"{added} |")
    if d.acceptance:
        lines += ["", "## Acceptance of the refined contenders", "",
                  "| effect | added | credited channels: replay RMSE before → after | "
                  "coefficients | why not added |", "|---|---|---|---|---|"]
        for a in d.acceptance:
            ch = ", ".join(f"{c} {x.before:.3g} → {x.after:.3g} {x.unit}"
                           + (f" (rise t = {x.rise_t:.1f})"
                              if x.rise_t is not None and x.after > x.before else "")
                           for c, x in a.credited_channels.items()) or "–"
            co = "; ".join(f"{k.text} ({k.status})" if k.status != "ok" else k.text
                           for k in a.coefficients) or "–"
            if a.torque is not None:
                lo, hi = a.torque.ci
                co += (f"; joint torques hold {100 * a.torque.held_share:+.0f} % of its "
                       f"{a.torque.rms_torque:.3g} N·m RMS [{100 * lo:+.0f}, {100 * hi:+.0f}] %")
            who = a.effect + (f" (given {', '.join(a.given)})" if a.given else "")
            added = "dropped" if a.dropped else ("yes" if a.accepted else "no")
            lines.append(f"| {who} | {added} | {ch} | {co} | "
                         f"{'; '.join(a.reasons) or '–'} |")
    lines += force_start_lines(d)
    if d.indistinguishable:
        lines += ["", "## Candidates the data cannot tell apart", ""]
        for g in d.indistinguishable:
            lines.append(f"* {' vs '.join(g.effects)} (correlation {g.correlation:.2f}): "
                         f"{g.experiment}")
    if d.not_twins:
        lines += ["", f"Not tested as terrain-strength (φ_s) twins: {', '.join(d.not_twins)} "
                  "— the joint torque equation error at the measured state shows a "
                  "discrepancy (the joint-axis proposal passed), which no φ_s can produce."]
    lines += proposal_section(d.proposal)       # a term outside the library (proposal.py)
    loc = d.localization
    lines += ["", "## Where the calibrated model fails", ""]
    lines += [f"* {s}" for s in loc.where] or ["* no channel × phase cell with |t| ≥ "
                                               f"{T_CELL:g}"]
    if v.added:
        lines += ["", "## After adding " + ", ".join(v.added), ""]
        lines += [f"* {s}" for s in loc.unexplained_where] or ["* no structure left"]
        if d.force_left:
            lines.append(f"* {force_leftover_sentence(d.force_left)}")
        lines += [f"* {lp.sentence()}" for lp in d.law_preferred]
        red = d.heldout_reduction_by_channel
        if red:
            lines += ["", "| channel | held-out RMS before | after | reduction |", "|---|---|---|---|"]
            for c, ch in red.items():
                lines.append(f"| {c} | {ch.before:.4g} {ch.unit} | {ch.after:.4g} | "
                             f"{100 * ch.reduction:.0f} % |")
    lines += ["", "## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs]
    lines += ["", "## Next step", "", f"`{d.recommended.validate_command}`", ""]
    return "\n".join(lines)


def force_start_lines(d: Diagnosis) -> list[str]:
    """The user's and proposed terrain forces fitted on the foot-force equation error with
    ζ (:mod:`.force_start`), and whether the replays started from there."""
    if not d.force_starts:
        return []
    zeta = d.calibration.equation_error.values.get("zeta", float("nan"))
    out = ["", "## The user's and proposed terms on the foot-force equation error", "",
           f"Fitted with ζ free on the sinking samples (the calibration's ζ = {zeta:.3g}); a "
           "term that meets the evidence rule is also refined by the replays from there "
           "(docs/validation.md §3.3, \"The force start\").", ""]
    units = {(r.effect, k): e.unit for r in d.ranking for k, e in r.params.items()}
    for s in d.force_starts:
        axis = "vertical" if s.axis == "z" else "forward"
        unit = units.get((s.effect, s.param), "")
        unit = f" {unit}" if unit and unit != "-" else ""
        verdict = ("refined from there" if s.passes else
                   "below the evidence rule: refined from the screening's estimate only")
        out.append(f"* {s.effect}: {s.param} = {s.value:.4g}{unit} with ζ = {s.zeta:.3g}; {axis} "
                   f"force error {s.rms_before:.2f} → {s.rms_after:.2f} N RMS (explains "
                   f"{s.explained:.1f} N), held-out "
                   f"{f'{-100 * s.heldout_reduction:+.0f}'.replace('-', '−')} % — "
                   f"{verdict}")
    return out


def write_outputs(d: Diagnosis, figs: Sequence[Path]) -> None:
    """``diagnosis.json`` and ``report.md`` in ``d.out_dir``."""
    out = d.out_dir
    (out / DIAGNOSIS_FILE).write_text(d.to_json(), encoding="utf-8")
    (out / REPORT_FILE).write_text(markdown(d, figs), encoding="utf-8")


__all__ = ["proposal_section", "figures", "tstat_figure", "ranking_figure", "profiles_figure",
           "markdown", "write_outputs", "coefficient_text", "force_start_lines", "FIGURE_DPI"]
