"""Out-of-library benchmark of ``diagnose``: effects nobody put in a library, found or not.

    python bench/out_of_library.py [--quick] [--forms NAME …] [--seeds 1 2 3] [--steps 7]
                                   [--speeds 0.15 0.25 0.35]
                                   [--mag-index 0 1] [--no-pairs] [--no-nulls]
                                   [--mismatches KEY=VALUE …] [--user-terms] [--measurement]
                                   [--replay-segments 1] [--workers 1] [--n-boot 60]
                                   [--out DIR [--reuse | --report-only]] [--json PATH]

Every hidden effect here is written with the public plugin API (``register_effect``,
``register_joint_effect``, ``register_sensor_effect``) exactly as a user's effect file
would be, and none of them is in the effects library (:data:`FORMS`: six terrain forces,
two joint torques, three sensor maps). Per case one plant run (``synth``, no noise: 3
trials at 0.15 / 0.25 / 0.35 m/s × ``--steps`` stances, the test suite's design; another
design with ``--speeds``, one trial per speed) is
turned into a data set with sensor noise level 1 (``noisy_copy``) and diagnosed two or
three times:

1. **library run**: the library's seven effects as candidates (what a new user gets);
2. **feedback run** (when the library run proposed anything): the library plus the
   proposed effects passed back with ``--effect-file``, one file per effect
   (``proposed_force.py``, ``proposed_joint.py``, ``proposed_torque_sensor.py``; only
   effects that met their evidence rule are written), and, with ``--user-terms``, the
   true form registered under ``user_<form>`` with a neutral default: the user who writes
   the right term from the localisation;
3. **proposal-alone run** (with ``--user-terms``, when anything was proposed): the library
   plus the proposed effects only — what a user who writes nothing gets (in the feedback
   run the user term, the same effect, takes the proposal's rank). Without
   ``--user-terms`` the feedback run is this run.

Cases: each form at two magnitudes × ``--seeds``; pairs (a library effect + a form at its
first magnitude, first seed); null sets without any effect but with a plant whose φ_s,
layer depth or contact stiffness is unlike the model file's (:data:`MISMATCHES`).
``--quick``: :data:`QUICK_FORMS` (9 forms) × the first magnitude × seed 1 + the first two
mismatches, no pairs.

Each case runs in its own process (``--workers`` at a time; the registries of two cases
never meet). Output: a progress line per case, the targets table of issue 11 and the
per-case table (case, truth, verdict, added / proposed, coefficients, the affected
channel's replay RMSE before → after); ``--json PATH`` writes figures and rows.

Each form case also replays the true model (``validate`` of the model file with the true
effects at their true values, :func:`truth_replay`): what the right term with the right
coefficient does to the affected channel. A case is *detectable* when that cuts the
affected channel's replay RMSE by ≥ 50 % — else
even the perfect answer cannot meet the −50 % target. With ``--reuse`` a noisy data set
already in ``--out`` is diagnosed again rather than re-synthesised (copy stored ones there).
With ``--user-terms`` a third table lists the user term per case (rank, added, coefficient
error, affected-channel reduction by the feedback run / by the truth, found by whom).

Figures (``name: value``): ool_wrong_answer_rate, ool_found_rate (proposal or user term
ranked first in the feedback run and the affected channel's replay RMSE −50 %),
ool_found_by_proposal_rate, ool_found_by_user_term_rate (the same split by who found it),
ool_found_by_proposal_alone_rate (the proposal-alone run: proposal ranked first, added,
affected error −50 %),
ool_detectable_rate, and ool_found_rate_detectable (and its split) over the detectable cases,
pair_both_found_rate (and pair_both_found_rate_detectable over the pairs whose form is detectable alone, :func:`ool_scoring.pair_form_detectable`), pair_rank1_rate, pair_coef_within_15pct_rate, null_added_rate,
added_worsening (added terms whose replay worsens a channel they are credited with),
cases, null_cases, pair_cases. Kept apart from ``bench/recovery.py`` (the library's own
recovery study). The forms and cases are in ``bench/ool_forms.py``, the scoring and
tables in ``bench/ool_scoring.py`` (re-exported here).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the helpers below, when imported

from ool_forms import (FORM_BY_NAME, FORMS, HIDDEN, KNEES, LIBRARY, MISMATCHES,  # noqa: E402
                       PAIRS, PROPOSED, PROPOSED_PREFIX, QUICK_FORMS, SPEEDS, USER, Case,
                       Form, build_cases, register_forms)
from ool_scoring import (affected_channel, case_table, figures,  # noqa: E402
                         progress_line, score, targets_table, truth_reduction_calibrated,
                         user_table)



# --- one case (in its own process) -----------------------------------------------------

def _channel_changes(d) -> dict:
    return {c: [ch.before, ch.after] for c, ch in d.replay_rmse_by_channel.items()}


def _worsened(d) -> list[str]:
    """Added terms whose replay worsens a channel they are credited with (the judgement
    that added them: a term rejected against one model may be added against a later one)."""
    out = []
    for a in d.acceptance:
        if a.accepted and a.effect in d.added and any(
                ch.after > ch.before for ch in a.credited_channels.values()):
            out.append(a.effect)
    return out


def _summary(d) -> dict:
    top = d.ranking[0] if d.ranking else None
    return {"status": d.verdict.status, "added": list(d.added),
            "rank1": top.effect if top else "", "rank1_added": bool(top and top.added),
            "is_answer": " is the answer" in d.best_candidate,
            "best_candidate": d.best_candidate,
            "fitted": {k: dict(v) for k, v in d.fitted_effects.items()},
            "replay": _channel_changes(d), "worsened": _worsened(d),
            "sigma": dict(d.design.sigma),
            "ranks": {r.effect: r.rank for r in d.ranking}}


def truth_replay(case: Case, noisy: Path, segments: int = 1) -> dict:
    """The true model replayed on the data: channel → [RMSE before, after] of the model
    file without and with the case's true effects at their true values. The plant of every
    form case *is* the model file plus those effects, so this is what the best possible
    term can do to each channel — the "detectable" test of :func:`ool_scoring.score`. It
    is not replayed with the library run's calibration: a calibration fitted without the
    effect absorbs part of it (a knee encoder offset of 0.05 rad: the truth on top of the
    calibration *raises* q_left_knee's replay RMSE 0.031 → 0.049 rad, on the model file it
    cuts it 0.043 → 0.035). Empty for null sets."""
    from granular_mpc.validation.replay import validate

    if not case.form:
        return {}
    v = validate(noisy, None, effects=case.effects(), params=None, n_boot=20, workers=1,
                 figures=False, seed=case.seed, replay_segments=segments)
    return {c: [ba["before"], ba["after"]] for c, ba in v.report["before_after"].items()}


def run_case(case: Case, root: Path, steps: int, n_boot: int, user_terms: bool,
             measurement: bool = False, reuse: bool = False,
             speeds: tuple[float, ...] = SPEEDS, segments: int = 1) -> dict:
    """Synthesize, noise (``reuse``: keep a noisy data set already in ``root``), diagnose
    with the library (and with ``measurement`` the measurement-model family), then with
    the proposal fed back; replay the truth at its true value (:func:`truth_replay`).
    ``segments``: replays per stance of every diagnosis and of the truth's replay."""
    from granular_mpc.effects.measurement import MEASUREMENT
    from granular_mpc.validation.diagnose import diagnose
    from granular_mpc.validation.diagnosis.proposal import proposed_effects
    from granular_mpc.validation.synth import noisy_copy, synthesize

    register_forms()
    library = LIBRARY + (list(MEASUREMENT) if measurement else [])
    t0 = time.perf_counter()
    clean, noisy = root / f"{case.tag}_clean", root / f"{case.tag}_noisy"
    if not (reuse and (noisy / "meta.yaml").is_file()):
        synthesize("sand_walk", clean, speeds=list(speeds), steps=steps, seed=case.seed,
                   effects=case.effects(), noise=0.0, format="parquet",
                   overrides=[case.mismatch] if case.mismatch else [], overwrite=True,
                   workers=1)
        noisy_copy(clean, noisy, 1.0, seed=case.seed, overwrite=True)
    row: dict = {"case": asdict(case), "design": design_of(list(speeds), steps, segments),
                 "synth_s": time.perf_counter() - t0}
    t0 = time.perf_counter()
    lib = diagnose(noisy, root / f"{case.tag}_lib", candidates=library, seed=case.seed,
                   n_boot=n_boot, workers=1, figures=False, replay_segments=segments)
    row["lib"] = _summary(lib)
    row["lib_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    row["truth_replay"] = truth_replay(case, noisy, segments)
    row["truth_s"] = time.perf_counter() - t0
    prop = lib.proposal
    row["proposal"] = ({"file": prop.file, "files": list(prop.files),
                        "pointed_to": prop.pointed_to,
                        "terms": {f"{t.axis}:{t.feature}": t.coefficient_patch
                                  for t in prop.terms},
                        # joint-axis terms (joint_proposal.py): "joint:<name>:<feature>"
                        "joint_terms": {f"joint:{t.joint}:{t.feature}": t.coefficient
                                        for t in prop.joint_terms}}
                       if prop is not None else None)
    # one file per proposed effect, each of which met its evidence rule (proposal.py):
    # every one is passed back, each registering the effect its file is named after
    files = [str(lib.out_dir / f) for f in prop.files] if prop is not None else []
    cands = library + [Path(f).stem for f in files]
    assert set(cands[len(library):]) <= set(proposed_effects(prop)), (files, prop)
    user = FORM_BY_NAME[case.form].user if user_terms and case.form else ""
    row["fb"] = row["fb_alone"] = None
    row["measurement"] = measurement
    if files or user:
        t0 = time.perf_counter()
        fb = diagnose(noisy, root / f"{case.tag}_fb", candidates=cands + ([user] if user else []),
                      seed=case.seed, n_boot=n_boot, workers=1, figures=False,
                      effect_files=files, replay_segments=segments)
        row["fb"] = _summary(fb)
        row["fb_s"] = time.perf_counter() - t0
    if files and user:
        # the proposal on its own, as a user who writes nothing would pass it back: the
        # user term beside it would take the rank of the same effect
        t0 = time.perf_counter()
        alone = diagnose(noisy, root / f"{case.tag}_fb_alone", candidates=cands,
                         seed=case.seed, n_boot=n_boot, workers=1, figures=False,
                         effect_files=files, replay_segments=segments)
        row["fb_alone"] = _summary(alone)
        row["fb_s"] += time.perf_counter() - t0
    elif files:
        row["fb_alone"] = row["fb"]         # the feedback run had no user term
    return row



def check_speeds(speeds: list[float], error) -> None:
    """Each speed against the scenario's own range of ``command.speed`` (the validation
    ``synthesize`` runs in every case), checked once before any case starts."""
    from granular_mpc.config import validate
    from granular_mpc.exceptions import ConfigError
    from granular_mpc.scenario import find_scenario, load_scenario

    command = load_scenario(find_scenario("sand_walk")).command
    for v in speeds:
        try:
            validate(type(command), {**command.model_dump(), "speed": v}, source="--speeds")
        except ConfigError as e:
            error(str(e))


def design_of(speeds: list[float], steps: int, segments: int = 1) -> dict:
    """A folder's design: speeds, stances per trial and (when not 1) replays per stance
    (folders written before ``--replay-segments`` existed hold the first two only)."""
    design = {"speeds": speeds, "steps": steps}
    if segments != 1:
        design["replay_segments"] = segments
    return design


def check_design(out: Path, speeds: list[float], steps: int, error, segments: int = 1) -> None:
    """One ``--out`` folder holds one design: its speeds, stances per trial and replays per
    stance are written to ``design.json`` on the first run, and a later run (``--reuse``,
    ``--report-only``) with another design stops with ``error`` instead of mixing the two."""
    mark = out / "design.json"
    design = design_of(speeds, steps, segments)
    if mark.is_file():
        old = json.loads(mark.read_text(encoding="utf-8"))
        if old != design:
            error(f"--out {out} holds cases of another design ({mark.name}: speeds "
                  f"{old.get('speeds')}, steps {old.get('steps')}, replay segments "
                  f"{old.get('replay_segments', 1)}; asked: speeds {speeds}, steps {steps}, "
                  f"replay segments {segments}): use another --out, or the same "
                  f"--speeds, --steps and --replay-segments")
        return
    mark.write_text(json.dumps(design), encoding="utf-8")


def _child(args) -> None:
    case = Case(**json.loads(args.case))
    row = run_case(case, args.out, args.steps, args.n_boot, args.user_terms, args.measurement,
                   args.reuse, tuple(args.speeds), args.replay_segments)
    (args.out / f"{case.tag}.json").write_text(json.dumps(row, indent=1, default=str),
                                               encoding="utf-8")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--forms", nargs="*", default=[f.name for f in FORMS],
                    choices=list(FORM_BY_NAME),
                    help="forms to run (default: every one of FORMS; the held-out "
                    "EXTRA_FORMS soft_bed, ratio_layer only when named)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--magnitudes", type=int, default=2, choices=(1, 2))
    ap.add_argument("--steps", type=int, default=7, help="stances per trial")
    ap.add_argument("--speeds", type=float, nargs="+", default=list(SPEEDS),
                    help="commanded speeds [m/s], one trial each")
    ap.add_argument("--n-boot", type=int, default=60)
    ap.add_argument("--no-pairs", action="store_true")
    ap.add_argument("--no-nulls", action="store_true")
    ap.add_argument("--mag-index", type=int, nargs="+", choices=(0, 1),
                    help="run only these magnitudes of each form (overrides --magnitudes)")
    ap.add_argument("--mismatches", nargs="*", default=list(MISMATCHES),
                    help="plant overrides of the null sets")
    ap.add_argument("--user-terms", action="store_true",
                    help="also pass the true form as a user term in the feedback run")
    ap.add_argument("--measurement", action="store_true",
                    help="add the measurement-model family to the candidates of both runs")
    ap.add_argument("--replay-segments", type=int, default=1,
                    help="replays per stance of every diagnosis (restarts mid-stance)")
    ap.add_argument("--workers", type=int, default=1, help="cases at a time")
    ap.add_argument("--out", type=Path, default=None, help="keep data and diagnoses here")
    ap.add_argument("--reuse", action="store_true",
                    help="with --out: reuse finished cases, and the noisy data sets there")
    ap.add_argument("--report-only", action="store_true",
                    help="with --out: only tabulate the cases already finished there")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--case", help=argparse.SUPPRESS)      # internal: run one case
    args = ap.parse_args()
    check_speeds(args.speeds, ap.error)
    if args.steps < 2:
        ap.error(f"--steps: {args.steps} — give at least 2 stances per trial")
    if args.replay_segments < 1:
        ap.error(f"--replay-segments: {args.replay_segments} — give 1 (whole stances) or more")
    if args.case:
        return _child(args)
    mismatches = () if args.no_nulls else tuple(args.mismatches)
    if args.quick:
        args.forms, args.seeds, args.magnitudes = list(QUICK_FORMS), [1], 1
        args.no_pairs, mismatches = True, MISMATCHES[:2]
    tmp = None
    if args.out is None:
        tmp = tempfile.TemporaryDirectory(prefix="out_of_library_")
        args.out = Path(tmp.name)
    args.out.mkdir(parents=True, exist_ok=True)
    check_design(args.out, list(args.speeds), args.steps, ap.error, args.replay_segments)
    cases = build_cases(args.forms, args.seeds, args.mag_index or args.magnitudes,
                        not args.no_pairs, mismatches)
    print(f"{len(cases)} cases in {args.out}", flush=True)

    def one(case: Case) -> dict | None:
        res = args.out / f"{case.tag}.json"
        if args.report_only and not res.is_file():
            return None
        if not ((args.reuse or args.report_only) and res.is_file()):
            cmd = [sys.executable, __file__, "--case", json.dumps(asdict(case)), "--out",
                   str(args.out), "--steps", str(args.steps), "--n-boot", str(args.n_boot),
                   "--speeds", *map(str, args.speeds),
                   "--replay-segments", str(args.replay_segments)]
            cmd += ["--user-terms"] if args.user_terms else []
            cmd += ["--measurement"] if args.measurement else []
            cmd += ["--reuse"] if args.reuse else []      # keep the noisy data sets there
            t0 = time.perf_counter()
            with open(args.out / f"{case.tag}.log", "w", encoding="utf-8") as log:
                proc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, env=os.environ)
            if proc.returncode != 0 or not res.is_file():
                print(f"{case.tag}: FAILED (rc {proc.returncode}; see {case.tag}.log) "
                      f"[{time.perf_counter() - t0:.0f} s]", flush=True)
                return None
        row = json.loads(res.read_text(encoding="utf-8"))
        print(progress_line(row), flush=True)
        return row

    with ThreadPoolExecutor(max_workers=max(1, args.workers)) as ex:
        rows = [r for r in ex.map(one, cases) if r is not None]
    print("\n## Targets (issue 11)\n\n" + targets_table(rows))
    print("\n## Cases\n\n" + case_table(rows) + "\n")
    if args.user_terms:
        print("## User terms\n\n" + user_table(rows) + "\n")
    figs = figures(rows)
    for k, v in figs.items():
        print(f"{k}: {v:.3g}" if isinstance(v, float) else f"{k}: {v}")
    if args.json:
        args.json.write_text(json.dumps({"figures": figs, "rows": rows,
                                         "scores": [score(r) for r in rows]}, indent=1,
                                        default=str), encoding="utf-8")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
