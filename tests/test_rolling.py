"""Foot rolling: rolling disc, pure slide, sign convention, plateau detection."""
from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.analysis import (detect_plateau, plateau_by_stance, rolling_from_arrays,
                                   rolling_from_log, segment_stances)
from synthetic_log import ROLL_TOTAL, make_contact_log, make_log, ramp_plateau_ramp

R_DISC = 0.0413  # m


def _rolling_disc(t, s):
    """A disc of radius R rolling forward without slip by arc length s(t): its lowest point
    moves by s, its pitch ψ_c decreases by s/R (rotation about +y)."""
    psi0 = 0.2
    return psi0 - s / R_DISC, s, np.zeros_like(s)


def test_pure_rolling_disc_has_reff_equal_radius():
    rng = np.random.default_rng(1)
    t = np.sort(np.concatenate(([0.0, 0.2], rng.uniform(0.0, 0.2, 300))))  # non-uniform
    s = 0.05 * t + 0.8 * t ** 2                 # accelerating roll, arc length [m]
    psi, xs, zs = _rolling_disc(t, s)
    df = rolling_from_arrays(t, psi, xs, zs)
    # ṡ ≥ 0.05 m/s, so |θ̇_r| = ṡ/R ≥ 1.2 rad/s, above min_rate (0.05 rad/s) everywhere:
    # R_eff is defined at every sample
    assert np.isfinite(df.r_eff).all()
    # R_eff = ẋ_s/|θ̇_r| with both rates differentiated by the same scheme from x_s = s and
    # ψ_c = ψ0 − s/R: the ratio is R up to round-off of the differences on the random grid
    # (measured 6.5e-11 relative)
    assert np.allclose(df.r_eff, R_DISC, rtol=1e-8)
    # Δθ_r starts at 0 and is negative (paper Fig. 6a: decreasing) for forward rolling
    assert df.dtheta_r.iloc[0] == 0.0
    assert np.allclose(df.dtheta_r, -s / R_DISC)
    assert (df.dtheta_r.iloc[1:] < 0).all()
    assert np.all(df.dtheta_r_rate <= 0)


def test_pure_sliding_without_rotation_gives_nan():
    t = np.linspace(0.0, 0.2, 101)
    df = rolling_from_arrays(t, np.full_like(t, 0.1), 0.3 * t, 0.02 * t)
    assert np.allclose(df.dtheta_r_rate, 0.0)
    assert np.allclose(df.v_s, np.hypot(0.3, 0.02))
    assert df.r_eff.isna().all()                # R_eff → ∞ is reported as NaN


def test_min_rate_guard_and_lateral_speed():
    t = np.linspace(0.0, 1.0, 201)
    psi = -0.5 * t ** 2                          # θ̇_r = −t: below 0.05 rad/s for t < 0.05
    xs, zs, ys = 0.1 * t, 0.0 * t, 0.1 * t
    df = rolling_from_arrays(t, psi, xs, zs, min_rate=0.05)
    slow = np.abs(df.dtheta_r_rate) < 0.05
    assert slow.any() and df.r_eff[slow].isna().all() and df.r_eff[~slow].notna().all()
    fast = ~slow
    assert np.allclose(df.r_eff[fast], 0.1 / t[fast.to_numpy()], rtol=1e-6)
    df3 = rolling_from_arrays(t, psi, xs, zs, intrusion_y=ys, min_rate=0.05)
    assert np.allclose(df3.r_eff[fast], np.sqrt(2) * df.r_eff[fast])
    assert np.allclose(df3.vs_y, 0.1)
    with pytest.raises(ValueError):
        rolling_from_arrays(t, psi[:-1], xs, zs)


def test_rolling_from_log_uses_the_stance_foot():
    L = make_log(4)
    log = L.df
    roll = rolling_from_log(log)
    segs = segment_stances(log)
    assert sorted(roll.stance_id.unique()) == list(segs.stance_id)
    for (side, a, b), sid in zip(L.segments, segs.stance_id):
        r = roll[roll.stance_id == sid]
        pitch = log[f"{side}_pitch"].to_numpy()[a:b]
        assert (r.side == side).all()
        assert np.allclose(r.dtheta_r, pitch - pitch[0])
        assert r.dtheta_r.iloc[-1] == pytest.approx(-ROLL_TOTAL)
        assert r.phase_pct.iloc[0] == 0.0 and r.phase_pct.iloc[-1] == pytest.approx(100.0)
        # the synthetic foot rolls with radius 0.06 m plus a small slip; during the
        # plateau θ̇_r ≈ 0, so R_eff is NaN there
        mid = (r.phase_pct > 45) & (r.phase_pct < 65)
        assert r.r_eff[mid].isna().all()
        early = (r.phase_pct > 5) & (r.phase_pct < 35)
        assert np.all(r.r_eff[early] > 0.06)


def test_plateau_ramp_plateau_ramp():
    phase = np.linspace(0.0, 100.0, 101)
    t = phase / 100.0 * 0.2
    theta = -0.4 * ramp_plateau_ramp(phase / 100.0, 0.4, 0.7)
    rate = np.gradient(theta, t)
    res = detect_plateau(phase, rate)
    assert res.has_plateau and len(res.intervals) == 1
    lo, hi = res.intervals[0]
    assert lo == pytest.approx(40.0, abs=1.0) and hi == pytest.approx(70.0, abs=1.0)
    assert res.onset_pct == pytest.approx(40.0, abs=1.0)
    assert res.fraction == pytest.approx(0.30, abs=0.015)
    # exactly: the central differences at the corner samples 40 and 70 see half the ramp
    # rate, so samples 41..69 are below threshold; their cells span 40.5 … 69.5 %
    assert (lo, hi) == pytest.approx((40.5, 69.5), abs=1e-9)
    assert res.fraction == pytest.approx(0.29, abs=1e-9)


def test_no_plateau_on_a_steady_roll_and_short_dips_ignored():
    phase = np.linspace(0.0, 100.0, 201)
    rate = np.full_like(phase, -2.0)
    res = detect_plateau(phase, rate)
    assert res.fraction == 0.0 and not res.has_plateau and np.isnan(res.onset_pct)
    dip = rate.copy()
    dip[(phase > 50) & (phase < 52)] = 0.0        # the rate crosses zero briefly
    assert detect_plateau(phase, dip, min_duration_pct=5.0).fraction == 0.0
    assert detect_plateau(phase, dip, min_duration_pct=1.0).fraction > 0.0
    # explicit absolute threshold
    assert detect_plateau(phase, rate, threshold=2.5).fraction == pytest.approx(1.0)


def test_plateau_by_stance_on_synthetic_log():
    roll = rolling_from_log(make_log(4).df)
    tab = plateau_by_stance(roll)
    assert len(tab) == 4
    # the synthetic stance (101 rows) has the ramp–plateau–ramp of
    # test_plateau_ramp_plateau_ramp: plateau 40–70 % found as 40.5–69.5 % exactly
    assert np.allclose(tab.onset_pct, 40.5, atol=1e-9)
    assert np.allclose(tab.fraction, 0.29, atol=1e-9)
    assert (tab.n_plateaus == 1).all()


def test_rolling_from_log_measures_from_touchdown():
    L = make_contact_log(4, early=5, late=3)
    log = L.df
    roll = rolling_from_log(log)                       # default: contact stances
    assert (roll.stance_source == "contact").all()
    assert sorted(roll.stance_id.unique()) == [0, 1, 2, 3]
    for k, (side, a, b) in enumerate(L.contact):
        r = roll[roll.stance_id == k]
        pitch = log[f"{side}_pitch"].to_numpy()[a:b]
        assert (r.side == side).all() and len(r) == b - a
        assert np.allclose(r.dtheta_r, pitch - pitch[0])        # Δθ_r from touchdown
        assert np.allclose(r.time, log.time.to_numpy()[a:b])
    planned = rolling_from_log(log, segments=segment_stances(log))
    assert (planned.stance_source == "planned").all()
    assert len(planned) == sum(b - a for _, a, b in L.planned)
    tab = plateau_by_stance(roll)
    assert (tab.stance_source == "contact").all() and len(tab) == 4
