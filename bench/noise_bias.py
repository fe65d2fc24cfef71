"""Where a refined coefficient's error comes from: the sensor noise, group by group.

    python bench/noise_bias.py [--cases TAG …] [--out DIR] [--json PATH] [--workers 2]
                               [--states | --segments 1 2]

The out-of-library benchmark fits the user's stiction τ_s 12–43 % high and the torque
gain 12–23 % high, every seed the same way; the library's recovery study fits the Coulomb
friction and the depth-hardening exponent 3–16 % high. A bias of one sign is not the
scatter of the noise, so this study asks which sensor puts it there. Per case one plant
run (``synth``, no noise, the out-of-library design: 3 trials at 0.15 / 0.25 / 0.35 m/s
× 7 stances, :data:`ool_forms.SPEEDS`) is copied with noise (``noisy_copy``) in several
*variants* (:data:`VARIANTS`):

* ``none`` — no noise; ``all`` — the realistic model at level 1 (what the benchmarks
  diagnose);
* ``no_<group>`` — level 1 with one sensor group silent (its prefixes overridden with
  white noise of σ = 0): ``tau`` (torque), ``q`` (encoder angles *and* their rates, which
  are the differentiated encoder noise), ``dq`` (the rates only), ``grf``, ``base``,
  ``intrusion``.

Every copy of a case uses the same noise seed, so a variant differs from ``all`` only in
the silent group. Each copy is diagnosed with the true term alone as the candidate
(``user_<form>`` of ``bench/ool_forms.py``, or the library effect), and its refined main
coefficient is printed with its error against the truth.

A sensor's noise can reach the fit two ways: through the scored channels (the
measurement the replay is compared with) or through the replay's *inputs* (each stance
window starts from the estimated state and is driven by the measured torques). The
*input* variants (:data:`INPUT_VARIANTS`) tell them apart: the ``all`` copy is diagnosed
again with parts of every window's inputs taken from the noise-free copy — the trunk's
initial twist (``v0`` of the free flyer: leg odometry + gyro), the torques, or all of
the inputs (configuration, velocity, torques, contact state, surface) — while every
scored channel keeps its noise. The substitution is done in this process by wrapping
``diagnosis.problem.stance_windows`` (a study device, not an API). The diagnosis is the
submitted one; nothing here changes it.

``--segments 1 2`` replaces the variants: the noise-free and the level-1 copy, each
diagnosed with one replay per stance and with restarts mid-stance
(``replay_segments``, :mod:`granular_mpc.validation.restarts`); variants ``none.seg1``,
``none.seg2``, ``all.seg1``, ``all.seg2``, and per variant whether the term was added.

``--states`` then prints how well the landing leg's joint angles and the trunk's angular
velocity one sample before each touchdown (where its replay starts) are estimated,
against the noise-free copy's samples:
a one-sided quadratic or cubic fit to the 15 samples up to it, the raw sample, a centred
quadratic Savitzky–Golay smoother over 15 (which reads across the impact) — on the
noise-free copy (the estimator's own bias) and on the level-1 copy (:func:`landing_angle_errors`).

Figures (``name: value``): per case ``<tag>.<variant>.coef_err`` (relative to the true
value's distance from neutral, as the other studies), and ``cases``; with ``--states``
``landing_angle_rms.<estimator>.<copy>`` [rad] and ``trunk_rate_rms.<estimator>.<copy>``
[rad/s].
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the helpers below, when imported

from _report import emit_study  # noqa: E402
from ool_forms import FORM_BY_NAME, SPEEDS, register_forms  # noqa: E402

#: variant → noise of ``noisy_copy`` (level 1 with the named prefixes silent)
VARIANTS = {
    "none": 0.0,
    "all": 1.0,
    "no_tau": {"level": 1.0, "tau_": 0.0},
    "no_q": {"level": 1.0, "q_": 0.0, "dq_": 0.0},
    "no_dq": {"level": 1.0, "dq_": 0.0},
    "no_grf": {"level": 1.0, "grf_": 0.0},
    "no_base": {"level": 1.0, "base_": 0.0},
    "no_intrusion": {"level": 1.0, "intrusion_": 0.0},
}
#: input variant → the parts of each window's replay inputs taken from the noise-free copy
INPUT_VARIANTS = {
    "clean_twist": ("twist",),
    "clean_tau": ("tau",),
    "clean_twist_tau": ("twist", "tau"),
    "clean_inputs": ("q0", "v0", "tau", "contact"),
}
ALL_VARIANTS = (*VARIANTS, *INPUT_VARIANTS)
#: the default cases: ``<form>_m<i>_s<seed>`` (an out-of-library form at its i-th
#: magnitude) or ``<library effect string>@<seed>``; chosen as the largest one-signed
#: errors of the two studies (docs/validation.md §5.3.12)
DEFAULT_CASES = ("stiction_m0_s2", "stiction_m1_s2", "torque_gain_m0_s2",
                 "joint_friction:coulomb=0.1,viscous=0.02@2",
                 "depth_hardening:n=1.5@2")


def parse_case(tag: str) -> tuple[list[str], str, str, float, int]:
    """(plant effects, candidate, main parameter, true value, seed) of a case tag."""
    from granular_mpc.config import parse_effect_string
    from granular_mpc.effects import effect_info
    from granular_mpc.exceptions import GranularMpcError

    if "@" in tag:
        spec, seed = tag.rsplit("@", 1)
        try:
            seed = int(seed)
            parsed = parse_effect_string(spec)
            info = effect_info(parsed["name"])
        except (ValueError, GranularMpcError) as e:
            raise SystemExit(f"--cases: {tag!r}: {e}") from None
        if not parsed["params"]:
            raise SystemExit(f"--cases: {tag!r} names no parameter: write the true value, "
                             "e.g. cohesion:suction=3000@1")
        name = parsed["name"]
        params = info.resolve_params(parsed["params"])
        # the main parameter: the one furthest from neutral relative to its range
        main = max(parsed["params"], key=lambda p: abs(params[p] - info.neutral_params()[p])
                   / (info.params[p].upper - info.params[p].lower))
        return [spec], name, main, float(params[main]), seed
    try:
        form_name, rest = tag.rsplit("_m", 1)
        mag, seed = rest.split("_s")
        form = FORM_BY_NAME[form_name]
        value = form.magnitudes[int(mag)]
    except (ValueError, KeyError, IndexError):
        raise SystemExit(f"--cases: {tag!r} is neither <form>_m<i>_s<seed> (forms: "
                         f"{', '.join(FORM_BY_NAME)}) nor <library effect>@<seed>") from None
    return [f"{form.hidden}:{form.param}={value:g}"], form.user, form.param, value, int(seed)


def clean_inputs_of(clean_windows, parts):
    """A ``stance_windows`` wrapper: the windows of the data set diagnosed, with ``parts``
    of each one's inputs replaced by those of the same window of the noise-free copy."""
    from dataclasses import replace

    from granular_mpc.validation import prepare

    def windows(ds, biped, **kw):
        noisy = prepare.stance_windows(ds, biped, **kw)
        clean = clean_windows(biped, **kw)
        if len(noisy) != len(clean):
            raise RuntimeError(f"{len(noisy)} noisy windows against {len(clean)} clean ones")
        out = []
        for w, c in zip(noisy, clean):
            q0, v0, extra = w.q0.copy(), w.v0.copy(), {}
            if "twist" in parts:
                v0[:6] = c.v0[:6]
            if "q0" in parts:
                q0 = c.q0.copy()
            if "v0" in parts:
                v0 = c.v0.copy()
            if "tau" in parts:
                extra["tau"] = c.tau
            if "contact" in parts:
                extra.update(feet=c.feet, origin=c.origin, touchdown_W=c.touchdown_W)
            out.append(replace(w, q0=q0, v0=v0, **extra))
        return out
    return windows


def run_case(tag: str, root: Path, segments: tuple[int, ...] = ()) -> dict:
    """Synthesize once (kept in ``root``), then one noisy copy and one diagnosis per
    variant; the refined main coefficient of each. With ``segments`` instead: the
    ``none`` and ``all`` copies only, each diagnosed with every number of replay segments
    per stance (variants ``<copy>.seg<n>``)."""
    from granular_mpc.effects import effect_info
    from granular_mpc.validation.diagnose import diagnose
    from granular_mpc.validation.synth import noisy_copy, synthesize

    register_forms()
    effects, cand, param, true, seed = parse_case(tag)
    clean = root / "clean"
    if not (clean / "meta.yaml").is_file():
        synthesize("sand_walk", clean, speeds=SPEEDS, steps=7, seed=seed, effects=effects,
                   noise=0.0, format="parquet", overwrite=True, workers=1)
    neutral = effect_info(cand).neutral_params()[param]
    row = {"case": tag, "candidate": cand, "param": param, "true": true, "fits": {},
           "coef_err": {}}
    runs = ([(name, n) for name in ("none", "all") for n in segments] if segments
            else [(name, 1) for name in VARIANTS])
    for name, n in runs:
        data = root / name / "data"
        if not (data / "meta.yaml").is_file():
            noisy_copy(clean, data, VARIANTS[name], seed=seed, overwrite=True)
        label = f"{name}.seg{n}" if segments else name
        d = diagnose(data, root / name / f"diag_seg{n}", candidates=[cand], seed=seed,
                     n_boot=20, workers=1, figures=False, replay_segments=n)
        fit = next((c.value for a in d.acceptance if a.effect == cand
                    for c in a.coefficients if c.param == param), math.nan)
        row["fits"][label] = fit
        row["coef_err"][label] = (fit - true) / (true - neutral)
        row.setdefault("added", {})[label] = cand in d.added
    if segments:
        return row
    from unittest import mock

    from granular_mpc.validation import prepare
    from granular_mpc.validation.dataformat import load_dataset
    from granular_mpc.validation.diagnosis import problem

    clean_ds = load_dataset(root / "none" / "data")
    for name, parts in INPUT_VARIANTS.items():
        wrapper = clean_inputs_of(lambda biped, **kw: prepare.stance_windows(clean_ds, biped, **kw),
                                  parts)
        with mock.patch.object(problem, "stance_windows", wrapper):
            d = diagnose(root / "all" / "data", root / name / "diag", candidates=[cand],
                         seed=seed, n_boot=20, workers=1, figures=False)
        fit = next((c.value for a in d.acceptance if a.effect == cand
                    for c in a.coefficients if c.param == param), math.nan)
        row["fits"][name] = fit
        row["coef_err"][name] = (fit - true) / (true - neutral)
    return row


def _child(tag: str, out: Path, segments: tuple[int, ...] = ()) -> None:
    row = run_case(tag, out, segments)
    (out / "row.json").write_text(json.dumps(row, indent=1), encoding="utf-8")


#: landing-leg angle estimators of ``--states``: name → (kind, degree)
ANGLE_ESTIMATORS = {"quadratic_past": ("past", 2), "cubic_past": ("past", 3),
                    "raw": ("raw", 0), "centred_sg": ("centred", 2)}
#: samples of the one-sided fits and of the centred smoother (``smooth_window``)
ANGLE_WINDOW = 15
#: the trunk's angular velocity columns (gyro, trunk frame)
GYRO = ("base_wx", "base_wy", "base_wz")


def landing_angle_errors(case_dirs) -> dict[str, float]:
    """RMS error of each :data:`ANGLE_ESTIMATORS` entry for the landing leg's joint angles
    (``landing_angle_rms.*`` [rad]) and the trunk's angular velocity (``trunk_rate_rms.*``
    [rad/s]) at the sample before every touchdown, on the ``none`` and ``all`` copies of
    the cases in ``case_dirs``, against the ``none`` copy's samples."""
    import numpy as np
    from scipy.signal import savgol_filter

    from granular_mpc.robot import load_biped
    from granular_mpc.validation.dataformat import load_dataset
    from granular_mpc.validation.prepare import stance_windows

    errs: dict[str, list] = {}
    for d in case_dirs:
        truth = load_dataset(d / "none" / "data")
        biped = load_biped(truth.meta.robot, with_visuals=False)
        windows = stance_windows(truth, biped)
        dt = 1.0 / truth.meta.sample_rate_hz
        for copy in ("none", "all"):
            ds = truth if copy == "none" else load_dataset(d / copy / "data")
            centred: dict = {}            # (trial, columns) → the centred smoother, once
            for w in windows:
                k = w.row_start - 1
                cols = [f"q_{j}" for j in ds.joint_names if j.startswith(w.side + "_")]
                q = ds.trials[w.trial][cols].to_numpy(float)
                q_true = truth.trials[w.trial][cols].to_numpy(float)[k]
                rows = np.arange(k - ANGLE_WINDOW + 1, k + 1)
                gyro = ds.trials[w.trial][list(GYRO)].to_numpy(float)
                gyro_true = truth.trials[w.trial][list(GYRO)].to_numpy(float)[k]
                for what, y, y_true, ycols in (("landing_angle", q, q_true, tuple(cols)),
                                               ("trunk_rate", gyro, gyro_true, GYRO)):
                    for name, (kind, deg) in ANGLE_ESTIMATORS.items():
                        if kind == "past":
                            est = np.polyfit((rows - k) * dt, y[rows], deg)[-1]
                        elif kind == "raw":
                            est = y[k]
                        else:
                            key = (w.trial, ycols, deg)
                            if key not in centred:
                                centred[key] = savgol_filter(y, ANGLE_WINDOW, deg, axis=0)
                            est = centred[key][k]
                        errs.setdefault(f"{what}_rms.{name}.{copy}", []).append(est - y_true)
    return {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errs.items()}


def table(rows: list[dict]) -> str:
    """Markdown: one row per case, the coefficient error per variant."""
    cols = list(rows[0]["coef_err"]) if rows else list(ALL_VARIANTS)
    head = "| case | truth | " + " | ".join(cols) + " |"
    lines = [head, "|" + "---|" * (len(cols) + 2)]
    for r in rows:
        errs = " | ".join(f"{100 * r['coef_err'][v]:+.0f} %" if math.isfinite(r["coef_err"][v])
                          else "-" for v in cols)
        lines.append(f"| {r['case']} | {r['param']} = {r['true']:g} | {errs} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES))
    ap.add_argument("--out", type=Path, default=None, help="keep data and diagnoses here")
    ap.add_argument("--workers", type=int, default=1, help="cases at a time")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--states", action="store_true",
                    help="also the landing leg's angle estimates against the noise-free copy")
    ap.add_argument("--segments", type=int, nargs="+", default=[],
                    help="instead of the sensor variants: the noise-free and level-1 copies "
                         "diagnosed with each number of replay segments per stance")
    ap.add_argument("--case", help=argparse.SUPPRESS)      # internal: run one case
    args = ap.parse_args()
    if any(n < 1 for n in args.segments):
        ap.error(f"--segments: {args.segments} — each at least 1 (1: whole stances)")
    if args.case:
        _child(args.case, args.out, tuple(args.segments))
        return
    for tag in args.cases:
        parse_case(tag)                                     # bad tags fail before any run
    tmp = tempfile.TemporaryDirectory() if args.out is None else None
    root = Path(tmp.name) if tmp else args.out
    dirs = {tag: root / tag.replace(":", "_").replace("=", "").replace(",", "_")
            for tag in args.cases}

    def one(tag: str) -> dict:
        t0 = time.perf_counter()
        dirs[tag].mkdir(parents=True, exist_ok=True)
        with open(dirs[tag] / "log.txt", "w", encoding="utf-8") as log:
            subprocess.run([sys.executable, __file__, "--case", tag, "--out", str(dirs[tag]),
                            *(["--segments", *map(str, args.segments)] if args.segments
                              else [])],
                           stdout=log, stderr=subprocess.STDOUT, check=True)
        row = json.loads((dirs[tag] / "row.json").read_text(encoding="utf-8"))
        print(f"{tag}: " + ", ".join(f"{v} {100 * e:+.0f} %" for v, e in row["coef_err"].items())
              + f" ({time.perf_counter() - t0:.0f} s)", flush=True)
        return row

    with ThreadPoolExecutor(max(1, args.workers)) as pool:
        rows = list(pool.map(one, args.cases))
    print(table(rows))
    figures = {f"{r['case']}.{v}.coef_err": r["coef_err"][v] for r in rows
               for v in r["coef_err"]}
    figures["cases"] = len(rows)
    if args.states:
        figures.update(landing_angle_errors([dirs[t] for t in args.cases]))
    emit_study(figures, rows, args.json)
    if tmp:
        tmp.cleanup()


if __name__ == "__main__":
    main()
