"""Closed-loop runner: outputs of a run, falls, pushes, drop rig, interruptions, metrics.

Runs are short (≤ 1.5 s of simulated time) and on rigid ground or on the drop rig, and
nothing here assumes the robot walks: checks hold whether it walks or falls (the summary
must say correctly which).
"""
from __future__ import annotations

import json
import math
import os
import signal

import numpy as np
import pytest

from granular_mpc.exceptions import ConfigError, OutputError
from granular_mpc.runlog import read_log
from granular_mpc.runner import (SUMMARY_KEYS, build_simulation, check_fall, run_scenario,
                                 trunk_roll_pitch)
from granular_mpc.scenario import load_scenario
from granular_mpc.viz.meshcat import read_html_commands
from granular_mpc.viz.plots import trunk_rpy

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _strict_json(path):
    def no_nan(token):
        raise AssertionError(f"{path} holds {token}: not valid JSON")
    return json.loads(path.read_text(), parse_constant=no_nan)


@pytest.fixture(scope="module")
def rigid_run(tmp_path_factory):
    """A 1.5 s closed-loop run on rigid ground, with plots and the HTML page."""
    scenario = load_scenario("rigid_walk", ["sim.duration=1.5"])
    out = tmp_path_factory.mktemp("rigid") / "run"
    rows = []
    result = run_scenario(scenario, out, progress=False, html=True, on_row=rows.append)
    return scenario, result, rows


def test_summary_holds_every_contract_key(rigid_run):
    scenario, result, _ = rigid_run
    summary = _strict_json(result.out_dir / "summary.json")
    assert summary == json.loads(json.dumps(result.summary))
    missing = [k for k in SUMMARY_KEYS if k not in summary]
    assert not missing, missing
    assert summary["terrain"] == "rigid" and summary["controller_terrain_model"] == "rigid"
    assert summary["commanded_speed_mps"] == pytest.approx(scenario.command.speed)
    for key in ("mpc_solve_ms", "wbc_solve_ms"):
        assert set(summary[key]) >= {"median", "p99"}
        assert summary[key]["n"] > 0 and 0 < summary[key]["median"] <= summary[key]["p99"]
    assert isinstance(summary["fell"], bool) and isinstance(summary["qp_failures"], int)
    assert summary["complete"] is True
    assert summary["reason"] == "duration reached" or summary["reason"].startswith("fell: ")
    assert summary["realtime_factor"] == pytest.approx(summary["sim_time_s"] / summary["wall_time_s"])
    for key in ("lateral_drift_m", "max_roll_deg", "max_pitch_deg", "sinkage_peak_mm_mean"):
        assert summary[key] is None or math.isfinite(summary[key])


def test_resolved_config_reloads_to_the_same_scenario(rigid_run):
    scenario, result, _ = rigid_run
    path = result.out_dir / "config.resolved.yaml"
    again = load_scenario(path)
    assert again == scenario
    text = path.read_text()
    assert "urdf:" in text and "friction:" in text      # robot and terrain files inlined


def test_log_is_readable_and_sampled_at_the_log_rate(rigid_run):
    scenario, result, rows = rigid_run
    log = read_log(result.out_dir)
    assert len(log) == len(rows) == result.summary["log_rows"]
    t = log["time"].to_numpy()
    assert t[0] == 0.0 and t[-1] == pytest.approx(result.summary["sim_time_s"])
    steps = np.diff(t)
    # every step is one log period, except possibly the last (a fall row between ticks)
    assert np.allclose(steps[:-1], 1.0 / scenario.log_rate_hz, atol=1e-9)
    assert set(log["stance"]) <= {"left", "right", "none"}
    assert (log.loc[t < scenario.command.start_delay, "cmd_vx"] == 0.0).all()
    assert (log[["push_fx", "push_fy", "push_fz"]] == 0.0).all().all()


def test_plots_and_page_are_written(rigid_run):
    _, result, _ = rigid_run
    pngs = sorted((result.out_dir / "plots").glob("*.png"))
    assert len(pngs) >= 4 and set(pngs) == set(result.plots)
    for p in pngs:
        assert p.read_bytes()[:8] == PNG_MAGIC and p.stat().st_size > 10_000
    assert result.html == result.out_dir / "animation.html"
    commands = read_html_commands(result.html)
    assert any(c.get("type") == "set_animation" for c in commands)


def test_fell_is_what_the_log_shows(rigid_run):
    """``fell`` is true exactly when a row crosses a fall threshold, and then the run
    stopped at that row."""
    scenario, result, _ = rigid_run
    log = read_log(result.out_dir)
    f = scenario.fall
    rpy = np.degrees(trunk_rpy(log))
    bad = ((log["base_z"].to_numpy() - scenario.terrain.surface_height < f.min_trunk_height)
           | (np.abs(rpy[:, 0]) > f.max_roll_deg) | (np.abs(rpy[:, 1]) > f.max_pitch_deg))
    assert result.summary["fell"] == bool(bad.any())
    if bad.any():
        assert np.flatnonzero(bad)[0] == len(log) - 1          # stopped at the first fall row
        assert result.summary["fall_time_s"] == pytest.approx(log["time"].iloc[-1])
        assert result.summary["sim_time_s"] < scenario.sim.duration
    else:
        assert result.summary["sim_time_s"] == pytest.approx(scenario.sim.duration)


def test_fall_thresholds():
    sim = build_simulation(load_scenario("rigid_walk", ["sim.duration=0.1"]))
    q = sim.q0.copy()
    assert check_fall(sim, q) is None
    q[2] = 0.2
    assert "trunk height" in check_fall(sim, q)
    q = sim.q0.copy()
    a = math.radians(20.0)
    q[3:7] = [0.0, math.sin(a / 2), 0.0, math.cos(a / 2)]        # pitch 20°
    roll, pitch = trunk_roll_pitch(q)
    assert roll == pytest.approx(0.0, abs=1e-12) and pitch == pytest.approx(a)
    assert "pitch" in check_fall(sim, q)


def test_controller_terrain_is_chosen_independently():
    sand_rigid = build_simulation(load_scenario("sand_walk", ["controller.terrain=rigid",
                                                              "sim.duration=0.1"]))
    assert sand_rigid.plant_terrain.kind == "granular"
    assert sand_rigid.controller_terrain.kind == "rigid"
    assert sand_rigid.controller.terrain is sand_rigid.controller_terrain
    rigid_sand = build_simulation(load_scenario("sand_walk", ["terrain=rigid",
                                                              "controller.terrain=dry_sand",
                                                              "sim.duration=0.1"]))
    assert rigid_sand.plant_terrain.kind == "rigid"
    assert rigid_sand.controller_terrain.kind == "granular"
    same = build_simulation(load_scenario("sand_walk", ["sim.duration=0.1"]))
    assert same.controller_terrain is same.plant_terrain


def test_push_is_applied_in_its_window_and_moves_the_robot(tmp_path):
    common = ["terrain=rigid", "sim.duration=0.45", "fall.enabled=false", "output.plots=false"]
    push = "pushes=[{time: 0.2, force: [0.0, 40.0, 0.0], duration: 0.1}]"
    pushed = run_scenario(load_scenario("rigid_walk", common + [push]), tmp_path / "push",
                          progress=False)
    base = run_scenario(load_scenario("rigid_walk", common), tmp_path / "base", progress=False)
    log, ref = read_log(pushed.out_dir), read_log(base.out_dir)
    t = log["time"].to_numpy()
    inside = (t >= 0.2 - 1e-9) & (t < 0.3 - 1e-9)
    assert (log.loc[inside, "push_fy"] == 40.0).all() and inside.sum() == 50
    assert (log.loc[~inside, ["push_fx", "push_fy", "push_fz"]] == 0.0).all().all()
    assert pushed.summary["pushes"][0]["impulse_Ns"] == pytest.approx([0.0, 4.0, 0.0])
    # 4 N·s on ≈ 11 kg: the lateral CoM speed rises by a large share of 0.36 m/s
    k = int(np.flatnonzero(t >= 0.3 - 1e-9)[0])
    dv = log["com_vy"].iloc[k] - ref["com_vy"].iloc[k]
    assert 0.15 < dv < 0.45
    assert (log.loc[t < 0.2 - 1e-9, "base_y"].to_numpy()
            == ref.loc[t < 0.2 - 1e-9, "base_y"].to_numpy()).all()


def test_mid_stance_push_starts_at_the_planned_mid_stance():
    sc = load_scenario("rigid_walk", [
        "sim.duration=3",
        "pushes=[{at: mid_stance, side: right, time: 0.0, impulse: [3, 0, 0], duration: 0.05},"
        " {at: mid_stance, time: 1.0, force: [0, 0, -10], duration: 0.1}]"])
    sim = build_simulation(sc)
    sched = sim.controller.schedule
    w = sim.pushes
    # right leg: first stance starts half a period after stepping starts
    expect_right = sched.start + 0.5 * sched.period + 0.5 * sched.stance_duration
    assert w[0].start == pytest.approx(expect_right, abs=2 * sc.sim.dt)
    assert w[0].wrench[:3] == pytest.approx([60.0, 0.0, 0.0])         # 3 N·s / 0.05 s
    assert w[1].start >= 1.0
    side = 0 if sched.in_stance(w[1].start, 0) else 1
    assert sched.stance_phase(w[1].start, side) == pytest.approx(0.5, abs=0.02)


def test_drop_rig_holds_the_trunk_upright_and_the_feet_sink(tmp_path):
    sc = load_scenario("drop_sand", ["sim.duration=0.4", "output.plots=false"])
    res = run_scenario(sc, tmp_path / "drop", progress=False)
    log = read_log(res.out_dir)
    assert res.summary["complete"] and res.summary["mode"] == "drop"
    assert np.abs(log["base_x"]).max() < 1e-3 and np.abs(log["base_y"]).max() < 1e-3  # rail
    rpy = np.degrees(trunk_rpy(log))
    assert np.abs(rpy[:, :2]).max() < 1.0
    z0 = log["base_z"].iloc[0]
    assert log["base_z"].iloc[-1] < z0 - sc.drop.height            # fell the gap and sank
    assert res.summary["sinkage_final_mm"] > 1.0                   # into the sand
    assert res.summary["peak_grf_z_N"] > 50.0


def test_diverged_plant_leaves_a_readable_log_and_an_incomplete_summary(tmp_path):
    # a velocity bound far below the free-fall speed makes the plant "diverge" at once
    sc = load_scenario("drop_sand", ["sim.max_speed=0.05", "output.flush_every=1",
                                     "output.plots=false"])
    res = run_scenario(sc, tmp_path / "div", progress=False)
    summary = _strict_json(res.out_dir / "summary.json")
    assert summary["complete"] is False
    assert summary["reason"].startswith("plant diverged")
    log = read_log(res.out_dir)
    assert 1 <= len(log) and log["time"].iloc[-1] < 0.05


def test_sigint_during_a_run_stops_it_cleanly(tmp_path):
    """SIGINT (Ctrl-C) in the middle: the log so far stays, the summary says why."""
    sc = load_scenario("rigid_walk", ["sim.duration=1.0", "fall.enabled=false",
                                      "output.plots=false", "output.flush_every=20"])
    sent = []

    def on_row(row):
        if row["time"] >= 0.2 and not sent:
            sent.append(row["time"])
            os.kill(os.getpid(), signal.SIGINT)

    handler = signal.getsignal(signal.SIGINT)
    res = run_scenario(sc, tmp_path / "int", progress=False, on_row=on_row)
    assert signal.getsignal(signal.SIGINT) is handler                # restored
    assert res.summary["complete"] is False and res.interrupted
    assert res.summary["reason"] == "interrupted by SIGINT"
    log = read_log(res.out_dir)
    assert log["time"].iloc[-1] == pytest.approx(sent[0] + sc.sim.dt, abs=2 * sc.sim.dt) \
        or log["time"].iloc[-1] == pytest.approx(sent[0])
    assert res.summary["sim_time_s"] < 0.25


def test_reusing_a_run_folder_replaces_the_previous_run(tmp_path):
    out = tmp_path / "again"
    long = load_scenario("drop_sand", ["sim.duration=0.2", "output.flush_every=10",
                                       "output.plots=false"])
    short = load_scenario("drop_sand", ["sim.duration=0.05", "output.flush_every=10",
                                        "output.plots=false"])
    run_scenario(long, out, progress=False)
    (out / "mine.txt").write_text("keep me")
    with pytest.raises(OutputError, match="already holds a previous run.*--overwrite"):
        run_scenario(short, out, progress=False)          # not without overwrite
    assert len(read_log(out)) == 101                      # the first run is untouched
    res = run_scenario(short, out, progress=False, overwrite=True)
    log = read_log(out)
    assert len(log) == res.summary["log_rows"] == 26 and log["time"].iloc[-1] == pytest.approx(0.05)
    assert (out / "mine.txt").read_text() == "keep me"


def test_unwritable_output_folder_is_one_clear_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(OutputError, match="cannot write the output folder"):
        run_scenario(load_scenario("rigid_walk"), blocker / "run", progress=False)


def test_log_rate_above_plant_rate_is_rejected():
    with pytest.raises(ConfigError, match="log_rate_hz"):
        load_scenario("rigid_walk", ["output.log_rate_hz=5000"])


def test_runner_keeps_its_public_names():
    """Names that moved out of the runner stay importable from it (same objects)."""
    import granular_mpc.runner as runner
    from granular_mpc import columns
    from granular_mpc.analysis import summary
    from granular_mpc.rotations import roll_pitch_from_quat_xyzw

    assert runner.stance_metrics is summary.stance_metrics
    assert runner.summarize is summary.summarize and runner.SUMMARY_KEYS is summary.SUMMARY_KEYS
    for name in ("LOG_DIR", "PLOTS_DIR", "SUMMARY_FILE", "RESOLVED_FILE", "HTML_FILE"):
        assert getattr(runner, name) == getattr(columns, name)
    assert set(runner.__all__) <= set(dir(runner))
    q = np.zeros(7)
    q[3:7] = [0.1, -0.2, 0.3, 0.9]
    q[3:7] /= np.linalg.norm(q[3:7])
    assert trunk_roll_pitch(q) == roll_pitch_from_quat_xyzw(q[3:7])


def test_solver_outcomes_are_logged_per_row(tmp_path):
    """Status as data: every walk-mode log row carries the latest MPC/WBC outcome, and a
    forced MPC failure shows up in the log as a fallback and a growing failure count."""
    from granular_mpc.control.solvers.proxqp import QPSolution, QPStatus
    from granular_mpc.runner import build_simulation, closed_loop
    from granular_mpc.scenario import load_scenario

    sim = build_simulation(load_scenario("sim/rigid_walk.yaml", ["sim.duration=1.2"]))
    state = sim.new_state()
    rows = []
    for row in closed_loop(sim, state):
        rows.append(row)
        if len(rows) == 400:             # from t ≈ 0.8 s on, every MPC solve fails
            mpc = state.controller.mpc
            mpc.solver.solve = lambda p, n=sim.controller.mpc.nu: QPSolution(
                np.zeros(n), QPStatus.PRIMAL_INFEASIBLE)
    assert {"mpc_status", "mpc_fallback", "wbc_status", "qp_failures"} <= set(rows[0])
    late = [r for r in rows if r["time"] > 1.0]
    assert all(r["mpc_status"] == "primal_infeasible" for r in late)
    assert all(r["mpc_fallback"] in ("shifted", "shifted+nominal", "nominal") for r in late)
    assert rows[-1]["qp_failures"] >= 6 > rows[350]["qp_failures"]
    assert state.fall is None            # the fallback keeps it walking for a while
