"""Run summary (analysis/summary.py): stance sinkage/slip, solver-time statistics,
averaging window, the summary of a run without a usable log."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from granular_mpc.analysis.summary import (SUMMARY_KEYS, averaging_window, solve_time_stats,
                                           stance_metrics, summarize)

from synthetic_log import make_log


def test_stance_metrics_on_a_log_with_known_answers():
    syn = make_log(n_stances=6, stance_rows=101, lead_rows=10)
    m = stance_metrics(syn.df)
    # synthetic stance: z_s = 15 mm (1 − e^{−6s}), x_s = R·0.35 + 4 mm·s, y_s = ±2 mm·s
    assert m["n_stances"] == 6
    assert m["sinkage_peak_mm_mean"] == pytest.approx(15.0 * (1 - math.exp(-6.0)), rel=1e-9)
    assert m["slip_mm_mean"] == pytest.approx(math.hypot(60.0 * 0.35 + 4.0, 2.0), rel=1e-9)
    later = stance_metrics(syn.df, t_start=syn.df["time"].iloc[syn.segments[3][1]])
    assert later["n_stances"] == 3


def test_solve_time_stats():
    assert solve_time_stats([]) == {"median": None, "p99": None, "n": 0}
    s = solve_time_stats(np.arange(1.0, 102.0))       # 1 … 101 ms
    assert s == {"median": 51.0, "p99": pytest.approx(100.0), "n": 101}


def _walk_sim(start_delay=0.2, settle=0.3, period=0.4, walk=True):
    scenario = SimpleNamespace(command=SimpleNamespace(start_delay=start_delay),
                               metrics=SimpleNamespace(settle=settle),
                               controller=SimpleNamespace(gait=SimpleNamespace(period=period)))
    return SimpleNamespace(scenario=scenario, controller=object() if walk else None)


def test_averaging_window_after_ramp_and_settle():
    a, b, note = averaging_window(_walk_sim(), 0.0, 3.0, ramp_duration=0.5)
    assert (a, b) == (pytest.approx(1.0), 3.0) and "ramp" in note


def test_averaging_window_falls_back_to_the_second_half_of_a_short_run():
    a, b, note = averaging_window(_walk_sim(), 0.0, 1.2, ramp_duration=0.5)
    assert (a, b) == (pytest.approx(0.6), 1.2) and note.startswith("second half")


def test_averaging_window_of_a_drop_test_is_the_whole_log():
    assert averaging_window(_walk_sim(walk=False), 0.1, 0.9, 0.0)[:2] == (0.1, 0.9)


def test_summary_without_log_rows_still_holds_every_contract_key():
    sc = SimpleNamespace(name="x", mode="walk", terrain=SimpleNamespace(name="rigid", kind="rigid"),
                         command=SimpleNamespace(speed=0.3), sim=SimpleNamespace(duration=2.0, seed=7))
    biped = SimpleNamespace(com=lambda q: np.array([0.0, 0.0, 0.45]),
                            lowest_sole_point=lambda q: np.array([0.02, 0.03]))
    sim = SimpleNamespace(scenario=sc, biped=biped, q0=np.zeros(3),
                          controller_terrain_name="rigid",
                          controller_terrain=SimpleNamespace(kind="rigid"))
    state = SimpleNamespace(plant=SimpleNamespace(t=0.0), controller=None, fall=None,
                            pushes_applied=[])
    out = summarize(None, sim, state, wall_time_s=0.0, complete=False, reason="interrupted by SIGINT")
    assert not [k for k in SUMMARY_KEYS if k not in out]
    assert out["complete"] is False and out["reason"] == "interrupted by SIGINT"
    assert out["log_rows"] == 0 and "log" in out["notes"]
    assert out["h_com_m"] == pytest.approx(0.43) and out["realtime_factor"] is None
    json.dumps(out, allow_nan=False)                   # strict JSON
