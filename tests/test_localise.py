"""Localisation's practical-size rule: a significant cell is major (structure a missing
effect must explain) only when its bias is at least one sample's error of a correct model,
√(σ_c² + σ_meas²) (docs/validation.md §3.4)."""

import math

import numpy as np
import pytest
from scipy.stats import rankdata, spearmanr

from granular_mpc.validation.diagnosis.cubes import group_keys
from granular_mpc.validation.diagnosis.localise import (average_ranks, localize, localize_final,
                                                        measurement_noise, practical_floor,
                                                        spearman)
from granular_mpc.validation.diagnosis.residuals import channel_sigma
from granular_mpc.validation.prepare import StanceWindow

FEATURES = ("depth", "sink_velocity", "rise_from_deepest", "sink_acceleration", "slip_velocity",
            "v_h", "v_l", "vc_z", "time_in_stance", "joint_speed", "trunk_speed", "grf_z",
            "x_position")


def _windows(n_windows, meas_sigma, rng, n=60):
    """Stance windows whose measured channel ``a`` is a smooth sinking curve plus white
    noise of ``meas_sigma``."""
    ws = []
    for i in range(n_windows):
        t = np.linspace(0.0, 0.3, n)
        smooth = 0.03 * (1.0 - np.exp(-t / 0.05))            # sinks 3 cm, like a sole
        meas = {"a": smooth + rng.normal(0.0, meas_sigma, n)}
        feats = {f: rng.normal(size=n) for f in FEATURES}
        ws.append(StanceWindow(i, f"t{i % 3}", 0.2, "left" if i % 2 else "right", i % 2,
                               10 * i, 10 * i + n, t, 100 * t / 0.3, np.zeros(13),
                               np.zeros(12), np.zeros((n, 6)), (), np.zeros(3), np.zeros(3),
                               meas, feats))
    return ws


def test_measurement_noise_recovers_white_noise_on_a_moving_signal():
    rng = np.random.default_rng(1)
    ws = _windows(40, 1e-3, rng)
    sigma = measurement_noise(ws, ["a", "missing"])
    assert sigma["a"] == pytest.approx(1e-3, rel=0.08)
    assert sigma["missing"] == 0.0


def test_practical_floor_is_one_sample_error():
    assert practical_floor(3.0, 4.0) == pytest.approx(5.0)
    assert practical_floor(0.3e-3, 0.0) == pytest.approx(0.3e-3)


def _cube(rng, W, bias, sd):
    """Binned residual (W, 1, 10): bin 2 carries ``bias``, every bin scatter ``sd``."""
    R = rng.normal(0.0, sd, (W, 1, 10))
    R[:, 0, 2] += bias
    return R


def test_significant_bias_below_sensor_noise_is_not_major():
    """The null data sets' touchdown bias: t ≈ 7, 1.1 σ_c, but below one sample's noise
    (0.35 mm against σ_c 0.3 mm and 0.5 mm of marker noise) — must not be major."""
    rng = np.random.default_rng(2)
    W = 45
    ws = _windows(W, 0.5e-3, rng)
    R = _cube(rng, W, 0.35e-3, 0.3e-3)
    sigma = {"a": 0.3e-3}
    edges = np.linspace(0, 100, 11)
    noise = measurement_noise(ws, ["a"])
    with_noise = localize(ws, R, ["a"], edges, sigma, noise=noise)
    cell = next(c for c in with_noise.cells if c.side == "all" and c.phase_lo == 20.0)
    assert abs(cell.t) >= 4 and abs(cell.normalised_bias) >= 1.0   # significant, ≥ 1 σ_c
    assert abs(cell.bias) < practical_floor(sigma["a"], noise["a"])
    assert cell.major is False and with_noise.n_major_cells == 0
    # without the sensor noise the old rule (|bias| ≥ σ_c) would call it major
    assert localize(ws, R, ["a"], edges, sigma).n_major_cells >= 1


def test_bias_above_one_sample_error_stays_major():
    """A missing effect of a few mm (a hard layer, a lateral spring pushing 2 mm) is major."""
    rng = np.random.default_rng(3)
    W = 21
    ws = _windows(W, 1e-3, rng)
    R = _cube(rng, W, 2.0e-3, 0.7e-3)
    sigma = {"a": 0.7e-3}
    noise = measurement_noise(ws, ["a"])
    loc = localize(ws, R, ["a"], np.linspace(0, 100, 11), sigma, noise=noise)
    cell = next(c for c in loc.cells if c.side == "all" and c.phase_lo == 20.0)
    assert 2.0e-3 > math.hypot(0.7e-3, 1e-3)
    assert cell.major is True and loc.n_major_cells >= 1


@pytest.mark.filterwarnings("ignore:An input array is constant")   # one commanded speed
def test_final_model_is_judged_against_its_own_scatter():
    """A large misfit that varies from stance to stance (late stance, bins 7–9) inflates
    the calibrated model's σ_c; the addition removes it and leaves a 1.2 mm loading-phase
    bias (bin 1) that is minor in units of the calibrated σ_c but major against the final
    model's own scatter (docs/validation.md §3.7)."""
    rng = np.random.default_rng(4)
    W = 24
    ws = _windows(W, 0.3e-3, rng)
    edges = np.linspace(0, 100, 11)
    R_after = rng.normal(0.0, 0.4e-3, (W, 1, 10))
    R_after[:, 0, 1] += 1.2e-3
    R_cal = R_after.copy()
    R_cal[:, 0, 7:] += rng.normal(10e-3, 6e-3, (W, 1))      # the misfit, stance to stance
    noise = measurement_noise(ws, ["a"])
    sigma_cal = channel_sigma(R_cal, ["a"], group_keys(ws))
    old = localize(ws, R_after, ["a"], edges, sigma_cal, noise=noise)
    new, sigma_after = localize_final(ws, R_after, ["a"], edges, noise=noise)
    assert sigma_after["a"] == pytest.approx(channel_sigma(R_after, ["a"], group_keys(ws))["a"])
    assert sigma_after["a"] < 0.5 * sigma_cal["a"]
    cell_old = next(c for c in old.cells if c.side == "all" and c.phase_lo == 10.0)
    cell_new = next(c for c in new.cells if c.side == "all" and c.phase_lo == 10.0)
    assert cell_old.bias == pytest.approx(cell_new.bias) and abs(cell_new.t) >= 4
    assert not cell_old.major and old.n_major_cells == 0
    assert cell_new.major is True and new.n_major_cells >= 1
    assert abs(cell_new.normalised_bias) == pytest.approx(cell_new.bias / sigma_after["a"])
    # a final model without structure left has no major cell against its own scatter
    clean, _ = localize_final(ws, rng.normal(0.0, 0.4e-3, (W, 1, 10)), ["a"], edges,
                              noise=noise)
    assert clean.n_major_cells == 0


def test_spearman_is_scipys_spearmanr_bit_for_bit():
    rng = np.random.default_rng(11)
    for t in range(200):
        n = int(rng.integers(10, 300))
        x = rng.normal(size=n)
        y = rng.normal(size=n) + 0.3 * x
        if t % 3 == 0:                            # ties
            x = np.round(x, 1)
        if t % 5 == 0:
            y = np.round(y)
        ref = spearmanr(x, y)
        assert spearman(x, y) == (float(ref.statistic), float(ref.pvalue))
        assert np.array_equal(average_ranks(x), rankdata(x))
