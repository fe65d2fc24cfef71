"""Proposed terms (validation/diagnosis/proposal.py, features.py, sparse.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from granular_mpc.effects import effect_info, load_effect_file
from granular_mpc.effects.state import PatchState
from granular_mpc.terrain.closed_form import FLOAT
from granular_mpc.validation.diagnosis.features import (FEATURES, feature, feature_names,
                                                        sample_columns)
from granular_mpc.validation.diagnosis.joint_proposal import PROPOSED_JOINT, PROPOSED_SENSOR
from granular_mpc.validation.diagnosis.proposal import (MIN_EXPLAINED_FORCE, PROPOSAL_FILE,
                                                        axis_passes, effect_source,
                                                        effect_sources, law_fit,
                                                        pointed_proposal, propose_terms,
                                                        write_proposal)
from granular_mpc.validation.diagnosis.proposal_records import (AxisFit, JointFit, JointTerm,
                                                                Proposal, ProposedTerm,
                                                                change_text)
from granular_mpc.validation.diagnosis.result import Verdict
from granular_mpc.validation.diagnosis.sparse import independent, sparse_fit, stlsq


def _toy(seed=0, n_groups=4, per=120):
    rng = np.random.default_rng(seed)
    n = n_groups * per
    X = rng.normal(size=(n, 6))
    nuis = rng.normal(size=(n, 1))
    y = 3.0 * X[:, 1] - 2.0 * X[:, 3] + 1.5 * nuis[:, 0] + 0.3 * rng.normal(size=n)
    groups = np.repeat(np.arange(n_groups), per).astype(str)
    units = np.repeat(np.arange(n // 20), 20)
    return X, nuis, y, groups, units


def test_stlsq_keeps_only_the_true_terms():
    X, N, y, _, _ = _toy()
    xi, nu = stlsq(X, N, y, threshold=0.5)
    assert set(np.flatnonzero(xi)) == {1, 3}
    assert xi[1] == pytest.approx(3.0, abs=0.1) and xi[3] == pytest.approx(-2.0, abs=0.1)
    assert nu[0] == pytest.approx(1.5, abs=0.1)


def test_sparse_fit_selects_stable_terms_and_reports_heldout_gain():
    X, N, y, groups, units = _toy(1)
    fit = sparse_fit(X, N, y, groups, units, seed=0)
    assert set(np.flatnonzero(fit.selected)) == {1, 3}
    assert fit.coef[1] == pytest.approx(3.0, rel=0.05)
    assert fit.frequency[1] >= 0.9 and fit.frequency[3] >= 0.9
    assert fit.heldout_reduction_selected > 0.5
    assert fit.rmse_after < fit.rmse_before


def test_sparse_fit_on_noise_proposes_little():
    rng = np.random.default_rng(3)
    X, N, _, groups, units = _toy(3)
    y = 0.5 * N[:, 0] + rng.normal(size=X.shape[0])
    fit = sparse_fit(X, N, y, groups, units, seed=0)
    assert fit.heldout_reduction_selected < 0.05


def test_duplicated_feature_is_not_usable():
    rng = np.random.default_rng(0)
    a = rng.normal(size=50)
    X = np.column_stack([a, -a, rng.normal(size=50)])
    assert independent(X, np.ones((50, 1))).tolist() == [True, False, True]


def test_every_feature_has_a_unit_and_a_unique_name():
    assert len(set(feature_names())) == len(FEATURES)
    assert all(f.unit for f in FEATURES)
    assert feature("v_z").expressible and feature("right_foot").expressible
    # the per-foot law features are shares of the law's own force: the same per patch
    assert feature("right_law_z").relative and feature("right_law_h").relative
    assert not feature("depth").relative


def _proposal(c_foot=-20.0):
    t = ProposedTerm("z", "v_z", feature("v_z").description, c_foot, c_foot / 2, 1.0,
                     "N/(m/s)", 0.95, True)
    return Proposal("test_proposed_force", "", (t,),
                    (AxisFit("z", 0.5, 0.6, 9.0, 5.0, 0.3, True),
                     AxisFit("h", 0.0, 0.01, 3.0, 3.0, 1.0, False)), 400, 24)


def _patch(vz):
    return PatchState(depth=0.02, in_contact=1.0, p_c=(0.0, 0.0, -0.02), v_c=(0.1, 0.0, vz),
                      a_c=(0.0, 0.0, 0.0), intrusion=(0.0, 0.0, 0.02), heading=(1.0, 0.0),
                      lateral=(0.0, 1.0), f_terrain=(0.0, 0.0, 50.0), f_yield_z=50.0,
                      area_h=0.002, width=0.04, density=1500.0, dt=5e-4)


def test_effect_file_registers_and_evaluates_the_proposed_force(tmp_path):
    path = tmp_path / PROPOSAL_FILE
    path.write_text(effect_source(_proposal(), "data"), encoding="utf-8")
    text = path.read_text(encoding="utf-8")
    assert "N/(m/s)" in text and "held-out error −60 %" in text
    assert load_effect_file(str(path)) == ["test_proposed_force"]
    info = effect_info("test_proposed_force")
    # every term switches off (the base model of a diagnosis has none of them on)
    assert set(info.neutral) == set(info.params)
    assert all(v == 0.0 for v in info.neutral_params().values())
    p = info.neutral_params() | {"z_v_z": -10.0}
    fx, fy, fz = info.fn(FLOAT, _patch(-0.5), p)
    assert fz == pytest.approx(5.0) and fx == pytest.approx(0.0) and fy == pytest.approx(0.0)
    # the physical interval keeps the proposed sign: a sign flip is reported as such
    assert info.params["z_v_z"].physical_range[1] == 0.0


def test_verdict_points_to_the_proposal_only_when_unexplained(tmp_path):
    v = Verdict("unexplained_structure", "structure", ())
    v2, p2 = pointed_proposal(v, "", _proposal(), tmp_path)
    assert p2.pointed_to and p2.files == ("test_proposed_force.py",)
    assert "--effect-file test_proposed_force.py" in v2.text
    assert (tmp_path / PROPOSAL_FILE).is_file() and (tmp_path / p2.files[0]).is_file()
    v3, p3 = pointed_proposal(Verdict("no_significant_missing_effect", "none", ()), "",
                              _proposal(), tmp_path)
    assert not p3.pointed_to and PROPOSAL_FILE not in v3.text


def _force_fit(pattern_n, effect_n, seed=0, n_groups=3, per=100):
    """A sparse fit of a constructed force equation error [N]: a systematic pattern of
    RMS ``pattern_n`` on three features that varies between trials (the closed form's
    forward-axis error on data without a missing force: explained by the features in
    sample, held-out −30 to −90 %), plus a true term of RMS ``effect_n`` on a fourth
    feature that is the same in every trial, plus 2 N noise."""
    rng = np.random.default_rng(seed)
    n = n_groups * per
    X = rng.normal(size=(n, 6))
    groups = np.repeat(np.arange(n_groups), per).astype(str)
    mix = 1.0 + 0.3 * rng.normal(size=(n_groups, 3))          # per-trial pattern weights
    g = np.repeat(np.arange(n_groups), per)
    pattern = (X[:, :3] * mix[g]).sum(axis=1)
    pattern *= pattern_n / np.sqrt(np.mean(pattern ** 2))
    y = pattern + effect_n * X[:, 3] + 2.0 * rng.normal(size=n)
    fit = sparse_fit(X, np.ones((n, 1)), y, groups, np.arange(n) // 10, seed=seed)
    return fit


@pytest.mark.parametrize("axis", ["z", "h"])
def test_axis_rule_needs_more_force_than_null_data_explain(axis):
    """The evidence rule of a force axis: a null-like pattern with a large held-out
    reduction but less force than :data:`MIN_EXPLAINED_FORCE` is not proposed; the same
    pattern plus a term twice the threshold is."""
    thr = MIN_EXPLAINED_FORCE[axis]
    null = _force_fit(0.8 * thr, 0.0)
    assert null.heldout_reduction_selected >= 0.15 and null.heldout_reduction >= 0.075
    assert not axis_passes(null.heldout_reduction, null.heldout_reduction_selected,
                           null.rmse_before, null.rmse_after, axis)
    real = _force_fit(0.8 * thr, 2.0 * thr, seed=1)
    assert axis_passes(real.heldout_reduction, real.heldout_reduction_selected,
                       real.rmse_before, real.rmse_after, axis)
    # a large force that does not hold out (per-fold selection makes the error worse)
    assert not axis_passes(-0.4, 0.7, 30.0, 5.0, axis)
    assert axis_passes(0.6, 0.7, 30.0, 5.0, axis)
    assert AxisFit(axis, 0.6, 0.7, 5.0, 3.0, 0.1, True).explained_rms == pytest.approx(4.0)


def test_a_reduction_prints_as_a_signed_change():
    assert change_text(0.83) == "−83 %" and change_text(-0.12) == "+12 %"
    assert "−-" not in change_text(-0.004) and change_text(0.0) == "+0 %"


def _full_proposal():
    joint = (JointTerm("left_knee", "dq", -0.4, 0.01, "N·m/(rad/s)", 1.0),
             JointTerm("right_knee", "tau", -0.1, 0.01, "-", 1.0))
    fits = (JointFit("left_knee", 0.8, 0.8, 0.5, 0.1, True),
            JointFit("right_knee", 0.5, 0.5, 0.4, 0.2, True))
    return Proposal(_proposal().effect, "", _proposal().terms, _proposal().axes, 400, 24,
                    joint_terms=joint, joint_fits=fits)


def test_each_proposed_effect_is_written_to_a_file_of_its_own(tmp_path):
    """One file per proposed effect, each loading alone and registering only its effect;
    the file with all of them registers the three."""
    p = write_proposal(tmp_path, _full_proposal(), "data")
    assert p.files == ("test_proposed_force.py", f"{PROPOSED_JOINT}.py", f"{PROPOSED_SENSOR}.py")
    assert set(effect_sources(_full_proposal())) == set(p.files)
    for f in p.files:
        text = (tmp_path / f).read_text(encoding="utf-8")
        # one registration, of the effect the file is named after (load_effect_file
        # returns only names new to the registry, so the text is what is checked)
        assert text.count("@register_") == 1 and f"({f[:-3]!r}, replace=True" in text
        assert f"--effect-file {f}" in text
        load_effect_file(str(tmp_path / f))
        assert set(effect_info(f[:-3]).params) > {"scale"} or f == p.files[0]
    all_text = (tmp_path / p.file).read_text(encoding="utf-8")
    assert all_text.count("@register_") == 3
    load_effect_file(str(tmp_path / p.file))
    assert effect_info(PROPOSED_SENSOR).kind == "sensor"
    assert effect_info(PROPOSED_JOINT).kind == "joint"
    # a proposal with nothing expressible writes nothing
    empty = Proposal("x", "", (), (), 10, 2)
    assert write_proposal(tmp_path / "none", empty).files == ()


@pytest.mark.slow
def test_proposal_finds_a_hidden_vertical_damping(tmp_path, monkeypatch):
    """Out-of-library F_z = −b·v_z (b = 10 N·s/m per patch, 20 per foot) written with the
    plugin API: on most realisations the proposal selects a sink-rate term with the sign
    of a damping.

    A rate over three realisations (seeds 31–33, reference plant), not one seed: whether
    the z axis passes its evidence rule is realisation-dependent (each revision of the
    plant and of the controller changes the same seed's data). Measured (this commit):
    seed 31 explains 3.6 N on z (below the 5 N rule: nothing proposed), seeds 32 and 33
    8.9–9.3 N with held-out −88 %. The test asks for 2 of 3."""
    monkeypatch.setenv("GRANULAR_MPC_PLANT", "reference")
    from granular_mpc.effects import Param, register_effect, registered_effects
    from granular_mpc.validation.calibrate import calibrate
    from granular_mpc.validation.diagnosis.problem import load_problem
    from granular_mpc.validation.synth import noisy_copy, synthesize

    if "_test_hidden_damping" not in registered_effects():
        @register_effect("_test_hidden_damping",
                         params={"b": Param(10.0, 0.0, 500.0, "N·s/m", "")})
        def _damp(o, s, p):
            return (0.0, 0.0, -p["b"] * s.v_c[2] * s.in_contact)

    found = []
    for seed in (31, 32, 33):
        clean = tmp_path / f"clean{seed}"
        synthesize("sand_walk", clean, speeds=(0.15, 0.25, 0.35), steps=7, seed=seed,
                   effects=["_test_hidden_damping:b=10"], noise=0.0, format="parquet")
        noisy = noisy_copy(clean, tmp_path / f"noisy{seed}", 1.0, seed=seed)
        pr = load_problem(noisy)
        cal = calibrate(pr.windows, pr.replay_model.terrain, n_slices=2, params=("zeta",),
                        n_boot=0)
        prop = propose_terms(pr, cal.values, seed=seed)
        # −b·v_z on every patch in contact is −b·n(depth)·v_z per foot: the fit may name it
        # v_z, depth·v_z or both. Either is a damping: at the median depth of the sinking
        # samples it was fitted on, the net sink-rate coefficient opposes the sinking.
        vz = {t.feature: t.coefficient_foot for t in prop.terms
              if t.axis == "z" and t.feature in ("v_z", "depth_v_z")}
        if not vz:
            continue
        depth = float(np.median(sample_columns(pr.windows)["depth"]))
        net = vz.get("v_z", 0.0) + vz.get("depth_v_z", 0.0) * depth           # N·s/m, foot
        assert -60.0 < net < -6.7, (seed, depth, vz)                         # truth −20
        z = next(a for a in prop.axes if a.axis == "z")
        assert z.proposed and z.heldout_error_reduction_selected > 0.3
        found.append(seed)
    assert len(found) >= 2, found


def _samples(law=None, coef=0.0, pattern=0.0, seed=0, n_stances=24, per=18,
             law_nuisance=False):
    """Synthetic sinking samples of 3 trials: features from random sole states, a target
    of ``coef``·(law feature) + a null-like pattern (depth, time in stance) + 2 N noise.
    ζ's column is ∝ depth on both axes, or with ``law_nuisance`` the law's own force / ζ
    (a law ∝ ζ, as the closed form)."""
    from granular_mpc.validation.diagnosis.features import ForceSamples

    rng = np.random.default_rng(seed)
    n = n_stances * per
    t = np.tile(np.linspace(0.0, 0.15, per), n_stances)
    c = {"depth": 0.005 + 0.15 * t + 1e-3 * rng.normal(size=n),
         "v_z": -0.9 + 4.0 * t + 0.05 * rng.normal(size=n),
         "v_h": np.repeat(rng.uniform(-0.25, 0.25, n_stances), per) + 0.03 * rng.normal(size=n),
         "v_l": 0.02 * rng.normal(size=n), "a_z": rng.normal(size=n), "t_stance": t,
         "foot": np.repeat(np.arange(n_stances) % 2, per)}
    # the calibrated law's own force at the sample (∝ depth, forward part opposing v_h)
    c["law_z"] = 5000.0 * c["depth"]
    c["law_h"] = -0.4 * c["law_z"] * np.tanh(c["v_h"] / 0.05)
    F = np.column_stack([f.compute(c) for f in FEATURES])
    y = 2.0 * rng.normal(size=n) + pattern * (c["depth"] / 0.015 - 1.0 - t / 0.075)
    if law:
        y = y + coef * F[:, feature_names().index(law)]
    window = np.repeat(np.arange(n_stances), per)
    trial = (window % 3).astype(str)
    nuis = ({"z": c["law_z"] / 1.36, "h": c["law_h"] / 1.36} if law_nuisance
            else {"z": 50.0 * c["depth"], "h": 50.0 * c["depth"]})
    return ForceSamples({"z": y, "h": y}, nuis, F, trial, window, c["foot"], 2)


def _law_passes(fit, axis) -> bool:
    """Whether a law fit passes its axis rule with the law thresholds."""
    from granular_mpc.validation.diagnosis.proposal import MIN_LAW_FORCE

    return fit is not None and axis_passes(fit.heldout_reduction,
                                           fit.heldout_reduction_selected, fit.rmse_before,
                                           fit.rmse_after, axis, MIN_LAW_FORCE)


def _assert_recovered(fit, law, coef, axis):
    """``law`` selected, its coefficient within 15 % of ``coef``, and the axis passes."""
    k = feature_names().index(law)
    assert fit is not None and fit.selected[k]
    assert fit.coef[k] == pytest.approx(coef, rel=0.15)
    assert _law_passes(fit, axis)


@pytest.mark.parametrize("law,axis,coef", [("v_h_abs_v_h", "h", -300.0),
                                           ("sign_v_h", "h", -12.0),
                                           ("v_z", "z", -25.0)])
def test_law_fit_recovers_a_dissipative_law_and_passes(law, axis, coef):
    """A force residual made of one physical law (quadratic drag, Coulomb offset, linear
    damping; foot level) under a null-like pattern and noise: the law stage selects it,
    with its coefficient within 15 %, and the axis passes with the law thresholds."""
    _assert_recovered(law_fit(_samples(law, coef, pattern=3.0, seed=2), axis, seed=0),
                      law, coef, axis)


@pytest.mark.parametrize("axis", ["z", "h"])
def test_law_fit_proposes_nothing_on_a_null_residual(axis):
    """Noise plus a null-like pattern (no velocity law): the law stage does not pass."""
    for seed in (3, 4):
        assert not _law_passes(law_fit(_samples(pattern=3.0, seed=seed), axis, seed=0), axis)


def test_law_fit_drops_a_law_of_the_wrong_physical_sign():
    """A force *along* the motion (v_h·|v_h| > 0: no drag) is not kept as a law."""
    fit = law_fit(_samples("v_h_abs_v_h", +300.0, seed=5), "h", seed=0)
    assert fit is None or not (fit.coef > 0).any()
    assert fit is None or not fit.selected[feature_names().index("v_h_abs_v_h")]


@pytest.mark.parametrize("axis,coef", [("z", -0.25), ("z", 0.4), ("h", -0.5)])
def test_per_foot_law_recovers_one_foots_share_of_the_law(axis, coef):
    """A right foot bearing (1 + g) of the law's force (a worn sole g < 0, a right track
    of stronger sand g > 0) under a null-like pattern and noise: the per-foot law stage
    (ζ free for the common scale) selects it with g within 15 % and the axis passes.
    (The stage has no term for a pattern common to both feet: at 3 N the forward share
    comes out 17 % high — a hypothesis the replays refit, as the worn sole below.)"""
    from granular_mpc.validation.diagnosis.proposal import PER_FOOT_FEATURES

    law = PER_FOOT_FEATURES[axis][0]
    fs = _samples(law, coef, pattern=1.0, seed=6, law_nuisance=True)
    _assert_recovered(law_fit(fs, axis, seed=0, laws=PER_FOOT_FEATURES, dissipative=False),
                      law, coef, axis)


@pytest.mark.parametrize("axis", ["z", "h"])
def test_per_foot_law_proposes_nothing_when_the_feet_agree(axis):
    """The same law on both feet (a common scale, which ζ carries) plus the null-like
    pattern: the per-foot stage does not pass."""
    from granular_mpc.validation.diagnosis.proposal import PER_FOOT_FEATURES

    for seed in (3, 4):
        fs = _samples(pattern=3.0, seed=seed, law_nuisance=True)
        both = {a: fs.target[a] + 0.3 * 1.36 * fs.nuisance[a] for a in ("z", "h")}
        fs = type(fs)(both, fs.nuisance, fs.features, fs.trial, fs.window, fs.foot, 2)
        fit = law_fit(fs, axis, seed=0, laws=PER_FOOT_FEATURES, dissipative=False)
        assert not _law_passes(fit, axis)


def test_effect_file_of_a_per_foot_share_acts_on_its_foot_only(tmp_path):
    """A proposed right-foot share of the law: per patch the same coefficient as per foot,
    physical above −1 (a sole cannot lose more than all of the force), zero on the left
    foot, g·f_terrain on the right."""
    t = ProposedTerm("z", "right_law_z", feature("right_law_z").description, -0.3, -0.3,
                     0.01, "-", 1.0, True)
    prop = Proposal("test_per_foot_force", "", (t,),
                    (AxisFit("z", 0.7, 0.7, 11.0, 5.0, 0.3, True, "per_foot"),), 300, 24)
    path = tmp_path / "per_foot.py"
    path.write_text(effect_source(prop, "data"), encoding="utf-8")
    assert load_effect_file(str(path)) == ["test_per_foot_force"]
    info = effect_info("test_per_foot_force")
    par = info.params["z_right_law_z"]
    assert par.default == pytest.approx(-0.3) and par.lower == pytest.approx(-6.0)
    assert par.physical_range == (-1.0, 0.0)
    p = {"z_right_law_z": -0.3}
    right, left = replace(_patch(-0.5), foot=1.0), replace(_patch(-0.5), foot=0.0)
    assert info.fn(FLOAT, right, p)[2] == pytest.approx(-0.3 * 50.0)
    assert info.fn(FLOAT, left, p)[2] == pytest.approx(0.0)


def test_proposal_finds_a_worn_right_sole(tmp_path):
    """Out-of-library: the right sole bears 75 % of the terrain law's force (written with
    the plugin API, not in the library). The proposal is the per-foot share of the law on
    the vertical axis, negative, near −0.25 (measured on this realisation: −0.32; the
    equation error at the calibrated ζ, before any replay refit)."""
    from granular_mpc.effects import Param, register_effect, registered_effects
    from granular_mpc.validation.calibrate import calibrate
    from granular_mpc.validation.diagnosis.problem import load_problem
    from granular_mpc.validation.synth import noisy_copy, synthesize

    if "_test_worn_sole" not in registered_effects():
        @register_effect("_test_worn_sole", params={"w": Param(0.25, 0.0, 0.9, "-", "")})
        def _worn(o, s, p):
            k = -p["w"] * s.is_right * s.in_contact
            return (k * s.f_terrain[0], k * s.f_terrain[1], k * s.f_terrain[2])

    clean = tmp_path / "clean"
    synthesize("sand_walk", clean, speeds=(0.15, 0.25, 0.35), steps=7, seed=1,
               effects=["_test_worn_sole:w=0.25"], noise=0.0, format="parquet")
    noisy = noisy_copy(clean, tmp_path / "noisy", 1.0, seed=1)
    pr = load_problem(noisy)
    cal = calibrate(pr.windows, pr.replay_model.terrain, n_slices=2, params=("zeta",),
                    n_boot=0)
    prop = propose_terms(pr, cal.values, seed=1)
    z = next(a for a in prop.axes if a.axis == "z")
    assert z.proposed and z.stage == "per_foot"
    terms = {t.feature: t for t in prop.terms if t.axis == "z"}
    assert set(terms) == {"right_law_z"}
    assert -0.45 < terms["right_law_z"].coefficient_patch < -0.15


def test_a_share_below_minus_one_is_not_a_per_foot_law():
    """A fitted share of −5 (the forward law's force is small: the share absorbs another
    pattern) is not physical: the per-foot stage must not pass with it."""
    from granular_mpc.validation.diagnosis.proposal import PER_FOOT_FEATURES, physical_shares

    fs = _samples("right_law_z", -0.25, pattern=1.0, seed=6, law_nuisance=True)
    fit = law_fit(fs, "z", seed=0, laws=PER_FOOT_FEATURES, dissipative=False)
    assert physical_shares(fit)
    k = feature_names().index("right_law_z")
    coef = fit.coef.copy()
    coef[k] = -5.0
    assert not physical_shares(replace(fit, coef=coef))


@pytest.mark.parametrize("law,coef", [("below_15mm", 4000.0), ("below_20mm", -3000.0)])
def test_layer_stage_recovers_a_layer_below_an_interface(law, coef):
    """A force that acts only below an interface depth, an extra stiffness k·(d − d_L)⁺
    (a harder bed, k > 0; a looser bed under a crust, k < 0), under a null-like pattern
    and noise: the best law of the vertical axis is that layer law, at its interface, with
    its coefficient within 15 %. (The toy's law is ∝ depth, so its share below d_L,
    ``law_below_*``, is the same column; the tie goes to the stiffness, tried first.)"""
    from granular_mpc.validation.diagnosis.proposal import best_law

    fs = _samples(law, coef, pattern=1.0, seed=7, law_nuisance=True)
    fit, stage = best_law(fs, "z", seed=0)
    assert stage == "layer"
    _assert_recovered(fit, law, coef, "z")
    assert fit.selected.sum() == 1


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_layer_stage_proposes_nothing_on_a_null_residual(seed):
    """Noise plus the null-like pattern, no layer: no law of the vertical axis passes."""
    from granular_mpc.validation.diagnosis.proposal import best_law

    fit, stage = best_law(_samples(pattern=3.0, seed=seed, law_nuisance=True), "z", seed=0)
    assert fit is None and stage == ""


def test_layer_features_stay_out_of_the_whole_library_fit():
    """The layer laws are tried alone only: the whole-library fit never selects one, even
    where a layer is the truth (a hinge at a grid of depths beside depth and depth² is a
    flexible curve that fits the closed form's own null pattern)."""
    from granular_mpc.validation.diagnosis.proposal import LAYER_FEATURES, library_fit

    fit = library_fit(_samples("below_15mm", 4000.0, pattern=1.0, seed=7), "z", seed=0)
    layer = [feature_names().index(n) for n in LAYER_FEATURES["z"]]
    assert fit.selected.any() and not fit.selected[layer].any()


def test_a_layer_splits_the_samples_or_is_not_tried():
    """An interface above (nearly) every sinking sample, or below (nearly) every one, is
    not a layer the samples can show: it is not tried."""
    from granular_mpc.validation.diagnosis.proposal import MIN_LAYER_SHARE, layer_splits

    fs = _samples(seed=1)
    depth = fs.features[:, feature_names().index("depth")]
    for name in ("below_5mm", "below_15mm", "below_30mm"):
        share = float(np.mean(depth > float(name[6:-2]) * 1e-3))
        assert layer_splits(fs, name) == (MIN_LAYER_SHARE <= share <= 1 - MIN_LAYER_SHARE)
    assert layer_splits(fs, "below_15mm") and not layer_splits(fs, "below_30mm")


def test_effect_file_of_a_layer_acts_below_its_interface_only(tmp_path):
    """A proposed stiffness below 15 mm: zero on a patch above the interface, k·(d − d_L)
    per patch below it; the law's share below the interface scales f_terrain by
    g·(d − d_L)/d."""
    terms = (ProposedTerm("z", "below_15mm", feature("below_15mm").description, 4000.0,
                          2000.0, 100.0, "N/(m)", 1.0, True),
             ProposedTerm("z", "law_below_15mm", feature("law_below_15mm").description, 0.5,
                          0.5, 0.01, "-", 1.0, True))
    prop = Proposal("test_layer_force", "", terms,
                    (AxisFit("z", 0.7, 0.7, 11.0, 5.0, 0.3, True, "layer"),), 300, 24)
    path = tmp_path / "layer.py"
    path.write_text(effect_source(prop, "data"), encoding="utf-8")
    assert load_effect_file(str(path)) == ["test_layer_force"]
    info = effect_info("test_layer_force")
    p = {"z_below_15mm": 2000.0, "z_law_below_15mm": 0.5}
    deep, shallow = replace(_patch(-0.5), depth=0.025), replace(_patch(-0.5), depth=0.010)
    assert info.fn(FLOAT, deep, p)[2] == pytest.approx(2000.0 * 0.010 + 0.5 * 50.0 * 0.4)
    assert info.fn(FLOAT, shallow, p)[2] == pytest.approx(0.0)
