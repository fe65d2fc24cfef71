"""Cost of transport: closed-form integrals, distance, cumulative CoT, weight estimate."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import trapezoid

from granular_mpc.analysis import (CotResult, cot_from_arrays, cot_from_log, cumulative_cot,
                                   estimate_weight_from_grf, mechanical_power,
                                   segment_stances, stance_cumulative_cot)
from synthetic_log import JOINTS, MASS, G, make_log

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
