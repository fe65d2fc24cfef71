"""Scoring and tables of the out-of-library benchmark (``bench/out_of_library.py``): per
case, whether the truth was found and by whom (the proposal or the user's term), whether it
was detectable at all, and the targets / per-case / user-term tables."""

from __future__ import annotations

import math

from ool_forms import FORM_BY_NAME, PROPOSED, PROPOSED_PREFIX, Case

#: "found": the affected channel's replay RMSE falls by at least this share (issue 11)
FOUND_REDUCTION = 0.5
#: "detectable": the truth at its true value cuts the affected channel by at least this
DETECTABLE_REDUCTION = 0.5


def affected_channel(case: Case, row: dict) -> str:
    """The channel the truth moves: among the form's channels (names or prefixes), the one
    whose base-model replay RMSE is largest in units of its scatter (the base replay is
    the same in both runs; when neither run replayed, the truth's replay
    (``row["truth_replay"]``, same calibration) gives the base RMSE; '' without any)."""
    if not case.form:
        return ""
    form = FORM_BY_NAME[case.form]
    runs = [r for r in (row.get("fb"), row.get("lib")) if r and r["replay"]]
    if runs:
        rep, sigma = runs[0]["replay"], runs[0]["sigma"]
    elif row.get("truth_replay"):
        rep, sigma = row["truth_replay"], row["lib"]["sigma"]
    else:
        return ""
    cands = [c for c in rep if any(c == p or (p.endswith("_") and c.startswith(p))
                                   for p in form.channels)]
    if not cands:
        return ""
    return max(cands, key=lambda c: rep[c][0] / sigma.get(c, 1.0))


def _reduction(run: dict | None, ch: str) -> float:
    if not run or not ch or ch not in run["replay"]:
        return 0.0 if run and not run["added"] else math.nan
    b, a = run["replay"][ch]
    return 1.0 - a / b if b > 0 else math.nan


def truth_reduction(row: dict, ch: str) -> float:
    """The affected channel's replay RMSE reduction by the truth at its true value (nan
    when the truth was not replayed)."""
    rep = row.get("truth_replay") or {}
    if ch not in rep or not rep[ch][0] > 0:
        return math.nan
    return 1.0 - rep[ch][1] / rep[ch][0]


def truth_reduction_calibrated(row: dict, ch: str) -> float:
    """The truth's replay RMSE of the affected channel against the *calibrated* model's
    (the "before" of the feedback run, else of the library run): the baseline ``found``
    is measured against, so this is what the right term can reach on that scale (a
    calibration fitted without the effect can absorb part of it: a hard layer's truth
    cuts intrusion_z by 81 % against the model file, 45 % against the calibrated model).
    nan when neither run replayed the channel or the truth was not replayed."""
    rep = row.get("truth_replay") or {}
    if ch not in rep:
        return math.nan
    for run in (row.get("fb"), row["lib"]):
        if run and ch in run["replay"] and run["replay"][ch][0] > 0:
            return 1.0 - rep[ch][1] / run["replay"][ch][0]
    return math.nan


def reduction_against_model_file(row: dict, run: dict | None, ch: str) -> float:
    """The affected channel's replay RMSE with ``run``'s additions against the *model
    file*'s (the truth's replay's "before": the user's model as it came, before any
    calibration): the other reading of the issue's "affected error −50 %" (the
    calibrated baseline of :func:`_reduction` is the strict one; docs/validation.md §5.3.17
    shows both). nan without the truth's replay of the channel or a run that replayed it."""
    base = (row.get("truth_replay") or {}).get(ch)
    if not base or not base[0] > 0 or not run or ch not in run["replay"]:
        return math.nan
    return 1.0 - run["replay"][ch][1] / base[0]


def user_in(run: dict, form) -> bool:
    """Whether the diagnosis ``run`` had the form's user term among its candidates."""
    return bool(form) and form.user in run.get("ranks", {})


def score(row: dict) -> dict:
    """Per-case judgements for the targets table.

    ``found``: the proposal or the user term ranked first and added in the feedback run,
    and the affected channel's replay RMSE −50 %; ``found_by``: ``proposal``, ``user`` or
    ''. ``detectable``: the truth itself, replayed at its true value, cuts the affected
    channel's RMSE by ≥ :data:`DETECTABLE_REDUCTION` — a case where even the right term
    with the right coefficient cannot reach −50 % is not one the target can be met on
    (nan when the truth was not replayed). ``detectable_calibrated``: the same against the
    calibrated baseline ``found`` is measured on (:func:`truth_reduction_calibrated`;
    the model-file test where neither run replayed the channel).
    """
    case = Case(**row["case"])
    lib, fb = row["lib"], row.get("fb")
    ch = affected_channel(case, row)
    out = {"channel": ch, "lib_red": _reduction(lib, ch), "fb_red": _reduction(fb, ch)}
    out["truth_red"] = truth_reduction(row, ch)
    out["detectable"] = (out["truth_red"] >= DETECTABLE_REDUCTION
                         if not math.isnan(out["truth_red"]) else math.nan)
    out["truth_red_cal"] = truth_reduction_calibrated(row, ch)
    # where no run replayed the channel (nothing added in either), the model-file test
    # stands in: a case is never dropped from the count for lack of a baseline
    out["detectable_calibrated"] = (out["truth_red_cal"] >= DETECTABLE_REDUCTION
                                    if not math.isnan(out["truth_red_cal"])
                                    else out["detectable"])
    form = FORM_BY_NAME.get(case.form)
    found_name = ""
    if fb and fb["rank1_added"] and (fb["rank1"].startswith(PROPOSED_PREFIX)
                                     or fb["rank1"] == (form.user if form else "")):
        found_name = fb["rank1"]
    out["found"] = bool(found_name) and (out["fb_red"] or 0.0) >= FOUND_REDUCTION
    out["found_term"] = found_name
    out["fb_red_file"] = reduction_against_model_file(row, fb, ch)
    out["found_model_file"] = bool(found_name) and (out["fb_red_file"] or 0.0) >= FOUND_REDUCTION
    out["found_by"] = ("" if not out["found"] else
                       "proposal" if found_name.startswith(PROPOSED_PREFIX) else "user")
    out["found_proposal"] = out["found_by"] == "proposal"
    out["found_user"] = out["found_by"] == "user"
    # the proposal-alone run (out_of_library.py); rows of older runs have none: their
    # feedback run stands in when it had no user term in it, else it is unknown (nan)
    if "fb_alone" in row or not (fb and user_in(fb, form)):
        alone = row["fb_alone"] if "fb_alone" in row else fb
        out["found_proposal_alone"] = bool(
            alone and alone["rank1_added"] and alone["rank1"].startswith(PROPOSED_PREFIX)
            and (_reduction(alone, ch) or 0.0) >= FOUND_REDUCTION)
    else:
        out["found_proposal_alone"] = math.nan
    user = form.user if form else ""
    out["user_rank"] = (fb or {}).get("ranks", {}).get(user) if user else None
    out["user_added"] = bool(fb and user in fb["added"])
    right = form.family if form and row.get("measurement") else ""
    out["family_found"] = bool(right) and lib["rank1"] == right and lib["rank1_added"]
    out["wrong_answer"] = bool(lib["added"]) and lib["is_answer"] and lib["rank1"] != right
    # the coefficient: the user term's, or the proposal's feature that is the law
    coef = math.nan
    if form and fb:
        if form.user in fb["fitted"]:
            coef = (fb["fitted"][form.user][form.param] - case.magnitude) / case.magnitude
        elif form.proposal_feature and PROPOSED in fb["fitted"]:
            key = form.proposal_feature.replace(":", "_")
            v = fb["fitted"][PROPOSED].get(key)
            if v is not None:
                coef = (v - form.sign * case.magnitude) / abs(case.magnitude)
    out["coef_err"] = coef
    if case.partner:
        from granular_mpc.config import parse_effect_string
        from granular_mpc.effects import effect_info

        spec = parse_effect_string(case.partner)
        name = spec["name"]
        info = effect_info(name)
        true = info.resolve_params(spec["params"])[case.partner_param]
        # the error of the magnitude, as the recovery study's coef_err: relative to the
        # distance from the neutral value (depth_hardening n: of the excess exponent n − 1)
        scale = true - info.neutral_params()[case.partner_param]
        # the final diagnosis: the feedback run (the user's term or the proposal passed
        # back), else the library run. The partner's coefficient is read there: in the
        # library run it also absorbs the missing form (cohesion + vdamp s1: suction
        # 4990 Pa in the library run, 1995 Pa with user_vdamp beside it, for 2000)
        final = fb or lib
        fit = final["fitted"].get(name, {}).get(case.partner_param)
        out["partner_rank1"] = lib["rank1"] == name and lib["rank1_added"]
        out["partner_coef_err"] = (fit - true) / scale if fit is not None else math.nan
        # both found: the final diagnosis adds the library partner and the form's term
        # (the user term or a proposal); no rank is asked of either (one of the two is
        # second whatever happens)
        term = any(a == user or a.startswith(PROPOSED_PREFIX) for a in final["added"])
        out["both_found"] = name in final["added"] and term
    out["null_added"] = bool(lib["added"]) if case.mismatch else False
    out["worsened"] = len(lib["worsened"]) + (len(fb["worsened"]) if fb else 0)
    return out


def pair_form_detectable(rows: list[dict]) -> dict[str, bool]:
    """Pair tag → whether its form is detectable *alone*: the single case of the same form,
    magnitude and seed (``score(...)["detectable"]``). A pair's own truth replay cannot
    tell: its affected channel is also moved by the library partner (joint friction cuts
    q_left_knee by 85 % whatever the encoder offset does). Pairs without that single case
    in ``rows`` are left out."""
    single = {(c.form, c.magnitude, c.seed): score(r)["detectable"]
              for r in rows for c in [Case(**r["case"])] if c.group == "ool"}
    out = {}
    for r in rows:
        c = Case(**r["case"])
        d = single.get((c.form, c.magnitude, c.seed)) if c.group == "pair" else None
        if isinstance(d, bool):
            out[c.tag] = d
    return out


def figures(rows: list[dict]) -> dict:
    sc = [(Case(**r["case"]), score(r)) for r in rows]
    ool = [s for c, s in sc if c.group in ("ool", "pair")]
    pairs = [s for c, s in sc if c.group == "pair"]
    form_det = pair_form_detectable(rows)
    pairs_det = [s for c, s in sc if c.group == "pair" and form_det.get(c.tag) is True]
    nulls = [s for c, s in sc if c.group == "null"]
    single = [s for c, s in sc if c.group == "ool"]
    detectable = [s for s in single if s["detectable"] is True]

    def rate(xs, key):
        vals = [x for x in xs if isinstance(x.get(key), bool) or not math.isnan(x.get(key, math.nan))]
        return sum(bool(x[key]) for x in vals) / len(vals) if vals else math.nan

    return {
        "ool_wrong_answer_rate": rate([s for c, s in sc if c.group == "ool"], "wrong_answer"),
        "ool_found_rate": rate(single, "found"),
        "ool_found_rate_model_file": rate(single, "found_model_file"),
        "ool_found_by_proposal_rate": rate(single, "found_proposal"),
        "ool_found_by_user_term_rate": rate(single, "found_user"),
        "ool_found_by_proposal_alone_rate": rate(single, "found_proposal_alone"),
        "ool_found_by_proposal_alone_rate_detectable": rate(detectable, "found_proposal_alone"),
        "ool_detectable_rate": rate(single, "detectable"),
        "ool_found_rate_detectable": rate(detectable, "found"),
        "ool_detectable_calibrated_rate": rate(single, "detectable_calibrated"),
        "ool_found_rate_detectable_calibrated": rate(
            [s for s in single if s["detectable_calibrated"] is True], "found"),
        "ool_found_by_proposal_rate_detectable": rate(detectable, "found_proposal"),
        "ool_found_by_user_term_rate_detectable": rate(detectable, "found_user"),
        "pair_both_found_rate": rate(pairs, "both_found"),
        "pair_both_found_rate_detectable": rate(pairs_det, "both_found"),
        "pair_rank1_rate": rate(pairs, "partner_rank1"),
        "pair_coef_within_15pct_rate": (sum(abs(p["partner_coef_err"]) <= 0.15 for p in pairs)
                                        / len(pairs) if pairs else math.nan),
        "null_added_rate": rate(nulls, "null_added"),
        "added_worsening": sum(s["worsened"] for _, s in sc),
        "cases": len(ool) - len(pairs), "pair_cases": len(pairs), "null_cases": len(nulls),
    }


def _pct(x: float) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:+.0f} %"


def progress_line(row: dict) -> str:
    """One finished case in a line: tag, each run's verdict and additions, the affected
    channel's replay RMSE change by the library / feedback run, and the seconds taken."""
    s, lib, fb = score(row), row["lib"], row.get("fb")
    tag = Case(**row["case"]).tag
    secs = row.get("synth_s", 0) + row.get("lib_s", 0) + row.get("fb_s", 0)
    return (f"{tag:34s} lib {lib['status']}: {','.join(lib['added']) or '-'}"
            f"{' (answer)' if lib['is_answer'] and lib['added'] else ''} | fb "
            f"{'-' if not fb else fb['status'] + ': ' + (','.join(fb['added']) or '-')} | "
            f"{s['channel'] or '-'} {_pct(s['lib_red'])} / {_pct(s['fb_red'])} [{secs:.0f} s]")


def _frac(rows: list[dict], group: str, key: str, where: str = "") -> str:
    """``key`` true / counted over the ``group`` cases (with ``where``: only those whose
    score has ``where`` True); nan values are not counted."""
    sc = [score(r) for r in rows if Case(**r["case"]).group == group]
    if where:
        sc = [s for s in sc if s.get(where) is True]
    vals = [s[key] for s in sc if key in s and not (isinstance(s[key], float) and math.isnan(s[key]))]
    return f"{sum(bool(v) for v in vals)}/{len(vals)}" if vals else "n/a"


def targets_table(rows: list[dict]) -> str:
    """The targets table of issue 11, from this benchmark's cases."""
    pairs = [score(r) for r in rows if Case(**r["case"]).group == "pair"]
    within = sum(abs(p["partner_coef_err"]) <= 0.15 for p in pairs)
    worsened = sum(score(r)["worsened"] for r in rows)
    form_det = pair_form_detectable(rows)
    det_rows = [r for r in rows if form_det.get(Case(**r["case"]).tag) is True]
    pairs_det = (f"{sum(score(r)['both_found'] for r in det_rows)}/{len(det_rows)}"
                 if det_rows else "n/a")
    lines = ["| figure | this run | target |", "|---|---|---|",
             f"| library effect (pair member) ranked first | {_frac(rows, 'pair', 'partner_rank1')} | ≥ 90 % |",
             f"| main coefficient within 15 % (pair member) | {within}/{len(pairs)} | ≥ 85 % |"
             if pairs else "| main coefficient within 15 % (pair member) | n/a | ≥ 85 % |",
             f"| both effects of a pair found | {_frac(rows, 'pair', 'both_found')} | ≥ 80 % |",
             f"| … among the pairs whose form is detectable alone (its single case, same seed) | {pairs_det} | ≥ 80 % |",
             f"| out-of-library: a wrong term presented as the answer | {_frac(rows, 'ool', 'wrong_answer')} | ≤ 10 % |",
             f"| out-of-library: proposal (or user term) ranked first, affected error −50 % | {_frac(rows, 'ool', 'found')} | ≥ 70 % |",
             f"| … the same with the affected error measured against the model file (the user's model before the workbench; the baseline of 'detectable') | {_frac(rows, 'ool', 'found_model_file')} | ≥ 70 % |",
             f"| … found by the proposal / by the user term | {_frac(rows, 'ool', 'found_proposal')} / {_frac(rows, 'ool', 'found_user')} | |",
             f"| … found by the proposal alone (a feedback run without the user term; all / detectable) | {_frac(rows, 'ool', 'found_proposal_alone')} / {_frac(rows, 'ool', 'found_proposal_alone', 'detectable')} | |",
             f"| … detectable cases (the true model: affected error −50 %) | {_frac(rows, 'ool', 'detectable')} | |",
             f"| … found among the detectable (proposal / user term) | {_frac(rows, 'ool', 'found', 'detectable')} ({_frac(rows, 'ool', 'found_proposal', 'detectable')} / {_frac(rows, 'ool', 'found_user', 'detectable')}) | ≥ 70 % |",
             f"| … detectable against the calibrated model (the baseline of 'found') | {_frac(rows, 'ool', 'detectable_calibrated')} | |",
             f"| … found among those | {_frac(rows, 'ool', 'found', 'detectable_calibrated')} | ≥ 70 % |",
             f"| null sets: a term added | {_frac(rows, 'null', 'null_added')} | 0 % |",
             f"| added terms whose replay worsens their channel | {worsened} | 0 |"]
    return "\n".join(lines)


def _coefs(fitted: dict, law: str = "") -> str:
    """Fitted parameters; a proposal's only as its term count and the law's term."""
    out = []
    for n, p in fitted.items():
        if n == PROPOSED:
            key = law.replace(":", "_")
            out.append(f"{n} ({len(p)} terms" + (f"; {key}={p[key]:.3g}" if key in p else "")
                       + ")")
        else:
            out.append(f"{n}: " + ", ".join(f"{k}={v:.3g}" for k, v in p.items()))
    return "; ".join(out) or "-"


def _proposed(prop: dict | None) -> str:
    """The proposal's terms by axis (feature names only)."""
    if not prop or not prop["file"]:
        return "-"
    axes: dict[str, list[str]] = {}
    for k in list(prop["terms"]) + list(prop.get("joint_terms", {})):
        ax, feat = k.split(":", 1)
        axes.setdefault(ax, []).append(feat)
    return "; ".join(f"{ax}: " + " ".join(f) for ax, f in axes.items())


def case_table(rows: list[dict]) -> str:
    """One line per case: truth, verdicts, added / proposed, coefficients, error."""
    lines = ["| case | truth | library run: verdict, added (answer?) | proposed | feedback run: "
             "verdict, added | coefficients (feedback, else library) | affected channel: "
             "RMSE before → after (lib / fb) |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        case, s = Case(**r["case"]), score(r)
        lib, fb, prop = r["lib"], r.get("fb"), r.get("proposal")
        added = ",".join(lib["added"]) or "-"
        ans = " (answer)" if lib["is_answer"] and lib["added"] else ""
        proposed = _proposed(prop)
        fbt = "-" if not fb else f"{fb['status']}, {','.join(fb['added']) or '-'}"
        form = FORM_BY_NAME.get(case.form)
        coefs = _coefs((fb or lib)["fitted"], form.proposal_feature if form else "")
        if not math.isnan(s["coef_err"]):
            coefs += f" [law coef err {_pct(s['coef_err'])}]"
        ch = s["channel"]
        err = "-"
        if ch:
            # the channel may be named by the truth's replay alone (neither run replayed it)
            rep = next(x for x in ((fb or lib)["replay"], lib["replay"],
                                   r.get("truth_replay") or {}) if ch in x)
            b = rep[ch][0]
            a_lib = lib["replay"][ch][1] if ch in lib["replay"] else b
            a_fb = fb["replay"][ch][1] if fb and ch in fb["replay"] else b
            err = f"{ch}: {b:.4g} → {a_lib:.4g} / {a_fb:.4g}"
        lines.append(f"| {case.tag} | {case.truth} | {lib['status']}, {added}{ans} | {proposed} "
                     f"| {fbt} | {coefs} | {err} |")
    return "\n".join(lines)


def user_table(rows: list[dict]) -> str:
    """One line per case with a user term: its rank and whether it was added in the
    feedback run, its coefficient error, the affected channel's replay RMSE reduction with
    the feedback run's additions and with the truth at its true value (the best possible)."""
    lines = ["| case | truth | user term: rank, added | coefficient error | affected channel: "
             "reduction (feedback run / truth) | found by |", "|---|---|---|---|---|---|"]
    for r in rows:
        case, s = Case(**r["case"]), score(r)
        if case.group != "ool":
            continue
        rank = "-" if s["user_rank"] is None else str(s["user_rank"])
        lines.append(f"| {case.tag} | {case.truth} | {rank}, {'yes' if s['user_added'] else 'no'} "
                     f"| {_pct(s['coef_err'])} | {s['channel'] or '-'}: {_pct(s['fb_red'])} / "
                     f"{_pct(s['truth_red'])} | {s['found_by'] or '-'} |")
    return "\n".join(lines)
