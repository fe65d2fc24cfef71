"""The out-of-library benchmark's case definitions and table assembly (bench/out_of_library.py),
without any diagnosis: each form registers with the plugin API, moves its channel when
switched on and nothing when off, and the targets table counts what the rows say."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from granular_mpc.effects import (PatchState, SensorContext, apply_sensor_effects, effect_info,
                                  joint_torque_function)
from granular_mpc.terrain.closed_form import FLOAT, casadi_ops

BENCH = Path(__file__).resolve().parents[1] / "bench" / "out_of_library.py"


@pytest.fixture(scope="module")
def ool():
    spec = importlib.util.spec_from_file_location("bench_out_of_library", BENCH)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod                    # dataclasses resolve their module
    spec.loader.exec_module(mod)
    mod.register_forms()
    return mod


def _patch(foot: float = 1.0) -> PatchState:
    """A sinking sole moving forward, 25 mm deep, 1 mm left of its touchdown track (of
    the right foot unless ``foot`` = 0)."""
    return PatchState(depth=0.025, in_contact=1.0, p_c=(0.1, 0.0, -0.025),
                      v_c=(0.2, 0.05, -0.3), a_c=(0.0, 0.0, 0.0), intrusion=(0.004, 0.001, 0.025),
                      heading=(1.0, 0.0, 0.0), lateral=(0.0, 1.0, 0.0),
                      f_terrain=(3.0, 0.0, 60.0), f_yield_z=60.0, area_h=2e-3, width=0.03,
                      density=1660.0, dt=5e-4, depth_max=0.025, t_stance=0.05, foot=foot)


AXIS = {"x": 0, "y": 1, "z": 2}


def test_at_least_eight_distinct_forms_of_every_kind(ool):
    assert len(ool.FORMS) >= 8
    assert len({f.name for f in ool.FORMS}) == len(ool.FORMS)
    assert {f.kind for f in ool.FORMS} == {"terrain_force", "joint", "sensor"}
    for f in ool.FORMS:
        assert effect_info(f.hidden).kind == f.kind == effect_info(f.user).kind
        assert f.magnitudes[0] != f.magnitudes[1]
        lo, hi = f.bounds
        assert lo <= 0.5 * f.magnitudes[0] <= hi and lo <= f.magnitudes[1] <= hi
        # none of them is in the library
        assert f.hidden not in ool.LIBRARY and f.user not in ool.LIBRARY
    assert set(ool.QUICK_FORMS) <= {f.name for f in ool.FORMS} and len(ool.QUICK_FORMS) == 9


def test_terrain_forms_push_along_their_channel_and_compile(ool):
    ca = pytest.importorskip("casadi")
    s = _patch()
    for f in (f for f in ool.FORMS if f.kind == "terrain_force"):
        fn = effect_info(f.hidden).fn
        axis = AXIS[f.channels[0][-1]]                  # intrusion_z → z …
        on = fn(FLOAT, s, {f.param: f.magnitudes[1]})
        off = fn(FLOAT, s, {f.param: 0.0})
        assert abs(on[axis]) > 0.2, (f.name, on)         # > 0.2 N per patch at this state
        assert max(abs(v) for v in off) == 0.0, f.name
        # the same source compiles (CasADi) and gives the same force
        sym = fn(casadi_ops(), s, {f.param: ca.SX(f.magnitudes[1])})
        got = [float(ca.evalf(ca.SX(v))) for v in sym]
        assert got == pytest.approx(list(on), rel=1e-9, abs=1e-12), f.name
    # the worn sole acts on the right foot only, as the share w of the law's own force
    f = ool.FORM_BY_NAME["worn_sole"]
    fn = effect_info(f.hidden).fn
    assert fn(FLOAT, _patch(0.0), {f.param: 0.3}) == (0.0, 0.0, 0.0)
    assert fn(FLOAT, _patch(1.0), {f.param: 0.3}) == pytest.approx((-0.9, 0.0, -18.0))


def test_joint_forms_add_torque_where_they_should(ool):
    q = np.array([-0.12, -0.7, 1.6, 0.12, -0.7, 1.2])
    dq = np.array([0.02, -0.03, 0.01, -0.02, 0.04, -0.01])      # slow: stiction acts
    for name, joints in (("stiction", range(6)), ("knee_spring", ool.KNEES)):
        f = ool.FORM_BY_NAME[name]
        info = effect_info(f.hidden)
        tau = joint_torque_function([(info, {f.param: f.magnitudes[0]})])(q, dq)
        assert np.all(np.abs(tau[list(joints)]) > 0.01), (name, tau)
        others = [i for i in range(6) if i not in joints]
        assert np.all(tau[others] == 0.0)
        off = joint_torque_function([(info, {f.param: 0.0})])(q, dq)
        assert np.all(off == 0.0)
    # stiction opposes the motion and vanishes at speed
    f = ool.FORM_BY_NAME["stiction"]
    fn = effect_info(f.hidden).fn
    assert np.all(fn(q, dq, {f.param: 0.5}) * dq < 0)
    assert np.all(np.abs(fn(q, 3.0 * np.ones(6), {f.param: 0.5})) < 1e-6)


def test_sensor_forms_change_only_their_columns(ool):
    n = 6
    joints = ("left_hip_abd", "left_hip_pitch", "left_knee", "right_hip_abd",
              "right_hip_pitch", "right_knee")
    cols = {f"{k}_{j}": np.linspace(1.0, 2.0, n) for k in ("q", "dq", "tau") for j in joints}
    cols |= {f"grf_{a}": np.full(n, 80.0) for a in "xyz"}
    ctx = SensorContext(np.array(["left"] * 3 + ["right"] * 3), np.arange(n) * 0.01, joints)
    expect = {"torque_gain": {f"tau_{j}" for j in joints}, "encoder_offset": {"q_left_knee"},
              "grf_bias_left": {"grf_z"}}
    for name, changed_cols in expect.items():
        f = ool.FORM_BY_NAME[name]
        out = apply_sensor_effects(cols, [(effect_info(f.hidden), {f.param: f.magnitudes[0]})],
                                   ctx)
        changed = {c for c in cols if not np.array_equal(out[c], cols[c])}
        assert changed == changed_cols, name
    f = ool.FORM_BY_NAME["grf_bias_left"]
    out = apply_sensor_effects(cols, [(effect_info(f.hidden), {f.param: 5.0})], ctx)
    assert np.allclose(out["grf_z"], [85.0] * 3 + [80.0] * 3)


def test_cases_quick_and_full(ool):
    quick = ool.build_cases(ool.QUICK_FORMS, [1], 1, False, ool.MISMATCHES[:2])
    assert len(quick) == 11 and [c.group for c in quick].count("null") == 2
    full = ool.build_cases([f.name for f in ool.FORMS], [1, 2, 3], 2, True, ool.MISMATCHES)
    assert len(full) == len(ool.FORMS) * 2 * 3 + len(ool.PAIRS) + len(ool.MISMATCHES)
    assert len({c.tag for c in full}) == len(full)
    pair = next(c for c in full if c.group == "pair")
    assert len(pair.effects()) == 2 and pair.effects()[0] == pair.partner
    assert next(c for c in full if c.group == "null").effects() == []
    # no forms (`--forms` with nothing): the null sets only
    nulls = ool.build_cases([], [1], 2, False, ool.MISMATCHES)
    assert [c.group for c in nulls] == ["null"] * len(ool.MISMATCHES)
    # two values of one key are two folders
    two = ool.build_cases([], [9], 1, False, ["terrain.contact_damping=300",
                                               "terrain.contact_damping=50"])
    assert [c.tag for c in two] == ["null_contact_damping_300_s109",
                                    "null_contact_damping_50_s109"]


def _run(status, added, replay, rank1="", answer=False, fitted=None, worsened=()):
    return {"status": status, "added": list(added), "rank1": rank1 or (added[0] if added else ""),
            "rank1_added": bool(added), "is_answer": answer, "best_candidate": "",
            "fitted": fitted or {}, "replay": replay, "worsened": list(worsened),
            "sigma": {"intrusion_z": 0.001, "grf_z": 5.0}, "ranks": {}}


def test_scores_and_targets_table(ool):
    vd = ool.Case("vdamp_m0_s1", 1, "vdamp", 10.0)
    found = {"case": vd.__dict__,
             "lib": _run("missing_effect", ["cohesion"], {"intrusion_z": [0.008, 0.006]},
                         answer=True),
             "proposal": {"file": "proposed_effect.py", "files": ["proposed_force.py"],
                          "pointed_to": False, "terms": {"z:v_z": -13.0}},
             "fb": _run("partially_explained", ["proposed_force"],
                        {"intrusion_z": [0.008, 0.002], "grf_z": [15.0, 10.0]},
                        fitted={"proposed_force": {"z_v_z": -11.0}}, worsened=["x"])}
    s = ool.score(found)
    assert s["channel"] == "intrusion_z" and s["found"] and s["wrong_answer"]
    assert s["fb_red"] == pytest.approx(0.75) and s["coef_err"] == pytest.approx(-0.1)
    null = {"case": ool.Case("null_phi_s_deg_s101", 101, mismatch="terrain.phi_s_deg=33").__dict__,
            "lib": _run("no_missing_effect", [], {}), "proposal": None, "fb": None}
    assert not ool.score(null)["null_added"] and math.isnan(ool.score(null)["coef_err"])
    figs = ool.figures([found, null])
    assert figs["ool_found_rate"] == 1.0 and figs["ool_wrong_answer_rate"] == 1.0
    assert figs["null_added_rate"] == 0.0 and figs["added_worsening"] == 1
    table = ool.targets_table([found, null])
    assert "| out-of-library: a wrong term presented as the answer | 1/1 |" in table
    assert "| null sets: a term added | 0/1 |" in table
    cases = ool.case_table([found, null])
    assert "intrusion_z: 0.008 → 0.006 / 0.002" in cases and "[law coef err -10 %]" in cases
    assert "| z: v_z |" in cases and "proposed_force (1 terms; z_v_z=-11)" in cases
    found.update(lib_s=30.4, fb_s=20.0)
    line = ool.progress_line(found)
    assert line.startswith("vdamp_m0_s1 ") and "lib missing_effect: cohesion (answer)" in line
    assert "fb partially_explained: proposed_force" in line
    assert "intrusion_z +25 % / +75 % [50 s]" in line
    assert "| fb - |" in ool.progress_line(null) and "[0 s]" in ool.progress_line(null)


def test_found_by_whom_and_detectable(ool):
    """``found`` split by who found it (the proposal or the user term) and the detectable
    cases: the truth at its true value cuts the affected channel by ≥ 50 %."""
    hl = ool.Case("hard_layer_m1_s1", 1, "hard_layer", 8000.0)
    user = {"case": hl.__dict__, "lib": _run("partially_explained", ["elastic_unloading"],
                                             {"intrusion_z": [0.004, 0.003]}),
            "proposal": None,
            "fb": _run("partially_explained", ["user_hard_layer"],
                       {"intrusion_z": [0.004, 0.0016]},
                       fitted={"user_hard_layer": {"k": 7200.0}}),
            "truth_replay": {"intrusion_z": [0.004, 0.0012]}}
    user["fb"]["ranks"] = {"user_hard_layer": 1}
    s = ool.score(user)
    assert s["found"] and s["found_by"] == "user" and s["found_user"]
    assert not s["found_proposal"] and s["user_rank"] == 1 and s["user_added"]
    assert s["truth_red"] == pytest.approx(0.7) and s["detectable"] is True
    assert s["coef_err"] == pytest.approx(-0.1)
    # the truth itself cuts the channel by 20 % only: not detectable, and not found
    weak = {**user, "truth_replay": {"intrusion_z": [0.004, 0.0032]},
            "fb": {**user["fb"], "replay": {"intrusion_z": [0.004, 0.0033]}}}
    w = ool.score(weak)
    assert w["detectable"] is False and not w["found"] and w["found_by"] == ""
    # nothing replayed by the diagnoses: the truth's replay names the affected channel
    quiet = {**user, "lib": _run("no_significant_missing_effect", [], {}),
             "fb": _run("no_significant_missing_effect", [], {})}
    q = ool.score(quiet)
    assert q["channel"] == "intrusion_z" and q["fb_red"] == 0.0 and not q["found"]
    assert "| intrusion_z: 0.004 → 0.004 / 0.004 |" in ool.case_table([quiet])
    # a proposal's find
    vd = ool.Case("vdamp_m0_s1", 1, "vdamp", 10.0)
    prop = {"case": vd.__dict__, "lib": _run("missing_effect", ["cohesion"],
                                             {"intrusion_z": [0.008, 0.006]}),
            "proposal": None, "fb": _run("missing_effect", ["proposed_force"],
                                         {"intrusion_z": [0.008, 0.002]}),
            "truth_replay": {"intrusion_z": [0.008, 0.003]}}
    p = ool.score(prop)
    assert p["found_by"] == "proposal" and p["found_proposal"] and not p["found_user"]
    figs = ool.figures([user, weak, quiet, prop])
    assert figs["ool_found_rate"] == 0.5
    assert figs["ool_found_by_user_term_rate"] == 0.25
    assert figs["ool_found_by_proposal_rate"] == 0.25
    assert figs["ool_detectable_rate"] == 0.75
    assert figs["ool_found_rate_detectable"] == pytest.approx(2 / 3)
    table = ool.targets_table([user, weak, quiet, prop])
    assert "| … found by the proposal / by the user term | 1/4 / 1/4 | |" in table
    assert "| … found among the detectable (proposal / user term) | 2/3 (1/3 / 1/3) |" in table
    ut = ool.user_table([user, weak, quiet, prop])
    assert "| hard_layer_m1_s1 | hard_layer k=8000 N/m | 1, yes | -10 % | intrusion_z: +60 % / +70 % | user |" in ut


def _absorbed_hard_layer(ool) -> dict:
    """A hard layer whose truth cuts intrusion_z by 70 % against the model file (4 → 1.2
    mm), 33 % against the library run's calibration (1.8 mm) and 25 % against the
    feedback run's (1.6 mm), where the user's term takes it to 1.3 mm."""
    hl = ool.Case("hard_layer_m1_s1", 1, "hard_layer", 8000.0)
    return {"case": hl.__dict__,
            "lib": _run("partially_explained", ["elastic_unloading"],
                        {"intrusion_z": [0.0018, 0.0015]}),
            "proposal": None,
            "fb": _run("partially_explained", ["user_hard_layer"],
                       {"intrusion_z": [0.0016, 0.0013]}),
            "truth_replay": {"intrusion_z": [0.004, 0.0012]}}


def test_detectable_against_the_calibrated_baseline(ool):
    """The truth's RMSE against the calibrated model's (the feedback run's 'before', else
    the library run's): a hard layer whose truth cuts intrusion_z by 70 % against the model
    file but only 25 % against a calibration that absorbed part of it is not detectable on
    that scale; with no run's baseline the model-file test stands in."""
    row = _absorbed_hard_layer(ool)
    s = ool.score(row)
    assert s["detectable"] is True and s["truth_red_cal"] == pytest.approx(0.25)
    assert s["detectable_calibrated"] is False
    assert ool.truth_reduction_calibrated({**row, "fb": None}, "intrusion_z") == \
        pytest.approx(1 - 0.0012 / 0.0018)
    bare = {**row, "lib": _run("no_significant_missing_effect", [], {}), "fb": None}
    b = ool.score(bare)
    assert math.isnan(b["truth_red_cal"]) and b["detectable_calibrated"] is True
    figs = ool.figures([row, bare])
    assert figs["ool_detectable_calibrated_rate"] == 0.5
    assert figs["ool_found_rate_detectable_calibrated"] == 0.0
    assert "| … found among those | 0/1 |" in ool.targets_table([row, bare])


def test_found_against_the_model_file(ool):
    """The other reading of "affected error −50 %": the feedback run's RMSE against the
    model file's (the truth replay's before). The hard layer above: −19 % against the
    calibrated model (not found), −68 % against the model file (found); a run that did
    not replay the channel, or a case without the truth's replay, is never found so."""
    row = _absorbed_hard_layer(ool)
    s = ool.score(row)
    assert not s["found"] and s["fb_red"] == pytest.approx(1 - 0.0013 / 0.0016)
    assert s["found_model_file"] and s["fb_red_file"] == pytest.approx(1 - 0.0013 / 0.004)
    # the rank still counts: a library proxy first is no find on either scale
    proxy = {**row, "fb": _run("partially_explained", ["elastic_unloading"],
                               {"intrusion_z": [0.0016, 0.0013]})}
    assert not ool.score(proxy)["found_model_file"]
    no_truth = {**row, "truth_replay": {}}
    t = ool.score(no_truth)
    assert math.isnan(t["fb_red_file"]) and not t["found_model_file"]
    figs = ool.figures([row, proxy, no_truth])
    assert figs["ool_found_rate_model_file"] == pytest.approx(1 / 3)
    assert ("| … the same with the affected error measured against the model file (the "
            "user's model before the workbench; the baseline of 'detectable') | 1/3 | ≥ 70 % |"
            in ool.targets_table([row, proxy, no_truth]))


def test_pairs_both_found_the_partner_coefficient_and_the_detectable_pairs(ool):
    """A pair is found when its final run (the feedback run, else the library run) adds the
    library partner and the form's term; the partner's coefficient is read in that run,
    relative to its distance from neutral (depth_hardening: of n − 1); the pairs counted
    'detectable alone' are those whose form's single case of the same seed is detectable."""
    stiction = ool.FORM_BY_NAME["stiction"]
    pair = ool.Case("pair_depth_hardening+stiction_s1", 1, "stiction", stiction.magnitudes[0],
                    "depth_hardening:n=1.5", "n")
    found = {"case": pair.__dict__,
             "lib": _run("partially_explained", ["depth_hardening", "joint_friction"],
                         {"q_left_hip_pitch": [0.04, 0.02]},
                         fitted={"depth_hardening": {"n": 1.9}}),
             "proposal": None,
             "fb": _run("missing_effect", ["depth_hardening", stiction.user],
                        {"q_left_hip_pitch": [0.04, 0.015]},
                        fitted={"depth_hardening": {"n": 1.6},
                                stiction.user: {"tau_s": 0.22}})}
    s = ool.score(found)
    assert s["both_found"] and s["partner_rank1"]
    assert s["partner_coef_err"] == pytest.approx(0.2)          # (1.6 − 1.5) / (1.5 − 1)
    missed = {**found, "case": ool.Case("pair_depth_hardening+stiction_s2", 2, "stiction",
                                        stiction.magnitudes[0], "depth_hardening:n=1.5",
                                        "n").__dict__,
              "fb": _run("partially_explained", ["depth_hardening"],
                         {"q_left_hip_pitch": [0.04, 0.039]},
                         fitted={"depth_hardening": {"n": 1.45}})}
    m = ool.score(missed)
    assert not m["both_found"] and m["partner_coef_err"] == pytest.approx(-0.1)
    single = {"case": ool.Case("stiction_m0_s1", 1, "stiction", stiction.magnitudes[0]).__dict__,
              "lib": _run("no_significant_missing_effect", [], {}), "proposal": None,
              "fb": _run("missing_effect", [stiction.user], {"q_left_hip_pitch": [0.04, 0.01]}),
              "truth_replay": {"q_left_hip_pitch": [0.04, 0.012]}}
    assert ool.score(single)["detectable"] is True
    figs = ool.figures([found, missed, single])
    assert figs["pair_both_found_rate"] == 0.5
    assert figs["pair_both_found_rate_detectable"] == 1.0      # seed 2 has no single case
    table = ool.targets_table([found, missed, single])
    assert "| both effects of a pair found | 1/2 |" in table
    assert "| … among the pairs whose form is detectable alone (its single case, same seed) | 1/1 |" in table
    assert "| main coefficient within 15 % (pair member) | 1/2 |" in table


def test_found_by_the_proposal_alone(ool):
    """The proposal-alone run (no user term among the candidates) scores the proposal on
    its own; rows without that run use the feedback run when it had no user term in it,
    and are unknown (nan, not counted) when the user term was in it."""
    vd = ool.Case("vdamp_m1_s1", 1, "vdamp", 15.0)
    lib = _run("partially_explained", ["cohesion"], {"intrusion_z": [0.008, 0.007]})
    both = _run("missing_effect", ["user_vdamp"], {"intrusion_z": [0.008, 0.002]})
    both["ranks"] = {"user_vdamp": 1, "proposed_force": 2}
    alone = _run("missing_effect", ["proposed_force"], {"intrusion_z": [0.008, 0.003]})
    alone["ranks"] = {"proposed_force": 1}
    row = {"case": vd.__dict__, "lib": lib, "proposal": {"files": ["proposed_force.py"]},
           "fb": both, "fb_alone": alone, "truth_replay": {"intrusion_z": [0.008, 0.002]}}
    s = ool.score(row)
    assert s["found_by"] == "user" and s["found_proposal_alone"] is True
    # the proposal alone cuts the channel by 25 % only: not found
    weak = {**row, "fb_alone": {**alone, "replay": {"intrusion_z": [0.008, 0.006]}}}
    assert ool.score(weak)["found_proposal_alone"] is False
    # nothing proposed: the proposal-alone run did not happen, and nothing was found by it
    none = {**row, "proposal": None, "fb_alone": None}
    assert ool.score(none)["found_proposal_alone"] is False
    # an older row: its feedback run had the user term, so the proposal alone is unknown
    old = {k: v for k, v in row.items() if k != "fb_alone"}
    assert math.isnan(ool.score(old)["found_proposal_alone"])
    # an older row without user terms: the feedback run was the proposal alone
    no_user = {**old, "fb": alone}
    assert ool.score(no_user)["found_proposal_alone"] is True
    figs = ool.figures([row, weak, none, old])
    assert figs["ool_found_by_proposal_alone_rate"] == pytest.approx(1 / 3)
    assert figs["ool_found_by_proposal_alone_rate_detectable"] == pytest.approx(1 / 3)
    assert ("| … found by the proposal alone (a feedback run without the user term; all / "
            "detectable) | 1/3 / 1/3 | |") in ool.targets_table([row, weak, none, old])
