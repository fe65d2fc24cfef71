"""The recovery study's signal (bench/recovery_signal.py), its ≥ 2 σ figures
(bench/recovery.py's study_figures) and its case folders (case_tag), on small hand-made
inputs: no replay, no diagnosis."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
from recovery import case_tag, study_figures  # noqa: E402
from recovery_signal import (effect_signature, largest_ratio, noise_sigma,  # noqa: E402
                             signal_from)


def test_signature_subtracts_the_floor_in_quadrature():
    assert effect_signature(5.0, 3.0) == pytest.approx(4.0)
    assert effect_signature(1.0, 2.0) == 0.0            # the effect made it worse: no signal


def test_signal_is_the_largest_signature_over_noise():
    ba = {"q_left_knee": (0.010, 0.006),   # s = 0.008 rad, σ = 0.001 rad → 8
          "grf_z": (5.0, 3.0),             # s = 4 N, σ = 2 N → 2
          "grf_x": (9.0, 1.0)}             # no σ given: skipped
    sig = signal_from(ba, {"q_left_knee": 1e-3, "grf_z": 2.0, "grf_x": 0.0})
    assert sig.channel == "q_left_knee"
    assert sig.value == pytest.approx(8.0)
    assert sig.signature == pytest.approx(0.008) and sig.sigma == pytest.approx(1e-3)
    assert sig.moves_2_sigma
    weak = signal_from({"grf_z": (2.5, 2.0)}, {"grf_z": 2.0})        # s = 1.5 N → 0.75
    assert weak.value == pytest.approx(0.75) and not weak.moves_2_sigma
    floor = signal_from(ba, {"q_left_knee": 1e-3, "grf_z": 2.0}, with_floor=True)
    assert floor.channel == "q_left_knee"                # 0.008 / hypot(0.006, 0.001)
    assert floor.value == pytest.approx(0.008 / math.hypot(0.006, 0.001))
    assert math.isnan(signal_from(ba, {}).value) and signal_from(ba, {}).channel is None
    moved = largest_ratio({"grf_z": 5.0, "q_left_knee": 0.004}, {"grf_z": 2.0, "q_left_knee": 1e-3})
    assert moved.channel == "q_left_knee" and moved.value == pytest.approx(4.0)


def test_noise_sigma_uses_stance_rows_only():
    rng = np.random.default_rng(0)
    n = 4000
    stance = np.where(np.arange(n) % 4 == 0, "none", "left")
    clean = pd.DataFrame({"stance": stance, "grf_z": np.linspace(0.0, 100.0, n)})
    noise = rng.normal(0.0, 2.0, n)
    noise[stance == "none"] = 50.0                       # off-stance rows must not count
    noisy = clean.assign(grf_z=clean["grf_z"] + noise)
    sigma = noise_sigma({"t1": clean}, {"t1": noisy}, ["grf_z"])
    assert sigma["grf_z"] == pytest.approx(2.0, rel=0.05)


def _row(signal, rank, coef_err, effect="cohesion:suction=3000", moved=None):
    return {"effect": effect, "rank": rank, "coef_err": coef_err, "signal": signal,
            "signal_moved": moved,
            "heldout_red": 0.6, "nothing_added": False, "status": "missing_effect"}


def test_study_figures_keep_all_cases_beside_the_signal2_population():
    rows = [_row(10.0, 1, 0.05, moved=9.0), _row(1.5, 2, 0.40, moved=2.5),
            _row(3.0, 1, -0.20, moved=1.0), _row(None, 1, 0.0)]
    rows.append({"effect": "none", "rank": None, "coef_err": None, "signal": None,
                 "heldout_red": None, "nothing_added": True,
                 "status": "no_significant_missing_effect"})
    f = study_figures(rows)
    assert f["cases"] == 4 and f["cases_signal2"] == 2 and f["null_cases"] == 1
    assert f["rank1_rate"] == pytest.approx(0.75)
    assert f["coef_within_15pct_rate"] == pytest.approx(0.5)
    assert f["rank1_rate_signal2"] == pytest.approx(1.0)
    assert f["coef_within_15pct_rate_signal2"] == pytest.approx(0.5)
    assert f["cases_moved2"] == 2 and f["rank1_rate_moved2"] == pytest.approx(0.5)
    assert f["coef_within_15pct_rate_moved2"] == pytest.approx(0.5)


def test_two_magnitudes_of_one_effect_get_their_own_folders():
    """An effect given with its parameters gets them in its tag (two magnitudes of one
    effect in a run wrote the same folders before); the default tags stay as they were, so
    stored studies are still reused; several mismatches get one tag each."""
    assert case_tag("depth_hardening", None, 4) == "depth_hardening_s4"
    assert case_tag("depth_hardening:n=1.3", None, 4) == "depth_hardening_n_1.3_s4"
    assert case_tag("depth_hardening:n=1.3", None, 4) != case_tag("depth_hardening:n=1.5", None, 4)
    assert case_tag(None, "terrain.zeta=1.768", 201) == "mismatch_s201"
    many = {case_tag(None, m, 201, several_mismatches=True)
            for m in ("terrain.zeta=1.768", "terrain.phi_s_deg=33")}
    assert len(many) == 2
    assert case_tag(None, None, 100) == "null_s100"
