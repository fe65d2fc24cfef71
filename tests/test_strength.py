"""A terrain-strength mismatch in disguise (``validation.diagnosis.strength``): a candidate
whose evidence a φ_s column explains as well is not significant and the verdict says the data
cannot tell a φ_s mismatch from an effect that strengthens the sand like one; a real effect
correlated with φ_s keeps its evidence."""
from __future__ import annotations

import math

import numpy as np
import pytest

from granular_mpc.effects import effect_info
from granular_mpc.validation.diagnosis import (Column, Design, ParamEstimate, Ranked,
                                               Regression, candidate_stats)
from granular_mpc.validation.diagnosis.localization_records import Localization
from granular_mpc.validation.diagnosis.strength import StrengthModel, StrengthTwin, strength_twin
from granular_mpc.validation.diagnosis.verdict import (VerdictInputs, best_candidate_statement,
                                                       decide)

PHI = "strength.phi_s"
DH = "depth_hardening.n"
PHI_FILE_RAD = math.radians(38.0)


def _design(truth: str, seed: int = 0, n_groups: int = 6, n_rows: int = 300,
            with_strength: bool = True) -> Regression:
    """Systematic rows with a nuisance (ζ), a φ_s column (per rad) and a depth-hardening
    column that shares 60 % of its variance with φ_s (|corr| ≈ 0.77, like the measured
    −0.73 on the recovery study's data); the residual is either a φ_s mismatch
    (``truth="phi_s"``, Δφ_s = −5°) or a real hardening (``truth="dh"``, Δn = 0.5)."""
    rng = np.random.default_rng(seed)
    n = n_groups * n_rows
    groups = np.repeat([f"t{k}" for k in range(n_groups)], n_rows)
    bins = np.arange(n) % 10
    nuis = rng.normal(size=n)
    phi = 10.0 * (np.linspace(-2.0, 2.0, 10)[bins] + 0.3 * rng.normal(size=n))
    own = np.cos(np.linspace(0.0, 2.0 * np.pi, 10))[bins] + 0.3 * rng.normal(size=n)
    dh = -(0.77 * phi / phi.std() + 0.64 * own / own.std())
    y = 0.8 * nuis + 0.5 * rng.normal(size=n)
    y += math.radians(-5.0) * phi if truth == "phi_s" else 0.5 * dh
    X = {"calibration.zeta": nuis, DH: dh}
    if with_strength:
        X[PHI] = phi
    d = Design(y, X, groups, np.zeros(n, int), np.full(n, "intrusion_z"), bins,
               {"intrusion_z": 1.0}, 1.0)
    return Regression(d, {k: (-10.0, 10.0) for k in X}, ["calibration.zeta"], stance_design=d)


def _stats(reg):
    cols = {"depth_hardening": [Column("depth_hardening", "n", 1.0, 0.5, 1.0, 3.0)]}
    return candidate_stats(reg, ["calibration.zeta"], {"depth_hardening": [DH]}, cols,
                           {"depth_hardening": effect_info("depth_hardening")}, n_boot=40,
                           seed=0, max_effects=1)


@pytest.mark.parametrize("seed", (0, 1, 2))
def test_a_strength_mismatch_is_not_a_missing_effect(seed):
    reg = _design("phi_s", seed)
    (row,) = _stats(reg)
    # alone the candidate explains a large share (it is 77 % collinear with φ_s) ...
    assert row.heldout_error_reduction > 0.25 and row.delta_aicc < -10
    # ... but not beside φ_s: not significant, and the twin says what φ_s the data ask for
    assert not row.significant
    tw = strength_twin(reg, ["calibration.zeta"], "depth_hardening", [DH],
                       row.heldout_error_reduction, {PHI: PHI_FILE_RAD})
    assert tw is not None and tw.given_strength_heldout_error_reduction < 0.02
    assert tw.strength_values["phi_s_deg"] == pytest.approx(33.0, abs=0.5)
    assert tw.file_values["phi_s_deg"] == pytest.approx(38.0)
    assert "EITHER the sand is weaker than the terrain file says" in tw.sentence()
    assert f"phi_s_deg ≈ {tw.strength_values['phi_s_deg']:.1f}" in tw.sentence()


@pytest.mark.parametrize("seed", (0, 1, 2))
def test_a_real_effect_correlated_with_strength_keeps_its_evidence(seed):
    reg = _design("dh", seed)
    (row,) = _stats(reg)
    assert row.significant and row.params["n"].value == pytest.approx(1.5, abs=0.05)
    assert strength_twin(reg, ["calibration.zeta"], "depth_hardening", [DH],
                         row.heldout_error_reduction, {PHI: PHI_FILE_RAD}) is None


def test_without_a_strength_column_there_is_no_twin():
    """φ_s calibrated (then a nuisance column) or no force data: nothing to test against;
    the candidate is judged as before (here it passes: it is all the model has)."""
    reg = _design("phi_s", with_strength=False)
    assert strength_twin(reg, ["calibration.zeta"], "depth_hardening", [DH], 0.3, {}) is None
    (row,) = _stats(reg)
    assert row.significant


def test_the_verdict_names_the_twin_and_adds_nothing():
    est = ParamEstimate(1.18, 0.02, 1.14, 1.22, "-", 1.0, 1.0, 3.0, False, 1.1, 1.25)
    r = Ranked(effect="depth_hardening", kind="terrain_force", heldout_error_reduction=0.26,
               heldout_error_reduction_stance=0.13, delta_aicc=-84.0, folds_improved="2/3",
               effect_size=2.3, params={"n": est}, main="n", depends_on=(), doc="",
               inclusion_probability=0.98, significant=False, rank=1)
    tw = StrengthTwin("depth_hardening", 0.26, -0.037, -8.0, 0.37, {"phi_s_deg": 33.3},
                      {"phi_s_deg": 38.0})
    empty = Localization((), (), 0, 0, {}, (), {}, {})
    v = decide(VerdictInputs((), (r,), None, empty, strength_twins=(tw,)))
    assert v.status == "no_significant_missing_effect" and v.added == ()
    assert "terrain-strength mismatch" in v.text and "phi_s_deg ≈ 33.3" in v.text
    best = best_candidate_statement(VerdictInputs((), (r,), None, empty, strength_twins=(tw,)))
    assert best.startswith("the best candidate, depth_hardening, is only the closest proxy")
    assert "terrain-strength mismatch" in best and "OR a missing effect" in best
    assert "is the answer" not in best
    # the signs of the held-out changes: 26 % less alone, 3.7 % more beside φ_s
    assert "alone by −26.0 %" in tw.sentence() and "beside φ_s by +3.7 %" in tw.sentence()


def _shapes(seed: int, n_groups: int = 6, n_rows: int = 300):
    """Rows of a φ_s mismatch far outside the linear range: the plant's response to the
    strength (``chord``, from the file's 38° to the plant's 33°) is not the derivative at
    38° (``slope``), and a depth-dependent candidate (``dh``) shares the difference."""
    rng = np.random.default_rng(seed)
    n = n_groups * n_rows
    groups = np.repeat([f"t{k}" for k in range(n_groups)], n_rows)
    bins = np.arange(n) % 10
    x = np.linspace(-2.0, 2.0, 10)[bins]
    nuis = rng.normal(size=n)
    slope = 10.0 * (x + 0.3 * rng.normal(size=n))
    curve = 10.0 * (x + 0.8 * x ** 2 + 0.3 * rng.normal(size=n))
    dh = -(x ** 2 + 0.2 * x + 0.3 * rng.normal(size=n))
    noise = 0.5 * rng.normal(size=n)
    return groups, bins, nuis, slope, curve, dh, noise


def _regression(groups, bins, y, cols) -> Regression:
    n = y.size
    d = Design(y, cols, groups, np.zeros(n, int), np.full(n, "intrusion_z"), bins,
               {"intrusion_z": 1.0}, 1.0)
    return Regression(d, {k: (-10.0, 10.0) for k in cols}, ["calibration.zeta"], stance_design=d)


@pytest.mark.parametrize("seed", (0, 1))
def test_the_twin_test_runs_at_the_strength_the_data_ask_for(seed):
    """Linearised at the file's φ_s, the candidate still helps beside the φ_s column (the
    curvature of the strength's response is the candidate's shape); replayed at the φ_s
    the data ask for (a StrengthModel), it does not: a twin, with the refined φ_s."""
    groups, bins, nuis, slope, curve, dh, noise = _shapes(seed)
    d_phi = math.radians(-5.0)
    y = 0.8 * nuis + d_phi * curve + noise
    linear = _regression(groups, bins, y, {"calibration.zeta": nuis, DH: dh, PHI: slope})
    assert strength_twin(linear, ["calibration.zeta"], "depth_hardening", [DH], 0.3,
                         {PHI: PHI_FILE_RAD}) is None          # the linear test misses it
    # at 33°: the residual of the model replayed there, the derivative there, the
    # candidate replayed there
    at = _regression(groups, bins, 0.8 * nuis + noise,
                     {"calibration.zeta": nuis, DH: dh, PHI: slope})
    model = StrengthModel(PHI, (PHI_FILE_RAD, PHI_FILE_RAD + d_phi), at)
    assert model.value == PHI_FILE_RAD + d_phi
    tw = strength_twin(linear, ["calibration.zeta"], "depth_hardening", [DH], 0.3,
                       {PHI: PHI_FILE_RAD}, model)
    assert tw is not None and tw.given_strength_heldout_error_reduction < 0.02
    assert tw.strength_values["phi_s_deg"] == pytest.approx(33.0, abs=0.3)
    assert tw.file_values["phi_s_deg"] == pytest.approx(38.0)
    assert tw.strength_heldout_error_reduction > 0.5
    # a real effect is still there at the refined strength: no twin
    real = _regression(groups, bins, 0.8 * nuis + 0.5 * dh + noise,
                       {"calibration.zeta": nuis, DH: dh, PHI: slope})
    assert strength_twin(linear, ["calibration.zeta"], "depth_hardening", [DH], 0.3,
                         {PHI: PHI_FILE_RAD},
                         StrengthModel(PHI, (PHI_FILE_RAD, PHI_FILE_RAD + d_phi), real)) is None
    # a candidate whose replays diverged at the refined strength is not in its
    # regression: it cannot be a twin
    without = _regression(groups, bins, 0.8 * nuis + noise, {"calibration.zeta": nuis, PHI: slope})
    assert strength_twin(linear, ["calibration.zeta"], "depth_hardening", [DH], 0.3,
                         {PHI: PHI_FILE_RAD},
                         StrengthModel(PHI, (PHI_FILE_RAD, PHI_FILE_RAD + d_phi), without)) is None


def test_a_candidate_exempt_from_the_twin_test_keeps_its_significance():
    """``not_twins`` (the torque-side candidates when the joint equations show a torque
    discrepancy, :func:`strength.not_twins`): the twin test is not applied to them."""
    reg = _design("phi_s", 0)
    cols = {"depth_hardening": [Column("depth_hardening", "n", 1.0, 0.5, 1.0, 3.0)]}
    args = (reg, ["calibration.zeta"], {"depth_hardening": [DH]}, cols,
            {"depth_hardening": effect_info("depth_hardening")})
    (tested,) = candidate_stats(*args, n_boot=40, seed=0, max_effects=1)
    (exempt,) = candidate_stats(*args, n_boot=40, seed=0, max_effects=1,
                                not_twins={"depth_hardening"})
    assert not tested.significant and exempt.significant
    assert exempt.heldout_error_reduction == tested.heldout_error_reduction


def test_torque_side_candidates_are_no_twins_only_with_a_joint_discrepancy(workbench_data):
    """Joint effects and sensor effects on ``tau_*`` are the torque side; they are exempt
    from the twin test only when the joint-axis proposal passed on some joint."""
    from granular_mpc.effects import Param, register_sensor_effect, registered_effects
    from granular_mpc.validation.diagnosis.candidates import (build_candidates,
                                                              check_sensor_candidates)
    from granular_mpc.validation.diagnosis.problem import load_problem
    from granular_mpc.validation.diagnosis.proposal_records import JointFit, Proposal
    from granular_mpc.validation.diagnosis.strength import not_twins, torque_side

    if "_test_tau_gain" not in registered_effects():
        @register_sensor_effect("_test_tau_gain", params={"g": Param(0.1, -0.5, 0.5)},
                                main="g", neutral={"g": 0.0})
        def _gain(cols, p, ctx):
            return {c: (1.0 + p["g"]) * np.asarray(v, float) for c, v in cols.items()
                    if c.startswith("tau_")}

    problem = load_problem(workbench_data("null"))
    cands = build_candidates(["joint_friction", "force_sensor_bias", "inertial_drag",
                              "_test_tau_gain"])
    # what the sensors change is known only once they were tried on the data
    assert torque_side(cands) == {"joint_friction"}
    cands = check_sensor_candidates(cands, problem.windows[0], problem.joint_names)
    assert cands.sensor_outputs["force_sensor_bias"] <= {"grf_x", "grf_y", "grf_z"}
    assert cands.replayed_sensors == {"_test_tau_gain"}
    assert torque_side(cands) == {"joint_friction", "_test_tau_gain"}
    assert torque_side(cands.without(["_test_tau_gain"])) == {"joint_friction"}

    def proposal(passed: bool) -> Proposal:
        return Proposal("p", "", (), (), 0, 0,
                        joint_fits=(JointFit("left_knee", 0.8, 0.8, 0.5, 0.1, passed),))

    assert not_twins(cands, None) == frozenset()
    assert not_twins(cands, proposal(False)) == frozenset()
    assert not_twins(cands, proposal(True)) == {"joint_friction", "_test_tau_gain"}
