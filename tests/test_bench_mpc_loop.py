"""The MPC-tick profile of the closed loop (bench/mpc_loop.py) and the ProxSuite settings
study (bench/proxsuite_settings.py), on short runs: the timers must not change the loop,
and the stages must nest as the docstrings say."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from mpc import new_settings, optimum_forces, record_ticks, replay  # noqa: E402
from mpc_loop import loop_stages, stage_figures  # noqa: E402
from proxsuite_settings import solve_sequence  # noqa: E402


@pytest.fixture
def at_root(monkeypatch):
    monkeypatch.chdir(ROOT)


def test_loop_profile_leaves_the_walk_alone_and_nests_proxsuite_inside_the_call(at_root):
    from granular_mpc.runner import build_simulation, closed_loop
    from granular_mpc.scenario import load_scenario

    stages = loop_stages(0.9, 0.2, "dry_sand")
    sim = build_simulation(load_scenario("sim/sand_walk.yaml", ["sim.duration=0.9"]))
    state = sim.new_state()
    for _ in closed_loop(sim, state):
        pass
    # ProxSuite's timers and the stage timers change no number of the closed loop
    assert stages["final_x_m"] == float(state.plant.q[0])
    n = len(stages["tick"])
    assert n == sum(r.kind == "mpc" for r in state.controller.records) >= 10
    call = np.asarray(stages["proxsuite_call"])
    inner = np.asarray(stages["proxsuite_setup"]) + np.asarray(stages["proxsuite_kernel"])
    assert np.all(inner <= call) and np.all(np.asarray(stages["proxsuite_kernel"]) > 0.0)
    for k in ("horizon", "assembly", "readout"):
        assert np.all(np.asarray(stages[k]) > 0.0), k
    figs = stage_figures(stages)
    assert figs["mpc_ticks"] == n
    assert figs["mpc_tick_ms_median_without_horizon_readout"] < figs["mpc_tick_ms_median"]
    assert figs["proxsuite_iterations_mean"] >= 1.0


def test_settings_study_default_reaches_the_optimum_and_a_loose_tolerance_does_not(at_root):
    mpc, ticks = record_ticks(0.9, 0.2, "dry_sand")
    mpc = new_settings(mpc)
    qps = replay(mpc, ticks, keep_qps=True)["qps"]
    optimum = optimum_forces(mpc, qps)
    default = solve_sequence(mpc, qps, optimum)
    loose = solve_sequence(mpc, qps, optimum, eps_abs=1e-1)
    assert default["failed"] == 0 and len(default["times"]) == len(qps) - 1
    # the default's plans: within 0.05 N of the optimum (docs/speed.md: ≈ 0.01 N worst)
    assert max(default["dist"]) < 0.05
    # a tolerance of 0.1 m g stops far earlier, visibly off the optimum
    assert max(loose["dist"]) > 10 * max(default["dist"])
    assert np.mean(loose["iters"]) < np.mean(default["iters"])
