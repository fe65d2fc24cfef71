"""Cost of transport: closed-form integrals, distance, cumulative CoT, weight estimate.

Tolerances: rel 1e-12 where the code and the reference take the same trapezoid sums
(round-off only); rel 1e-8 against closed-form integrals of smooth periodic power over
whole periods on 200 001 samples (the trapezoid rule is exact to round-off there); rel 1e-6
for ∫|P| and ∫max(P, 0), whose kinks at the 20 zero crossings cost O(h²) each
(h = 1e-5 s: ≈ 1e-9 relative in all).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import trapezoid

from granular_mpc.analysis import (COT_READINGS, DEFAULT_COT_READING, CotReadings, CotResult,
                                   contact_segments, cot_decoupled, cot_decoupled_readings,
                                   cot_from_arrays, cot_from_log, cot_readings_from_arrays,
                                   cot_readings_from_log, cumulative_cot, decoupled_joint_power,
                                   decoupled_power, estimate_weight_from_grf, mechanical_power,
                                   reading_mode, segment_stances, stance_cumulative_cot)
from synthetic_log import JOINTS, MASS, G, make_contact_log, make_log

A, B, OMEGA = 3.0, 2.0, 2 * np.pi * 2.5      # N·m, rad/s, rad/s
T = 2.0                                      # s: 5 full periods of ω
W = MASS * G


def _t(n=200001):
    return np.linspace(0.0, T, n)


def test_in_phase_signals_energy_closed_form():
    # τ = A sin ωt, q̇ = B sin ωt → P = AB sin² ωt ≥ 0, E = AB (T/2 − sin 2ωT / 4ω)
    t = _t()
    tau, dq = A * np.sin(OMEGA * t), B * np.sin(OMEGA * t)
    e_true = A * B * (T / 2 - np.sin(2 * OMEGA * T) / (4 * OMEGA))
    v = np.full_like(t, 0.3)                                    # constant speed
    res = cot_from_arrays(t, tau, dq, v, W)
    assert isinstance(res, CotResult)
    assert res.energy_J == pytest.approx(e_true, rel=1e-8)
    assert res.distance_m == pytest.approx(0.3 * T, rel=1e-12)  # d = v T
    assert res.cot == pytest.approx(e_true / (W * 0.3 * T), rel=1e-8)
    # all power positive: every mode agrees
    for mode in ("positive", "abs_joint", "positive_joint"):
        assert cot_from_arrays(t, tau, dq, v, W, mode=mode).energy_J == pytest.approx(e_true, rel=1e-8)


def test_quadrature_signals_abs_and_positive_work():
    # τ = A sin ωt, q̇ = B cos ωt → P = (AB/2) sin 2ωt; over whole periods
    # ∫|P| = AB T / π and ∫max(P, 0) = AB T / (2π)
    t = _t()
    tau, dq = A * np.sin(OMEGA * t), B * np.cos(OMEGA * t)
    v = np.full_like(t, 0.5)
    e_abs = cot_from_arrays(t, tau, dq, v, W, mode="abs").energy_J
    e_pos = cot_from_arrays(t, tau, dq, v, W, mode="positive").energy_J
    assert e_abs == pytest.approx(A * B * T / np.pi, rel=1e-6)
    assert e_pos == pytest.approx(A * B * T / (2 * np.pi), rel=1e-6)


def test_net_versus_per_joint_power():
    # two joints with opposite powers: the net power is 0, the per-joint sum is not
    t = _t(20001)
    tau = np.column_stack([A * np.sin(OMEGA * t), -A * np.sin(OMEGA * t)])
    dq = np.column_stack([B * np.sin(OMEGA * t), B * np.sin(OMEGA * t)])
    assert np.allclose(mechanical_power(tau, dq, "abs"), 0.0)
    p_joint = mechanical_power(tau, dq, "abs_joint")
    assert np.allclose(p_joint, 2 * A * B * np.sin(OMEGA * t) ** 2)
    assert np.allclose(mechanical_power(tau, dq, "positive_joint"), A * B * np.sin(OMEGA * t) ** 2)


def test_undefined_and_bad_inputs():
    t = _t(1001)
    tau = dq = np.ones_like(t)
    assert np.isnan(cot_from_arrays(t, tau, dq, np.zeros_like(t), W).cot)     # no progress
    assert np.isnan(cot_from_arrays(t, tau, dq, -np.ones_like(t), W).cot)     # backwards
    with pytest.raises(ValueError):
        mechanical_power(tau, dq, "bogus")
    with pytest.raises(ValueError):
        cot_from_arrays(t, tau, dq, np.ones_like(t), 0.0)
    with pytest.raises(ValueError):
        cot_from_arrays(t[::-1], tau, dq, np.ones_like(t), W)
    with pytest.raises(ValueError):
        cot_from_arrays(t, tau[:-1], dq, np.ones_like(t), W)


def test_cumulative_cot_end_value_and_shape():
    t = np.linspace(0.0, 0.2, 401)
    tau, dq = A * np.sin(OMEGA * t + 0.3), B * np.cos(3 * OMEGA * t)
    v = 0.2 + 0.05 * np.sin(2 * np.pi * t / 0.2)
    whole = cot_from_arrays(t, tau, dq, v, W)
    p = mechanical_power(tau, dq)
    running = cumulative_cot(t, p, v, W, normalise="running", min_distance_frac=0.05)
    final = cumulative_cot(t, p, v, W, normalise="final")
    assert running[-1] == pytest.approx(whole.cot, rel=1e-12)
    assert final[-1] == pytest.approx(whole.cot, rel=1e-12)
    # "final" grows from 0 monotonically (power ≥ 0), "running" is NaN until 5 % of d
    assert final[0] == 0.0 and np.all(np.diff(final) >= -1e-15)
    d = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))))
    assert np.all(np.isnan(running[d < 0.05 * d[-1]]))
    assert np.all(np.isfinite(running[d >= 0.05 * d[-1]]))
    # independent check of one interior value
    k = 250
    e_k = trapezoid(p[: k + 1], t[: k + 1])
    assert running[k] == pytest.approx(e_k / (W * d[k]), rel=1e-10)
    with pytest.raises(ValueError):
        cumulative_cot(t, p, v, W, normalise="bogus")
    assert np.all(np.isnan(cumulative_cot(t, p, -v, W)))


def test_cot_from_log_matches_arrays_and_window():
    log = make_log(6).df
    tau = log[[f"tau_{j}" for j in JOINTS]].to_numpy()
    dq = log[[f"dq_{j}" for j in JOINTS]].to_numpy()
    ref = cot_from_arrays(log.time.to_numpy(), tau, dq, log.com_vx.to_numpy(), W)
    got = cot_from_log(log, weight=W)
    assert got.cot == pytest.approx(ref.cot, rel=1e-12)
    assert got.energy_J == pytest.approx(ref.energy_J, rel=1e-12)
    win = cot_from_log(log, weight=W, t_start=0.2, t_end=0.6)
    sel = (log.time >= 0.2) & (log.time <= 0.6)
    ref_w = cot_from_arrays(log.time[sel].to_numpy(), tau[sel], dq[sel], log.com_vx[sel].to_numpy(), W)
    assert win.cot == pytest.approx(ref_w.cot, rel=1e-12)
    assert win.duration_s == pytest.approx(0.4, abs=1e-9)
    with pytest.raises(ValueError, match="weight"):
        cot_from_log(log)


def test_cot_from_log_with_robot_model(biped):
    log = make_log(4).df
    res = cot_from_log(log, biped=biped)
    assert res.weight_N == pytest.approx(biped.weight)
    assert res.cot == pytest.approx(cot_from_log(log, weight=biped.weight).cot)


def test_stance_cumulative_cot_ends_at_whole_stance_cot():
    log = make_log(6).df
    segs = segment_stances(log)
    cum = stance_cumulative_cot(log, weight=W, segments=segs)
    final = stance_cumulative_cot(log, weight=W, segments=segs, normalise="final")
    for seg in segs.itertuples():
        part = log.iloc[seg.row_start:seg.row_stop]
        whole = cot_from_log(part, weight=W)
        c = cum[cum.stance_id == seg.stance_id]
        f = final[final.stance_id == seg.stance_id]
        assert c.cot_cum.iloc[-1] == pytest.approx(whole.cot, rel=1e-12)
        assert f.cot_cum.iloc[-1] == pytest.approx(whole.cot, rel=1e-12)
        assert c.energy_J.iloc[-1] == pytest.approx(whole.energy_J, rel=1e-12)
        assert c.phase_pct.iloc[0] == 0.0 and c.phase_pct.iloc[-1] == pytest.approx(100.0)


def test_weight_from_vertical_impulse_balance():
    log = make_log(6).df
    assert estimate_weight_from_grf(log) == pytest.approx(MASS * G, rel=1e-9)
    # without per-foot columns the v1 grf_z is used (same here: no double stance)
    v1 = log.drop(columns=["left_grf_z", "right_grf_z"])
    assert estimate_weight_from_grf(v1) == pytest.approx(MASS * G, rel=1e-9)


# --------------------------------------------------------------------------- readings
def _const(values, n):
    return np.tile(np.asarray(values, dtype=float), (n, 1))


@pytest.mark.parametrize("tau_row, dq_row, expect", [
    # p = (2·1.5, −3·0.5) = (3, −1.5) W: per joint |3|+|−1.5| = 4.5, net |1.5| = 1.5,
    # positive 3; W_net = 1.5 W · 2 s
    ((2.0, -3.0), (1.5, 0.5), {"abs_per_joint": 4.5, "abs_net": 1.5, "positive": 3.0,
                               "net": 1.5}),
    # p = (−2, 0.5) W: per joint 2.5, net |−1.5| = 1.5, positive 0.5 (abs_net > positive)
    ((-2.0, 0.25), (1.0, 2.0), {"abs_per_joint": 2.5, "abs_net": 1.5, "positive": 0.5,
                                "net": -1.5}),
])
def test_two_joint_readings_by_hand(tau_row, dq_row, expect):
    T2, v, m = 2.0, 0.5, 10.0                     # s, m/s, kg → d = 1 m, W_r = 98.1 N
    t = np.linspace(0.0, T2, 11)
    w = m * 9.81
    res = cot_readings_from_arrays(t, _const(tau_row, t.size), _const(dq_row, t.size),
                                   np.full(t.size, v), w)
    assert isinstance(res, CotReadings)
    for r in COT_READINGS:
        got = res.get(r)
        assert got.energy_J == pytest.approx(expect[r] * T2, rel=1e-12)
        assert got.distance_m == pytest.approx(1.0, rel=1e-12)
        assert got.cot == pytest.approx(expect[r] * T2 / (w * 1.0), rel=1e-12)
        assert got.mode == reading_mode(r)
    assert res.net_work_J == pytest.approx(expect["net"] * T2, rel=1e-12)
    assert res.default is res.abs_per_joint and DEFAULT_COT_READING == "abs_per_joint"
    assert res.cots() == {r: res.get(r).cot for r in COT_READINGS}


def test_lifting_a_mass_positive_work_is_mgh():
    # a joint winds a rope on a drum of radius r and lifts a load m from rest to rest with
    # speed v(t) = v_max sin²(πt/T): τ = m r (g + a), q̇ = v / r, so ∫ τ q̇ dt = m g h
    # (the kinetic energy returns to 0) with h = v_max T / 2
    m, r, v_max, T_lift = 2.0, 0.05, 0.2, 3.0
    t = np.linspace(0.0, T_lift, 300001)
    v = v_max * np.sin(np.pi * t / T_lift) ** 2
    a = v_max * np.pi / T_lift * np.sin(2 * np.pi * t / T_lift)
    tau, dq = m * r * (G + a), v / r
    h = v_max * T_lift / 2
    walk = np.full_like(t, 0.1)
    up = cot_readings_from_arrays(t, tau, dq, walk, W)
    for rd in COT_READINGS:                      # all power positive: every reading = m g h
        assert up.get(rd).energy_J == pytest.approx(m * G * h, rel=1e-8)
    # lowering it again the same way: the motor brakes (negative work)
    down = cot_readings_from_arrays(t, m * r * (G - a), -dq, walk, W)
    assert down.positive.energy_J == pytest.approx(0.0, abs=1e-12)
    assert down.abs_per_joint.energy_J == pytest.approx(m * G * h, rel=1e-8)
    assert down.net_work_J == pytest.approx(-m * G * h, rel=1e-8)
    # the round trip: net work 0, positive m g h, motor (per joint) 2 m g h
    tt = np.concatenate([t, T_lift + t[1:]])
    both = cot_readings_from_arrays(tt, np.concatenate([tau, m * r * (G - a)[1:]]),
                                    np.concatenate([dq, -dq[1:]]), np.full_like(tt, 0.1), W)
    assert both.net_work_J == pytest.approx(0.0, abs=1e-6)
    assert both.positive.energy_J == pytest.approx(m * G * h, rel=1e-8)
    assert both.abs_per_joint.energy_J == pytest.approx(2 * m * G * h, rel=1e-8)


def test_reading_ordering_and_identity_on_random_signals():
    rng = np.random.default_rng(4)
    t = np.sort(rng.uniform(0.0, 1.0, 400))
    tau, dq = rng.normal(size=(400, 6)), rng.normal(size=(400, 6))
    res = cot_readings_from_arrays(t, tau, dq, np.full(400, 0.3), W)
    e = {r: res.get(r).energy_J for r in COT_READINGS}
    assert e["abs_net"] <= e["abs_per_joint"]
    assert e["positive"] <= e["abs_per_joint"]
    assert e["abs_net"] >= abs(res.net_work_J)
    assert e["positive"] >= max(res.net_work_J, 0.0)
    # Σ|p| = 2 Σ max(p, 0) − Σ p holds sample by sample, hence for the trapezoid sums
    assert e["abs_per_joint"] == pytest.approx(2 * e["positive"] - res.net_work_J, rel=1e-12)
    # independent trapezoid of each reading's power
    p = tau * dq
    assert e["abs_per_joint"] == pytest.approx(trapezoid(np.abs(p).sum(1), t), rel=1e-12)
    assert e["abs_net"] == pytest.approx(trapezoid(np.abs(p.sum(1)), t), rel=1e-12)
    assert e["positive"] == pytest.approx(trapezoid(np.clip(p, 0, None).sum(1), t), rel=1e-12)
    with pytest.raises(ValueError, match="reading"):
        res.get("abs")


def test_readings_from_log_match_the_power_modes():
    log = make_log(6).df
    res = cot_readings_from_log(log, weight=W, t_start=0.1, t_end=1.0)
    for r in COT_READINGS:
        ref = cot_from_log(log, weight=W, mode=reading_mode(r), t_start=0.1, t_end=1.0)
        assert res.get(r).cot == pytest.approx(ref.cot, rel=1e-12)
    # the literal reading is what cot_from_log computes by default
    assert res.abs_net.cot == pytest.approx(cot_from_log(log, weight=W, t_start=0.1,
                                                         t_end=1.0).cot, rel=1e-12)
    half = cot_readings_from_log(log, weight=W, distance=2 * res.abs_net.distance_m,
                                 t_start=0.1, t_end=1.0)
    assert half.abs_per_joint.cot == pytest.approx(res.abs_per_joint.cot / 2, rel=1e-12)


# --------------------------------------------------------------------------- decoupled readings
def _decoupled_inputs(n=300, seed=2):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 0.6, n)
    q = rng.normal(0.0, 0.3, (n, 6))
    dq, tau = rng.normal(size=(n, 6)), rng.normal(size=(n, 6))
    pitch, roll = 0.05 * np.sin(8 * t), 0.03 * np.cos(5 * t)
    side = np.where(t < 0.3, "left", "right")
    return t, q, dq, tau, pitch, roll, side


def test_decoupled_readings_exact_actuation():
    t, q, dq, tau, pitch, roll, side = _decoupled_inputs()
    d = 0.12
    dec = cot_decoupled_readings(t, q, dq, tau, pitch, roll, side, W, d)
    full = cot_readings_from_arrays(t, tau, dq, np.full_like(t, d / 0.6), W, distance=d)
    # exact B: each joint's share is its own τ_j q̇_j, so per-joint readings coincide
    assert dec.abs_per_joint == pytest.approx(full.abs_per_joint.cot, rel=1e-9)
    assert dec.positive == pytest.approx(full.positive.cot, rel=1e-9)
    # |P_s| + |P_f| lies between |P_s + P_f| and Σ|p_j|
    assert full.abs_net.cot <= dec.abs_net <= dec.abs_per_joint
    assert dec.abs_net == pytest.approx(cot_decoupled(t, q, dq, tau, pitch, roll, side, W, d),
                                        rel=1e-12)
    assert dec.get("abs_per_joint") == pytest.approx(
        cot_decoupled(t, q, dq, tau, pitch, roll, side, W, d, reading="abs_per_joint"), rel=1e-12)
    assert [e.reading for e in dec.energies] == list(COT_READINGS)
    assert np.isnan(cot_decoupled_readings(t, q, dq, tau, pitch, roll, side, W, 0.0).abs_net)


def test_decoupled_joint_shares_paper_actuation_by_hand():
    t, q, dq, tau, pitch, roll, _ = _decoupled_inputs()
    dpitch, droll = np.gradient(pitch, t), np.gradient(roll, t)
    p_s, p_f = decoupled_joint_power(q, dq, tau, dpitch, droll, "left", actuation="paper")
    P_s, P_f = decoupled_power(q, dq, tau, dpitch, droll, "left", actuation="paper")
    assert np.allclose(p_s.sum(1), P_s) and np.allclose(p_f.sum(1), P_f)
    # left stance, +y/+x axes: hip pitch q = θ_thigh − θ_b, so the pitch motors work on the
    # absolute thigh rate q̇ + θ̇_b; knees unchanged; stance abduction q = q1f − q2f with
    # q2f the hip line (= trunk roll) and the stance leg's torque dropped: −τ θ̇_roll
    for j in (1, 4):
        assert np.allclose(p_s[:, j], tau[:, j] * (dq[:, j] + dpitch))
    for j in (2, 5):
        assert np.allclose(p_s[:, j], tau[:, j] * dq[:, j])
    assert np.allclose(p_s[:, [0, 3]], 0.0) and np.allclose(p_f[:, [1, 2, 4, 5]], 0.0)
    assert np.allclose(p_f[:, 0], -tau[:, 0] * droll)
    assert np.allclose(p_f[:, 3], tau[:, 3] * dq[:, 3])


# --------------------------------------------------------------------------- contact stances
def test_stance_cumulative_cot_uses_contact_stances():
    L = make_contact_log(4)
    cum = stance_cumulative_cot(L.df, weight=W)
    assert (cum.stance_source == "contact").all()
    segs = contact_segments(L.df)
    assert [(r.side, r.row_start, r.row_stop) for r in segs.itertuples()] == L.contact
    for seg in segs.itertuples():
        c = cum[cum.stance_id == seg.stance_id]
        whole = cot_from_log(L.df.iloc[seg.row_start:seg.row_stop], weight=W)
        assert len(c) == seg.row_stop - seg.row_start
        assert c.energy_J.iloc[-1] == pytest.approx(whole.energy_J, rel=1e-12)
    planned = stance_cumulative_cot(L.df, weight=W, segments=segment_stances(L.df))
    assert (planned.stance_source == "planned").all()
    assert len(planned) == sum(b - a for _, a, b in L.planned)
