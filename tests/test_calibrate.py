"""Terrain calibration on equation-error residuals (granular_mpc.validation.calibrate).

Synthetic stance windows are built by hand: at each sample the stance foot sinks at a
chosen depth, pitch and direction of motion u, and the "measured" vertical force is the
package's closed-form RFT force (``TerrainModel.foot_forces``) of a terrain with KNOWN ζ
and φ_s, different from the model's. The measured contact-point velocity is
v = u + F/(n K τ) (what the calibration inverts), so a noise-free fit must return the
generating ζ, φ_s up to the optimiser's tolerance.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from granular_mpc.config import load_terrain
from granular_mpc.terrain import build_terrain
from granular_mpc.validation.calibrate import (CAL_PARAMS, Calibration, calibrate,
                                               sinking_samples)
from granular_mpc.validation.prepare import StanceWindow

N_SLICES = 3
TRUE_ZETA, TRUE_PHI_DEG = 1.6, 33.0        # the model file (dry_sand) has 1.36 and 38°


@pytest.fixture(scope="module")
def truth(robot_config):
    return build_terrain(load_terrain("dry_sand", zeta=TRUE_ZETA, phi_s_deg=TRUE_PHI_DEG),
                         robot_config)


def make_windows(terrain, rng, *, n_windows=6, n=40, noise=0.0, n_trials=3,
                 depths=None, single_point=False, gamma_lo=55.0):
    """Sinking stance windows whose F_z comes from ``terrain``'s force law (+ noise [N])."""
    cfg = terrain.config
    nkt = N_SLICES * cfg.contact_stiffness * cfg.direction_time_constant
    out = []
    for w in range(n_windows):
        if single_point:
            depth = np.full(n, 0.02)
            pitch = np.full(n, 0.05)
            gam = np.full(n, math.radians(70.0))
        else:
            depth = np.linspace(0.004, 0.03, n) if depths is None else depths
            pitch = rng.uniform(-0.2, 0.2, n)
            # flow direction below horizontal: steep by default (a sinking stance foot),
            # clear of the φ_s bounds 25–50° where the force jumps (see the xfail below)
            gam = rng.uniform(math.radians(gamma_lo), math.radians(90.0), n)
        speed = rng.uniform(0.1, 0.5, n)
        u_h, u_z = speed * np.cos(gam), -speed * np.sin(gam)
        f = [terrain.foot_forces(d, p, uh, uz) for d, p, uh, uz in zip(depth, pitch, u_h, u_z)]
        f_h = np.array([r.f_h for r in f])
        f_z = np.array([r.f_z for r in f]) + noise * rng.normal(size=n)
        feats = {"depth": depth, "pitch": pitch, "sink_velocity": -u_z + 0.3,
                 "grf_z": f_z, "heading_x": np.ones(n), "heading_y": np.zeros(n),
                 "v_h": u_h + f_h / nkt, "vc_z": u_z + f_z / nkt}
        meas = {"grf_x": f_h, "grf_y": np.zeros(n), "grf_z": f_z}
        out.append(StanceWindow(
            index=w, trial=f"trial{w % n_trials}", speed=0.2, side="left", foot=0,
            row_start=0, row_stop=n, time=np.arange(n) * 0.002, phase=np.linspace(0, 100, n),
            q0=np.zeros(13), v0=np.zeros(12), tau=np.zeros((n, 6)), feet=(None, None),
            origin=np.zeros(3), touchdown_W=np.zeros(3), meas=meas, features=feats))
    return out


def test_noise_free_fit_recovers_the_generating_parameters(sand, truth):
    windows = make_windows(truth, np.random.default_rng(0))
    cal = calibrate(windows, sand, n_slices=N_SLICES, n_boot=20)
    # least_squares' default xtol/ftol 1e-8 on a zero-residual problem: measured error
    # < 1e-9; bound 1e-6 (relative ζ, radians φ_s)
    assert cal.values["zeta"] == pytest.approx(TRUE_ZETA, rel=1e-6)
    assert cal.values["phi_s"] == pytest.approx(math.radians(TRUE_PHI_DEG), abs=1e-6)
    assert cal.initial["zeta"] == pytest.approx(1.36) and cal.initial["phi_s"] == pytest.approx(
        math.radians(38.0))
    assert cal.n_samples == 6 * 40 and cal.n_stances == 6
    assert cal.rmse_before > 5.0 and cal.rmse_after < 1e-6 * cal.rmse_before
    assert cal.identified["zeta"] and cal.identified["phi_s"]
    # what sinking alone cannot see is flagged as such
    for p in ("bulldozing_length", "sole_shear_alpha", "added_mass_scale"):
        assert cal.identified[p] is False


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_noisy_fit_is_within_its_own_error_bars(sand, truth, seed):
    """σ = 3 N white noise on F_z (≈ 3 % of the weight carried): the estimate lies within 4
    of its Gauss–Newton standard errors of the truth (a 4σ bound: false alarm 6e-5 per
    seed if the errors are right; measured |error|/se ≤ 2.5 over seeds 11–20, which the
    assertions do not use), the error bars are small enough to call both parameters
    identified, and the intervals contain the estimate."""
    windows = make_windows(truth, np.random.default_rng(seed), noise=3.0)
    cal = calibrate(windows, sand, n_slices=N_SLICES, n_boot=50, seed=seed)
    for p, true in (("zeta", TRUE_ZETA), ("phi_s", math.radians(TRUE_PHI_DEG))):
        assert abs(cal.values[p] - true) < 4.0 * cal.se_gn[p], (p, cal.values[p], cal.se_gn[p])
        assert cal.identified[p]
        lo, hi = cal.ci_gn[p]
        assert lo < cal.values[p] < hi
        blo, bhi = cal.ci_boot[p]
        assert blo <= cal.values[p] <= bhi
    # the residual RMS is the noise level: σ·√((N − 2)/N) ± sampling spread (σ/√(2N) ≈
    # 5 % at N = 240); measured 0.90–1.06 σ over seeds 11–20; bound ±20 %
    assert cal.rmse_after == pytest.approx(3.0, rel=0.2)


def test_too_few_sinking_samples_keep_the_model_values(sand, truth):
    """Fewer than 20 sinking samples: no fit, the model's values, nothing identified."""
    windows = make_windows(truth, np.random.default_rng(5), n_windows=1, n=15)
    cal = calibrate(windows, sand, n_slices=N_SLICES)
    assert cal.n_samples == 15
    assert cal.values == cal.initial
    assert cal.initial["zeta"] == pytest.approx(1.36)
    assert not any(cal.identified.values())
    assert "too few sinking samples" in cal.note
    assert cal.se_gn == {} and math.isnan(cal.rmse_after)


def test_samples_that_are_not_sinking_are_not_used(sand, truth):
    """sink_velocity ≤ 0.2 m/s, depth ≤ 2 mm or F_z ≤ 10 N: not in vertical flow."""
    windows = make_windows(truth, np.random.default_rng(6), n_windows=2, n=30)
    s = sinking_samples(windows)
    assert s["depth"].size == 60
    w = windows[0]
    w.features["sink_velocity"][:10] = 0.1
    w.features["depth"][10:15] = 0.001
    w.features["grf_z"][15:20] = 5.0
    s = sinking_samples(windows)
    assert s["depth"].size == 60 - 20
    # f_h is the measured force along the heading: rotate the heading by 90° and the
    # force that was along x becomes along y
    hx = w.features["heading_x"].copy()
    w.features["heading_x"], w.features["heading_y"] = np.zeros(30), hx
    w.meas["grf_x"], w.meas["grf_y"] = w.meas["grf_y"], w.meas["grf_x"]
    s2 = sinking_samples(windows)
    np.testing.assert_array_equal(s2["f_h"], s["f_h"])
    np.testing.assert_array_equal(s2["window"][:10], 0)
    assert set(s2["trial"]) == {"trial0", "trial1"}


def test_a_single_operating_point_does_not_identify_zeta_and_phi(sand, truth):
    """Every sample at the same depth, pitch and direction: F_z = ζ·g(φ_s) at one point
    cannot separate ζ from φ_s; the fit must say so rather than report an estimate."""
    windows = make_windows(truth, np.random.default_rng(7), single_point=True, noise=1.0)
    cal = calibrate(windows, sand, n_slices=N_SLICES, n_boot=0)
    assert cal.ci_boot["zeta"] == [None, None]          # n_boot = 0: no bootstrap interval
    assert not (cal.identified["zeta"] and cal.identified["phi_s"])
    assert not (cal.se_gn["zeta"] == 0.0 and cal.se_gn["phi_s"] == 0.0)


@pytest.mark.xfail(strict=True, reason=(
    "calibrate: the RFT force is discontinuous in φ_s where a sample's flow direction is "
    "parallel to a wedge face (a face is 'leading' or not), i.e. for flows 25°–50° below "
    "horizontal within the φ_s bounds. least_squares (local, gradient-based) then stops "
    "on a plateau: seed 14 with flows 30°–90° ends at RMS 5.23 N against 3.09 N at the "
    "generating (ζ, φ_s), φ_s off by 1.4° (2 of its own standard errors), yet flagged "
    "identified. Excluding samples whose flow angle lies within the φ_s bounds, or a "
    "1-D scan over φ_s before the local fit, would avoid it."))
def test_fit_reaches_the_least_squares_minimum_with_shallow_flows(sand, truth):
    """With flows from 30° below horizontal the fit must still end no worse than the
    generating parameters (whose RMS is the drawn noise)."""
    noisy = make_windows(truth, np.random.default_rng(14), noise=3.0, gamma_lo=30.0)
    clean = make_windows(truth, np.random.default_rng(14), noise=0.0, gamma_lo=30.0)
    keep = [w.features["grf_z"] > 10.0 for w in noisy]
    drawn = np.concatenate([(n.meas["grf_z"] - c.meas["grf_z"])[k]
                            for n, c, k in zip(noisy, clean, keep)])
    cal = calibrate(noisy, sand, n_slices=N_SLICES, n_boot=0)
    assert cal.rmse_after <= 1.01 * float(np.sqrt(np.mean(drawn ** 2)))


def test_a_parameter_listed_twice_is_not_identified(sand, truth):
    """Two identical Jacobian columns: JᵀJ is singular up to round-off, the Gauss–Newton
    errors blow up (measured se 1.2e6 against ζ ≈ 1.6) and ζ is not identified."""
    windows = make_windows(truth, np.random.default_rng(8))
    cal = calibrate(windows, sand, n_slices=N_SLICES, n_boot=0, params=("zeta", "zeta"))
    assert not cal.identified["zeta"]
    assert not cal.se_gn["zeta"] < 0.25 * cal.values["zeta"]


def test_uninvertible_normal_matrix_gives_nan_errors_not_an_exception(sand, truth, monkeypatch):
    """The LinAlgError path (an exactly singular JᵀJ, which round-off rarely produces, so it
    is forced here): NaN standard errors and correlation, nothing identified, the fitted
    values still returned."""
    windows = make_windows(truth, np.random.default_rng(8))

    def singular(_):
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(np.linalg, "inv", singular)
    cal = calibrate(windows, sand, n_slices=N_SLICES, n_boot=0)
    assert math.isnan(cal.se_gn["zeta"]) and math.isnan(cal.se_gn["phi_s"])
    assert math.isnan(cal.correlation)
    assert not cal.identified["zeta"] and not cal.identified["phi_s"]
    assert cal.values["zeta"] == pytest.approx(TRUE_ZETA, rel=1e-6)


def test_rigid_like_data_without_sinking_samples(sand, truth):
    windows = make_windows(truth, np.random.default_rng(9), n_windows=2, n=30)
    for w in windows:
        w.features["sink_velocity"][:] = 0.0
    cal = calibrate(windows, sand, n_slices=N_SLICES)
    assert cal.n_samples == 0 and cal.values == cal.initial


def test_calibration_json_round_trip(sand, truth):
    cal = calibrate(make_windows(truth, np.random.default_rng(10), noise=2.0), sand,
                    n_slices=N_SLICES, n_boot=10)
    data = cal.to_json()
    assert data["values_readable"]["phi_s_deg"] == pytest.approx(math.degrees(cal.values["phi_s"]))
    back = Calibration.from_json(data)
    assert back == cal or (back.values == cal.values and back.se_gn == cal.se_gn
                           and back.ci_boot == cal.ci_boot and back.identified == cal.identified
                           and back.rmse_after == cal.rmse_after)
    # NaN has no JSON form: None reads back as NaN
    data["correlation_zeta_phi"] = None
    assert math.isnan(Calibration.from_json(data).correlation)


def test_bounds_are_those_of_granular_media():
    lo, hi = CAL_PARAMS["phi_s"]
    assert (math.degrees(lo), math.degrees(hi)) == pytest.approx((25.0, 50.0))
    assert CAL_PARAMS["zeta"][0] < 0.33 and CAL_PARAMS["zeta"][1] > 3.05
