"""All CoT readings of a log in one call: whole-body + decoupled, and the summary keys."""
from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.analysis import (COT_READINGS, RunCot, cot_decoupled_readings,
                                   cot_readings_from_log, cot_readings_report)
from granular_mpc.rotations import rpy_rows_from_quat_wxyz
from synthetic_log import JOINTS, MASS, G, make_log

W = MASS * G


def test_report_combines_full_and_decoupled():
    log = make_log(6).df
    rep = cot_readings_report(log, weight=W, t_start=0.1, t_end=1.0)
    assert isinstance(rep, RunCot)
    full = cot_readings_from_log(log, weight=W, t_start=0.1, t_end=1.0)
    assert rep.full == full
    part = log[(log.time >= 0.1) & (log.time <= 1.0)]
    rpy = rpy_rows_from_quat_wxyz(part[["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy())
    dec = cot_decoupled_readings(
        part.time.to_numpy(), part[[f"q_{j}" for j in JOINTS]].to_numpy(),
        part[[f"dq_{j}" for j in JOINTS]].to_numpy(), part[[f"tau_{j}" for j in JOINTS]].to_numpy(),
        rpy[:, 1], rpy[:, 0], part.stance.astype(str).to_numpy(), W, full.abs_net.distance_m)
    for r in COT_READINGS:
        assert rep.decoupled.get(r) == pytest.approx(dec.get(r), rel=1e-12)
    assert rep.cot == full.abs_per_joint.cot                 # the default reading
    # mass instead of weight gives the same numbers
    assert cot_readings_report(log, mass=MASS, t_start=0.1, t_end=1.0).full == full


def test_summary_items_keys_and_values():
    log = make_log(4).df
    rep = cot_readings_report(log, weight=W)
    items = rep.summary_items()
    for r in COT_READINGS:
        assert items[f"cot_{r}"] == rep.full.get(r).cot
        assert items[f"cot_decoupled_{r}"] == rep.decoupled.get(r)
        assert items[f"energy_J_{r}"] == rep.full.get(r).energy_J
        assert np.isfinite(items[f"cot_{r}"])
    assert items["cot_default_reading"] == "abs_per_joint"
    assert items["net_work_J"] == rep.full.net_work_J
    no_dec = cot_readings_report(log, weight=W, decoupled=False).summary_items()
    assert all(no_dec[f"cot_decoupled_{r}"] is None for r in COT_READINGS)
    with pytest.raises(ValueError, match="weight"):
        cot_readings_report(log)


def test_report_with_robot_model(biped):
    log = make_log(4).df
    rep = cot_readings_report(log, biped=biped, actuation="exact")
    assert rep.full.abs_net.weight_N == pytest.approx(biped.weight)
    assert rep.decoupled.weight_N == pytest.approx(biped.weight)
