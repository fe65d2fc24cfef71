"""The foot-force equation error after the additions (``validation.diagnosis.force_leftover``):
what a stage still explains beside an effect column, which additions make the test
inapplicable, the verdict it changes, and a real data set without a missing foot force."""

from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.effects import effect_info
from granular_mpc.validation.diagnosis import ParamEstimate, Ranked
from granular_mpc.validation.diagnosis.acceptance_records import ForceLeftover
from granular_mpc.validation.diagnosis.features import FEATURES, ForceSamples, feature_names
from granular_mpc.validation.diagnosis.force_leftover import (EVIDENCE_MARGIN, FOOTPRINT_SHARE,
                                                              explained_by, force_leftover,
                                                              inapplicable, unproduced)
from granular_mpc.validation.diagnosis.localization_records import Localization
from granular_mpc.validation.diagnosis.verdict import (VerdictInputs, best_candidate_statement,
                                                       decide)
from sinking import sinking_columns


def _samples(y_of, n: int = 300, seed: int = 1) -> ForceSamples:
    """Sinking samples with the feature library's columns (three trials); target y_of(F)
    plus noise, ζ's column a law-like positive force."""
    rng = np.random.default_rng(seed)
    c = sinking_columns(n, seed)
    law = 100.0 + 3000.0 * c["depth"]
    F = np.column_stack([f.compute({**c, "law_z": law, "law_h": 0.1 * law}) for f in FEATURES])
    y = y_of(F) + rng.normal(0.0, 2.0, n)
    trial = np.array([f"t{i % 3}" for i in range(n)])
    window = np.arange(n) // 10
    return ForceSamples({"z": y, "h": rng.normal(0.0, 2.0, n)},
                        {"z": law / 1.4, "h": 0.1 * law / 1.4}, F, trial, window,
                        c["foot"].astype(int), 2)


def test_a_missing_damping_is_explained_by_the_law_beside_zeta():
    """y = −60·v_z (a vertical damping) + noise: the velocity law explains, beside ζ, the
    part of it ζ's column does not (computed here by projection); on noise alone the law
    explains (almost) nothing."""
    iv = feature_names().index("v_z")
    fs = _samples(lambda F: -60.0 * F[:, iv])
    base = fs.nuisance["z"][:, None]
    truth = -60.0 * fs.features[:, iv]
    coef = np.linalg.lstsq(base, truth, rcond=None)[0]
    expected = float(np.sqrt(np.mean((truth - base @ coef) ** 2)))
    assert expected > 8.0                         # well above the noise (2 N)
    assert explained_by(fs, "z", "law", seed=0) == pytest.approx(expected, rel=0.15)
    assert explained_by(_samples(lambda F: 0.0 * F[:, iv]), "z", "law", seed=0) < 1.0


def test_a_missing_force_is_left_when_the_additions_do_not_act_where_it_is():
    """9.5 N on z found by the library (threshold 5 N, margin 1.5: 7.5 N) and 7.0 N by the
    law: left when the additions produce less than half of it on those samples, not when
    they produce more; a stage below its threshold × the margin is no evidence."""
    assert EVIDENCE_MARGIN == 1.5 and FOOTPRINT_SHARE == 0.5
    explained = {"z": {"library": 9.5, "law": 7.0, "per_foot": 0.0},
                 "h": {"library": 12.0, "law": 8.0, "per_foot": 0.0}}   # h: < 14.25 and 9
    left = unproduced(explained, 0.8, ("elastic_unloading",), 259)
    assert [(f.axis, f.stage, f.explained, f.footprint, f.threshold) for f in left] == [
        ("z", "library", 9.5, 0.8, 5.0)]
    assert unproduced(explained, FOOTPRINT_SHARE * 9.5 + 1e-9, (), 259) == ()
    assert unproduced(explained, 10.0, ("user_hard_layer",), 259) == ()
    # 5.6 N of z (the strong elastic unloading's own data): above 5 N, below the margin
    assert unproduced({"z": {"library": 5.6, "law": 0.0, "per_foot": 0.0}}, 0.0, (), 9) == ()
    # the law relative to its own threshold (6 N on h) beats the library's 9.5 N
    both = unproduced({"h": {"library": 15.0, "law": 10.0, "per_foot": 0.0}}, 0.0, (), 100)
    assert [(f.stage, f.explained) for f in both] == [("law", 10.0)]


def test_additions_that_change_what_the_equation_reads_make_it_inapplicable():
    from dataclasses import replace

    from granular_mpc.validation.diagnosis.candidates import build_candidates

    cands = replace(build_candidates(["cohesion", "joint_friction", "terrain_slope",
                                      "force_sensor_bias"]),
                    sensor_outputs={"force_sensor_bias": frozenset({"grf_z"})})
    names = ("cohesion", "joint_friction", "terrain_slope", "force_sensor_bias")
    assert inapplicable(names, cands) == ("terrain_slope", "force_sensor_bias")
    assert inapplicable(names[:2], cands) == ()
    # a sensor on the torques only does not change the foot-force equation
    tau = replace(cands, sensor_outputs={"force_sensor_bias": frozenset({"tau_left_knee"})})
    assert inapplicable(names, tau) == ("terrain_slope",)


def _ranked(effect: str) -> Ranked:
    est = ParamEstimate(4882.0, 100.0, 4700.0, 5000.0, "Pa", 0.0, 0.0, 50000.0, False, 4700.0,
                        5000.0)
    return Ranked(effect=effect, kind="terrain_force", heldout_error_reduction=0.83,
                  heldout_error_reduction_stance=0.7, delta_aicc=-173.0, folds_improved="3/3",
                  effect_size=4.0, params={"pressure": est}, main="pressure", depends_on=(),
                  doc="", inclusion_probability=1.0, significant=True, rank=1, added=True,
                  refined_params={"pressure": 4882.0})


def test_a_foot_force_the_addition_does_not_produce_makes_it_a_proxy():
    """The hard layer's case: elastic_unloading added, its replays accepted, no cell left
    — but the equation error while the sole sinks holds 9.5 N of which it produces 0.8 N:
    partially explained, and the best candidate is only the closest proxy; without it,
    the answer."""
    empty = Localization((), (), 0, 0, {}, (), {}, {})
    r = _ranked("elastic_unloading")
    left = ForceLeftover("z", 9.5, 0.8, 5.0, ("elastic_unloading",), 259, "library")
    assert ForceLeftover.from_dict(left.to_dict()) == left       # diagnosis.json round trip
    plain = VerdictInputs(("elastic_unloading",), (r,), None, empty)
    assert decide(plain).status == "missing_effect"
    assert best_candidate_statement(plain).startswith("elastic_unloading is the answer")
    flagged = VerdictInputs(("elastic_unloading",), (r,), None, empty, force_left=(left,))
    v = decide(flagged)
    assert v.status == "partially_explained" and v.added == ("elastic_unloading",)
    assert ("The foot force while the sole sinks is not what elastic_unloading produces"
            in v.text)
    assert ("holds a vertical force of 9.5 N RMS (the feature library; data without a missing "
            "foot force < 5 N), it produces 0.8 N RMS there") in v.text
    best = best_candidate_statement(flagged)
    assert best.startswith("elastic_unloading is only the closest proxy")


def test_data_without_a_missing_foot_force_leave_nothing_after_any_addition(workbench_data):
    """On the null workbench data set (the model's own plant) the equation error holds no
    missing foot force, neither on the calibrated model nor beside an added elastic
    unloading (which acts only while the sole rises)."""
    from granular_mpc.validation.diagnosis.problem import load_problem

    problem = load_problem(workbench_data("null"))
    theta = {"zeta": 1.36}
    info = effect_info("elastic_unloading")
    assert force_leftover(problem, theta, [], seed=0) == ()
    assert force_leftover(problem, theta, [(info, info.resolve_params({}))], seed=0) == ()
