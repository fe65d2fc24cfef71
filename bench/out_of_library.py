"""Out-of-library benchmark of ``diagnose``: effects nobody put in a library, found or not.

    python bench/out_of_library.py [--quick] [--forms NAME …] [--seeds 1 2 3] [--steps 7]
                                   [--mag-index 0 1] [--no-pairs] [--no-nulls]
                                   [--mismatches KEY=VALUE …] [--user-terms] [--measurement]
                                   [--workers 1] [--n-boot 60]
                                   [--out DIR [--reuse | --report-only]] [--json PATH]

Every hidden effect here is written with the public plugin API (``register_effect``,
``register_joint_effect``, ``register_sensor_effect``) exactly as a user's effect file
would be, and none of them is in the effects library (:data:`FORMS`: five terrain forces,
two joint torques, three sensor maps). Per case one plant run (``synth``, no noise: 3
trials at 0.15 / 0.25 / 0.35 m/s × ``--steps`` stances, the test suite's design) is
turned into a data set with sensor noise level 1 (``noisy_copy``) and diagnosed twice:

1. **library run**: the library's seven effects as candidates (what a new user gets);
2. **feedback run** (when the library run proposed anything): the library plus the
   proposed effects passed back with ``--effect-file``, one file per effect
   (``proposed_force.py``, ``proposed_joint.py``, ``proposed_torque_sensor.py``; only
   effects that met their evidence rule are written), and, with ``--user-terms``, the
   true form registered under ``user_<form>`` with a neutral default: the user who writes
   the right term from the localisation.

Cases: each form at two magnitudes × ``--seeds``; pairs (a library effect + a form at its
first magnitude, first seed); null sets without any effect but with a plant whose φ_s,
layer depth or contact stiffness is unlike the model file's (:data:`MISMATCHES`).
``--quick``: :data:`QUICK_FORMS` (8 forms) × the first magnitude × seed 1 + the first two
mismatches, no pairs.

Each case runs in its own process (``--workers`` at a time; the registries of two cases
never meet). Output: a progress line per case, the targets table of issue 11 and the
per-case table (case, truth, verdict, added / proposed, coefficients, the affected
channel's replay RMSE before → after); ``--json PATH`` writes figures and rows.

Figures (``name: value``): ool_wrong_answer_rate, ool_found_rate (proposal or user term
ranked first in the feedback run and the affected channel's replay RMSE −50 %),
pair_both_found_rate, pair_rank1_rate, pair_coef_within_15pct_rate, null_added_rate,
added_worsening (added terms whose replay worsens a channel they are credited with),
cases, null_cases, pair_cases. Kept apart from ``bench/recovery.py`` (the library's own
recovery study).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from granular_mpc.effects import (Param, register_effect, register_joint_effect,
                                  register_sensor_effect, registered_names)

LIBRARY = ["inertial_drag", "cohesion", "depth_hardening", "elastic_unloading",
           "joint_friction", "force_sensor_bias", "terrain_slope"]
SPEEDS = (0.15, 0.25, 0.35)
HIDDEN, USER = "ool_", "user_"
PROPOSED = "proposed_force"
#: every effect a proposal file registers (force, joint, torque sensor) starts so
PROPOSED_PREFIX = "proposed_"


def _tanh(o, x):
    """tanh written with ``o.exp`` (the math namespace has no tanh); |x| clipped."""
    x = o.fmin(o.fmax(x, -30.0), 30.0)
    return 1.0 - 2.0 / (o.exp(2.0 * x) + 1.0)


def _v_h(s):
    """Forward sole velocity along the heading [m/s]."""
    return s.v_c[0] * s.heading[0] + s.v_c[1] * s.heading[1]


# --- the laws: terrain forces fn(o, s, k) -> (fx, fy, fz) [N] per patch, world frame -----

def vertical_damping(o, s, b):
    """Linear vertical damping of the sand: F_z = −b·v_z while in contact."""
    return (0.0, 0.0, -b * s.v_c[2] * s.in_contact)


def shear_drag_sq(o, s, c):
    """Velocity-squared shear drag on the sole's horizontal motion: F_xy = −c·|v_xy|·v_xy."""
    speed = o.sqrt(s.v_c[0] ** 2 + s.v_c[1] ** 2 + 1e-12)
    return (-c * speed * s.v_c[0] * s.in_contact, -c * speed * s.v_c[1] * s.in_contact, 0.0)


def hard_layer(o, s, k, d0=0.02):
    """A harder layer below d0 = 20 mm: F_z = k·max(depth − d0, 0)."""
    return (0.0, 0.0, k * o.fmax(s.depth - d0, 0.0) * s.in_contact)


def lateral_restoring(o, s, k):
    """A lateral spring pulling the sole back to its touchdown track: F_y = −k·y_s."""
    return (0.0, -k * s.intrusion[1] * s.in_contact, 0.0)


def sole_coulomb(o, s, f0, v0=0.02):
    """Coulomb-like friction offset of the sole: −f0·tanh(v_h / 2 cm/s) along the heading."""
    f = -f0 * _tanh(o, _v_h(s) / v0) * s.in_contact
    return (f * s.heading[0], f * s.heading[1], 0.0)


# --- joint torques fn(q_a, dq_a, k) -> tau_a [N·m], actuator order ----------------------

def stiction(q_a, dq_a, tau_s):
    """Stribeck stiction in every joint: −τ_s·tanh(q̇/0.05)·exp(−(q̇/0.5)²) (low speed only)."""
    return -tau_s * np.tanh(dq_a / 0.05) * np.exp(-(dq_a / 0.5) ** 2)


#: the knees in actuator order (left_hip_abd, left_hip_pitch, left_knee, right_…)
KNEES = (2, 5)


def knee_spring(q_a, dq_a, k, q0=1.4):
    """A parallel spring in both knees: τ = −k·(q − 1.4 rad)."""
    tau = np.zeros_like(dq_a)
    for i in KNEES:
        tau[i] = -k * (q_a[i] - q0)
    return tau


# --- sensor maps fn(cols, k, ctx) -> {column: measured} ---------------------------------

def torque_gain(cols, g, ctx):
    """Torque sensing gain error: every tau_* reads (1 + g)·τ."""
    return {c: (1.0 + g) * np.asarray(v, dtype=float) for c, v in cols.items()
            if c.startswith("tau_")}


def encoder_offset(cols, delta, ctx):
    """Encoder zero offset of the left knee: q_left_knee reads q + δ."""
    return {"q_left_knee": np.asarray(cols["q_left_knee"], dtype=float) + delta}


def grf_bias_left(cols, b, ctx):
    """Vertical force-sensor bias of the left foot only: grf_z + b during left stances."""
    left = (np.asarray(ctx.stance).astype(str) == "left").astype(float)
    return {"grf_z": np.asarray(cols["grf_z"], dtype=float) + b * left}


@dataclass(frozen=True)
class Form:
    """One out-of-library effect form.

    Attributes:
        name: short name (hidden effect ``ool_<name>``, user term ``user_<name>``).
        kind: ``terrain_force``, ``joint`` or ``sensor``.
        law: the law (signature of its kind, the coefficient as third argument).
        param: the coefficient's name; unit: its unit.
        magnitudes: the two injected values (per patch for terrain forces).
        bounds: (lower, upper) of the user term's parameter.
        channels: the channels it should move (names or prefixes such as ``q_``).
        proposal_feature: ``axis:feature`` of the proposal that is this law, and its
            expected per-patch coefficient as a multiple of the magnitude ("" when no
            feature of the proposal library is the law).
        sign: that multiple.
        family: the measurement-model effect (``granular_mpc.effects.measurement``) that
            contains this law, when it does ("" otherwise): with ``--measurement`` it is a
            candidate of the library run and counts as the right answer.
    """

    name: str
    kind: str
    law: Callable
    param: str
    unit: str
    magnitudes: tuple[float, float]
    bounds: tuple[float, float]
    channels: tuple[str, ...]
    proposal_feature: str = ""
    sign: float = 0.0
    family: str = ""

    @property
    def hidden(self) -> str:
        return HIDDEN + self.name

    @property
    def user(self) -> str:
        return USER + self.name

    @property
    def words(self) -> str:
        return (self.law.__doc__ or "").strip().split("\n")[0]


FORMS: tuple[Form, ...] = (
    Form("vdamp", "terrain_force", vertical_damping, "b", "N·s/m", (10.0, 15.0), (0.0, 500.0),
         ("intrusion_z",), "z:v_z", -1.0),
    Form("v2drag", "terrain_force", shear_drag_sq, "c", "N·s²/m²", (150.0, 400.0),
         (0.0, 5000.0), ("intrusion_x", "grf_x"), "h:v_h_abs_v_h", -1.0),
    Form("hard_layer", "terrain_force", hard_layer, "k", "N/m", (3000.0, 8000.0),
         (0.0, 1.0e5), ("intrusion_z",)),
    Form("lat_spring", "terrain_force", lateral_restoring, "k", "N/m", (3.0e4, 1.0e5),
         (0.0, 1.0e6), ("intrusion_y", "grf_y")),
    Form("sole_coulomb", "terrain_force", sole_coulomb, "f0", "N", (5.0, 12.0), (0.0, 100.0),
         ("intrusion_x", "grf_x"), "h:sign_v_h", -1.0),
    Form("stiction", "joint", stiction, "tau_s", "N·m", (0.2, 0.5), (0.0, 5.0), ("q_",)),
    Form("knee_spring", "joint", knee_spring, "k", "N·m/rad", (1.0, 3.0), (-20.0, 20.0),
         ("q_left_knee", "q_right_knee")),
    Form("torque_gain", "sensor", torque_gain, "g", "-", (0.08, 0.2), (-0.5, 0.5), ("q_",),
         family="torque_gain"),
    Form("encoder_offset", "sensor", encoder_offset, "delta", "rad", (0.02, 0.05),
         (-0.3, 0.3), ("q_left_knee",), family="encoder_offset"),
    Form("grf_bias_left", "sensor", grf_bias_left, "b", "N", (5.0, 12.0), (-50.0, 50.0),
         ("grf_z",)),
)
FORM_BY_NAME = {f.name: f for f in FORMS}
QUICK_FORMS = ("vdamp", "v2drag", "hard_layer", "sole_coulomb", "stiction", "torque_gain",
               "encoder_offset", "grf_bias_left")
#: null sets: the plant's terrain unlike the model file (φ_s 38°, layer 0.12 m, k 2e5 N/m)
MISMATCHES = ("terrain.phi_s_deg=33", "terrain.layer_depth=0.04",
              "terrain.contact_stiffness=1e5")
#: pairs: a library effect (its main parameter) + a form at its first magnitude
PAIRS = (("cohesion:suction=2000", "suction", "vdamp"),
         ("joint_friction:coulomb=0.1,viscous=0.02", "coulomb", "encoder_offset"))


def _wrap(form: Form) -> Callable:
    """The law as a function of the kind's plugin signature, reading ``p[form.param]``."""
    law, key = form.law, form.param
    if form.kind == "terrain_force":
        def fn(o, s, p):
            return law(o, s, p[key])
    elif form.kind == "joint":
        def fn(q_a, dq_a, p):
            return law(q_a, dq_a, p[key])
    else:
        def fn(cols, p, ctx):
            return law(cols, p[key], ctx)
    fn.__doc__ = law.__doc__
    return fn


_REGISTER = {"terrain_force": register_effect, "joint": register_joint_effect,
             "sensor": register_sensor_effect}


def register_forms() -> None:
    """Register every form twice with the plugin API: the hidden truth ``ool_<name>``
    (default: its first magnitude) and the user's term ``user_<name>`` (default: half of
    it, the user's guess; bounds :attr:`Form.bounds`). Idempotent."""
    have = set(registered_names())
    for f in FORMS:
        lo, hi = f.bounds
        for name, default in ((f.hidden, f.magnitudes[0]), (f.user, 0.5 * f.magnitudes[0])):
            if name in have:
                continue
            _REGISTER[f.kind](name, params={f.param: Param(default, lo, hi, f.unit, f.words)},
                              neutral={f.param: 0.0})(_wrap(f))


@dataclass(frozen=True)
class Case:
    """One data set: a form at a magnitude (optionally with a library partner), or a null
    set with a plant mismatch."""

    tag: str
    seed: int
    form: str = ""
    magnitude: float = 0.0
    partner: str = ""          # library effect string
    partner_param: str = ""
    mismatch: str = ""         # scenario override of the plant

    @property
    def group(self) -> str:
        return "null" if self.mismatch else ("pair" if self.partner else "ool")

    @property
    def truth(self) -> str:
        if self.mismatch:
            return f"none (plant {self.mismatch.split('.', 1)[1]})"
        f = FORM_BY_NAME[self.form]
        t = f"{f.name} {f.param}={self.magnitude:g} {f.unit}"
        return f"{self.partner} + {t}" if self.partner else t

    def effects(self) -> list[str]:
        out = [self.partner] if self.partner else []
        if self.form:
            f = FORM_BY_NAME[self.form]
            out.append(f"{f.hidden}:{f.param}={self.magnitude:g}")
        return out


def build_cases(forms, seeds, magnitudes, pairs: bool, mismatches) -> list[Case]:
    """The benchmark's cases, in run order (``magnitudes``: how many of each form's, or
    the indices of those to run)."""
    idx = range(magnitudes) if isinstance(magnitudes, int) else magnitudes
    cases = [Case(f"{n}_m{i}_s{s}", s, n, FORM_BY_NAME[n].magnitudes[i])
             for n in forms for i in idx for s in seeds]
    if pairs:
        for lib, par, n in PAIRS:
            cases.append(Case(f"pair_{lib.split(':')[0]}+{n}_s{seeds[0]}", seeds[0], n,
                              FORM_BY_NAME[n].magnitudes[0], lib, par))
    for m in mismatches:
        key = m.split("=")[0].split(".")[-1]
        cases.append(Case(f"null_{key}_s{100 + seeds[0]}", 100 + seeds[0], mismatch=m))
    return cases


# --- one case (in its own process) -----------------------------------------------------

def _channel_changes(d) -> dict:
    return {c: [ch.before, ch.after] for c, ch in d.replay_rmse_by_channel.items()}


def _worsened(d) -> list[str]:
    """Added terms whose replay worsens a channel they are credited with."""
    out = []
    for a in d.acceptance:
        if a.effect in d.added and any(ch.after > ch.before for ch in a.credited_channels.values()):
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


def run_case(case: Case, root: Path, steps: int, n_boot: int, user_terms: bool,
             measurement: bool = False) -> dict:
    """Synthesize, noise, diagnose with the library (and with ``measurement`` the
    measurement-model family), then with the proposal fed back."""
    from granular_mpc.effects.measurement import MEASUREMENT
    from granular_mpc.validation.diagnose import diagnose
    from granular_mpc.validation.diagnosis.proposal import proposed_effects
    from granular_mpc.validation.synth import noisy_copy, synthesize

    register_forms()
    library = LIBRARY + (list(MEASUREMENT) if measurement else [])
    t0 = time.perf_counter()
    clean, noisy = root / f"{case.tag}_clean", root / f"{case.tag}_noisy"
    synthesize("sand_walk", clean, speeds=SPEEDS, steps=steps, seed=case.seed,
               effects=case.effects(), noise=0.0, format="parquet",
               overrides=[case.mismatch] if case.mismatch else [], overwrite=True, workers=1)
    noisy_copy(clean, noisy, 1.0, seed=case.seed, overwrite=True)
    row: dict = {"case": asdict(case), "synth_s": time.perf_counter() - t0}
    t0 = time.perf_counter()
    lib = diagnose(noisy, root / f"{case.tag}_lib", candidates=library, seed=case.seed,
                   n_boot=n_boot, workers=1, figures=False)
    row["lib"] = _summary(lib)
    row["lib_s"] = time.perf_counter() - t0
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
    if user_terms and case.form:
        cands.append(FORM_BY_NAME[case.form].user)
    row["fb"] = None
    row["measurement"] = measurement
    if len(cands) > len(library):
        t0 = time.perf_counter()
        fb = diagnose(noisy, root / f"{case.tag}_fb", candidates=cands, seed=case.seed,
                      n_boot=n_boot, workers=1, figures=False, effect_files=files)
        row["fb"] = _summary(fb)
        row["fb_s"] = time.perf_counter() - t0
    return row


# --- scoring and tables ------------------------------------------------------------------

def affected_channel(case: Case, row: dict) -> str:
    """The channel the truth moves: among the form's channels (names or prefixes), the one
    whose base-model replay RMSE is largest in units of its scatter (the base replay is
    the same in both runs; '' when neither run replayed)."""
    if not case.form:
        return ""
    form = FORM_BY_NAME[case.form]
    runs = [r for r in (row.get("fb"), row.get("lib")) if r and r["replay"]]
    if not runs:
        return ""
    rep, sigma = runs[0]["replay"], runs[0]["sigma"]
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


def score(row: dict) -> dict:
    """Per-case judgements for the targets table."""
    case = Case(**row["case"])
    lib, fb = row["lib"], row.get("fb")
    ch = affected_channel(case, row)
    out = {"channel": ch, "lib_red": _reduction(lib, ch), "fb_red": _reduction(fb, ch)}
    form = FORM_BY_NAME.get(case.form)
    found_name = ""
    if fb and fb["rank1_added"] and (fb["rank1"].startswith(PROPOSED_PREFIX)
                                     or fb["rank1"] == (form.user if form else "")):
        found_name = fb["rank1"]
    out["found"] = bool(found_name) and (out["fb_red"] or 0.0) >= 0.5
    out["found_term"] = found_name
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
        true = effect_info(name).resolve_params(spec["params"])[case.partner_param]
        fit = lib["fitted"].get(name, {}).get(case.partner_param)
        out["partner_rank1"] = lib["rank1"] == name and lib["rank1_added"]
        out["partner_coef_err"] = (fit - true) / true if fit is not None else math.nan
        out["both_found"] = name in lib["added"] and bool(found_name)
    out["null_added"] = bool(lib["added"]) if case.mismatch else False
    out["worsened"] = len(lib["worsened"]) + (len(fb["worsened"]) if fb else 0)
    return out


def figures(rows: list[dict]) -> dict:
    sc = [(Case(**r["case"]), score(r)) for r in rows]
    ool = [s for c, s in sc if c.group in ("ool", "pair")]
    pairs = [s for c, s in sc if c.group == "pair"]
    nulls = [s for c, s in sc if c.group == "null"]

    def rate(xs, key):
        vals = [x for x in xs if isinstance(x.get(key), bool) or not math.isnan(x.get(key, math.nan))]
        return sum(bool(x[key]) for x in vals) / len(vals) if vals else math.nan

    return {
        "ool_wrong_answer_rate": rate([s for c, s in sc if c.group == "ool"], "wrong_answer"),
        "ool_found_rate": rate([s for c, s in sc if c.group == "ool"], "found"),
        "pair_both_found_rate": rate(pairs, "both_found"),
        "pair_rank1_rate": rate(pairs, "partner_rank1"),
        "pair_coef_within_15pct_rate": (sum(abs(p["partner_coef_err"]) <= 0.15 for p in pairs)
                                        / len(pairs) if pairs else math.nan),
        "null_added_rate": rate(nulls, "null_added"),
        "added_worsening": sum(s["worsened"] for _, s in sc),
        "cases": len(ool) - len(pairs), "pair_cases": len(pairs), "null_cases": len(nulls),
    }


def _pct(x: float) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:+.0f} %"


def _frac(rows: list[dict], group: str, key: str) -> str:
    sc = [score(r) for r in rows if Case(**r["case"]).group == group]
    vals = [s[key] for s in sc if key in s and not (isinstance(s[key], float) and math.isnan(s[key]))]
    return f"{sum(bool(v) for v in vals)}/{len(vals)}" if vals else "n/a"


def targets_table(rows: list[dict]) -> str:
    """The targets table of issue 11, from this benchmark's cases."""
    pairs = [score(r) for r in rows if Case(**r["case"]).group == "pair"]
    within = sum(abs(p["partner_coef_err"]) <= 0.15 for p in pairs)
    worsened = sum(score(r)["worsened"] for r in rows)
    lines = ["| figure | this run | target |", "|---|---|---|",
             f"| library effect (pair member) ranked first | {_frac(rows, 'pair', 'partner_rank1')} | ≥ 90 % |",
             f"| main coefficient within 15 % (pair member) | {within}/{len(pairs)} | ≥ 85 % |"
             if pairs else "| main coefficient within 15 % (pair member) | n/a | ≥ 85 % |",
             f"| both effects of a pair found | {_frac(rows, 'pair', 'both_found')} | ≥ 80 % |",
             f"| out-of-library: a wrong term presented as the answer | {_frac(rows, 'ool', 'wrong_answer')} | ≤ 10 % |",
             f"| out-of-library: proposal (or user term) ranked first, affected error −50 % | {_frac(rows, 'ool', 'found')} | ≥ 70 % |",
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
            rep = (fb or lib)["replay"] if ch in (fb or lib)["replay"] else lib["replay"]
            b = rep[ch][0]
            a_lib = lib["replay"][ch][1] if ch in lib["replay"] else b
            a_fb = fb["replay"][ch][1] if fb and ch in fb["replay"] else b
            err = f"{ch}: {b:.4g} → {a_lib:.4g} / {a_fb:.4g}"
        lines.append(f"| {case.tag} | {case.truth} | {lib['status']}, {added}{ans} | {proposed} "
                     f"| {fbt} | {coefs} | {err} |")
    return "\n".join(lines)


def _child(args) -> None:
    case = Case(**json.loads(args.case))
    row = run_case(case, args.out, args.steps, args.n_boot, args.user_terms, args.measurement)
    (args.out / f"{case.tag}.json").write_text(json.dumps(row, indent=1, default=str),
                                               encoding="utf-8")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--forms", nargs="*", default=[f.name for f in FORMS],
                    choices=[f.name for f in FORMS])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--magnitudes", type=int, default=2, choices=(1, 2))
    ap.add_argument("--steps", type=int, default=7, help="stances per trial (3 trials)")
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
    ap.add_argument("--workers", type=int, default=1, help="cases at a time")
    ap.add_argument("--out", type=Path, default=None, help="keep data and diagnoses here")
    ap.add_argument("--reuse", action="store_true", help="with --out: reuse finished cases")
    ap.add_argument("--report-only", action="store_true",
                    help="with --out: only tabulate the cases already finished there")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--case", help=argparse.SUPPRESS)      # internal: run one case
    args = ap.parse_args()
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
    cases = build_cases(args.forms, args.seeds, args.mag_index or args.magnitudes,
                        not args.no_pairs, mismatches)
    print(f"{len(cases)} cases in {args.out}", flush=True)

    def one(case: Case) -> dict | None:
        res = args.out / f"{case.tag}.json"
        if args.report_only and not res.is_file():
            return None
        if not ((args.reuse or args.report_only) and res.is_file()):
            cmd = [sys.executable, __file__, "--case", json.dumps(asdict(case)), "--out",
                   str(args.out), "--steps", str(args.steps), "--n-boot", str(args.n_boot)]
            cmd += ["--user-terms"] if args.user_terms else []
            cmd += ["--measurement"] if args.measurement else []
            t0 = time.perf_counter()
            with open(args.out / f"{case.tag}.log", "w", encoding="utf-8") as log:
                proc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, env=os.environ)
            if proc.returncode != 0 or not res.is_file():
                print(f"{case.tag}: FAILED (rc {proc.returncode}; see {case.tag}.log) "
                      f"[{time.perf_counter() - t0:.0f} s]", flush=True)
                return None
        row = json.loads(res.read_text(encoding="utf-8"))
        s, lib, fb = score(row), row["lib"], row.get("fb")
        print(f"{case.tag:34s} lib {lib['status']}: {','.join(lib['added']) or '-'}"
              f"{' (answer)' if lib['is_answer'] and lib['added'] else ''} | fb "
              f"{'-' if not fb else fb['status'] + ': ' + (','.join(fb['added']) or '-')} | "
              f"{s['channel'] or '-'} {_pct(s['lib_red'])} / {_pct(s['fb_red'])} "
              f"[{row.get('synth_s', 0) + row.get('lib_s', 0) + row.get('fb_s', 0):.0f} s]",
              flush=True)
        return row

    with ThreadPoolExecutor(max_workers=max(1, args.workers)) as ex:
        rows = [r for r in ex.map(one, cases) if r is not None]
    print("\n## Targets (issue 11)\n\n" + targets_table(rows))
    print("\n## Cases\n\n" + case_table(rows) + "\n")
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
