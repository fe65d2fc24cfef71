"""Whether the measured joint torques hold a joint term (``validation.diagnosis.torque_evidence``):
on constructed equation-error rows whose content is written out by hand (the term's own
torque, noise, a sliver of a large torque), on the real rows of the workbench's null data
set with and without the term's torque added, and inside the acceptance (``judge``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from granular_mpc.effects import effect_info, joint_torque_function
from granular_mpc.validation.dataformat import load_dataset
from granular_mpc.validation.diagnosis import judge
from granular_mpc.validation.diagnosis.problem import load_problem
from granular_mpc.validation.diagnosis.joint_proposal import JointSamples, equation_rows
from granular_mpc.validation.diagnosis.torque_evidence import MIN_REACH, torque_evidence

FRICTION = {"coulomb": 0.1, "viscous": 0.02}


def _rows(error_of, n_units=24, per_unit=60, seed=0) -> JointSamples:
    """Rows of 6 joints in ``n_units`` stance segments, the left leg (joints 0–2) in stance
    in the even ones; q, q̇ a swing-like motion; ``error_of(q, dq, rng)`` → (N, 6)."""
    rng = np.random.default_rng(seed)
    n = n_units * per_unit
    t = np.arange(n) / 500.0
    phase = rng.uniform(0, 2 * np.pi, 6)
    q = 0.4 * np.sin(2 * np.pi * 2.5 * t[:, None] + phase)
    dq = 0.4 * 2 * np.pi * 2.5 * np.cos(2 * np.pi * 2.5 * t[:, None] + phase)
    unit = np.repeat(np.arange(n_units), per_unit)
    left = (unit % 2 == 0).astype(float)
    stance = np.column_stack([left] * 3 + [1.0 - left] * 3)
    return JointSamples(error_of(q, dq, rng), q, dq, np.zeros_like(q), stance,
                        np.full(n, 100.0), np.full(n, "t1"),
                        np.array([f"t1|{u}" for u in unit]))


def _term_torque(q, dq, params=FRICTION):
    info = effect_info("joint_friction")
    p = info.neutral_params()
    p.update(params)
    fn = joint_torque_function([(info, p)])
    return np.vstack([fn(q[i], dq[i]) for i in range(q.shape[0])])


def test_a_term_in_the_torques_is_held():
    rows = _rows(lambda q, dq, rng: _term_torque(q, dq) + rng.normal(0, 0.1, q.shape))
    ev = torque_evidence(rows, effect_info("joint_friction"), FRICTION)
    assert ev.held_share == pytest.approx(1.0, abs=0.08)
    assert ev.ci[0] < ev.held_share < ev.ci[1] and ev.ci[1] >= MIN_REACH
    assert ev.holds
    # swing rows only: half the rows of each joint, every stance segment
    assert ev.n_rows == rows.n * 6 // 2 and ev.n_stances == 24
    swing = rows.stance_leg < 0.5
    assert ev.rms_torque == pytest.approx(
        float(np.sqrt(np.mean(_term_torque(rows.q, rows.dq)[swing] ** 2))))


def test_a_term_the_torques_do_not_hold_is_refused():
    # noise only: the share is ~0, its interval far below one half
    rows = _rows(lambda q, dq, rng: rng.normal(0, 0.1, q.shape))
    ev = torque_evidence(rows, effect_info("joint_friction"), FRICTION)
    assert abs(ev.held_share) < 0.05 and ev.ci[1] < MIN_REACH and not ev.holds
    assert "hold less than 50 % of its torque" in ev.text()
    # a sliver of a large torque (a friction standing in for a sensor gain): the interval
    # lies above 0 but below one half
    big = {"coulomb": 0.8, "viscous": 0.1}
    rows = _rows(lambda q, dq, rng: 0.05 * _term_torque(q, dq, big)
                 + rng.normal(0, 0.02, q.shape))
    ev = torque_evidence(rows, effect_info("joint_friction"), big)
    assert ev.ci[0] > 0.0 and ev.ci[1] < MIN_REACH and not ev.holds


def test_a_term_too_small_for_the_torques_to_judge_is_not_refused():
    """A small term in more noise, really there: its interval is wide, reaches 0 and ½ —
    no evidence against it (a weak stiction of the robot looked like this)."""
    small = {"coulomb": 0.002, "viscous": 0.0004}
    rows = _rows(lambda q, dq, rng: _term_torque(q, dq, small) + rng.normal(0, 0.3, q.shape),
                 n_units=12)
    ev = torque_evidence(rows, effect_info("joint_friction"), small)
    assert ev.ci[0] <= 0.0 and ev.ci[1] >= MIN_REACH and ev.holds


def test_only_joint_terms_with_rows_and_torque_are_tested():
    rows = _rows(lambda q, dq, rng: rng.normal(0, 0.1, q.shape))
    assert torque_evidence(None, effect_info("joint_friction"), FRICTION) is None
    assert torque_evidence(rows, effect_info("cohesion"), {"suction": 2000.0}) is None
    assert torque_evidence(rows, effect_info("joint_friction"),
                           {"coulomb": 0.0, "viscous": 0.0}) is None
    stance_only = dataclasses.replace(rows, stance_leg=np.ones_like(rows.stance_leg))
    assert torque_evidence(stance_only, effect_info("joint_friction"), FRICTION) is None


def test_real_rows_of_null_data(workbench_data):
    """The workbench's null data set (no joint effect in its plant): a small joint friction
    is not held; the same rows with that friction's torque added to the equation error —
    what a friction of the robot would put there — hold it."""
    data = workbench_data("null")
    problem = load_problem(data)
    rows = equation_rows(load_dataset(data), problem.biped, problem.sample_rate_hz)
    small = {"coulomb": 0.03, "viscous": 0.005}
    info = effect_info("joint_friction")
    ev = torque_evidence(rows, info, small)
    assert not ev.holds
    real = dataclasses.replace(rows, error=rows.error + _term_torque(rows.q, rows.dq, small))
    held = torque_evidence(real, info, small)
    assert held.holds and held.held_share == pytest.approx(1.0 + ev.held_share, abs=1e-9)


def test_the_acceptance_refuses_a_term_the_torques_do_not_hold():
    from types import SimpleNamespace

    rng = np.random.default_rng(1)
    ws, before, after = [], [], []
    for _ in range(6):
        meas = {"q_a": rng.normal(0, 0.01, 40)}
        ws.append(SimpleNamespace(meas=meas))
        before.append({"q_a": meas["q_a"] + 0.05})
        after.append({"q_a": meas["q_a"] + 0.01})
    info = effect_info("joint_friction")
    noise = _rows(lambda q, dq, rng: rng.normal(0, 0.1, q.shape))
    held = _rows(lambda q, dq, rng: _term_torque(q, dq) + rng.normal(0, 0.1, q.shape))
    args = (ws, ["q_a"], {"q_a": 0.01}, info, FRICTION, before, after)
    assert judge(*args).accepted and judge(*args).torque is None
    ok = judge(*args, torque_evidence(held, info, FRICTION))
    assert ok.accepted and ok.torque.holds
    refused = judge(*args, torque_evidence(noise, info, FRICTION))
    assert not refused.accepted and "hold less than 50 % of its torque" in refused.reasons[-1]
    assert refused.to_dict()["torque"]["n_stances"] == 24
    # diagnosis.json round trip; no key without a test
    from granular_mpc.validation.diagnosis.acceptance_records import Acceptance

    assert Acceptance.from_dict(refused.to_dict()).torque == refused.torque
    assert "torque" not in judge(*args).to_dict()
