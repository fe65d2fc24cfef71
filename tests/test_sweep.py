"""Sweeps: expansion of the sweep section, the table and plot, local pool vs Ray.

The runs are very short (0.3 s: the weight shift), so the table's physics columns are
checked for agreement between backends, not for walking.
"""
from __future__ import annotations

import importlib.util

import numpy as np
import pandas as pd
import pytest

from granular_mpc.exceptions import ConfigError
from granular_mpc.runner import SUMMARY_KEYS, run_sweep, sweep_plot, sweep_table
from granular_mpc.scenario import expand_sweep

SWEEP = "velocity_sweep"
SHORT = ["sweep.speeds=[0.1, 0.3]", "sweep.terrains=[dry_sand, rigid]", "sweep.duration=0.3"]
#: columns that depend only on the simulation (not on timing): must agree across backends
PHYSICS = ["terrain", "controller_terrain_model", "commanded_speed_mps", "mean_speed_mps",
           "sim_time_s", "fell", "energy_J", "distance_m", "sinkage_peak_mm_mean",
           "slip_mm_mean", "lateral_drift_m", "max_roll_deg", "max_pitch_deg", "qp_failures",
           "log_rows", "complete", "reason"]


def test_expansion_covers_every_combination_once():
    base, tasks = expand_sweep(SWEEP, ["sweep.speeds=[0.1, 0.2]",
                                       "sweep.controller_terrains=[plant, rigid]",
                                       "sweep.grid={controller.gait.period: [0.35, 0.4]}",
                                       "sweep.duration=2"])
    # 2 terrains × 2 controller terrains × 2 speeds × 2 periods, minus the rigid plant's
    # duplicate (controller 'plant' and 'rigid' are the same model there)
    assert len(tasks) == 12
    assert len({t.name for t in tasks}) == 12
    seen = set()
    for t in tasks:
        sc = t.scenario
        assert sc.sweep is None and sc.sim.duration == 2 and sc.output.plots is False
        assert sc.terrain.name == t.params["terrain"]
        assert sc.command.speed == t.params["commanded_speed_mps"]
        assert sc.controller.gait.period == t.params["controller.gait.period"]
        ctrl = sc.controller_terrain.name if sc.controller_terrain else sc.terrain.name
        seen.add((sc.terrain.name, ctrl, sc.command.speed, sc.controller.gait.period))
    assert len(seen) == 12
    assert base.sweep.speeds == [0.1, 0.2]


def test_seeds_multiply_runs():
    _, tasks = expand_sweep(SWEEP, SHORT + ["sweep.seeds=[1, 2]"])
    assert len(tasks) == 8
    assert sorted({t.scenario.sim.seed for t in tasks}) == [1, 2]
    assert all(t.name.endswith(("seed1", "seed2")) for t in tasks)


def test_bad_sweep_values_are_reported():
    with pytest.raises(ConfigError, match="terrain file 'mud' not found"):
        expand_sweep(SWEEP, ["sweep.terrains=[mud]"])
    with pytest.raises(ConfigError, match="sweep.speeds"):
        expand_sweep(SWEEP, ["sweep.speeds=fast"])
    with pytest.raises(ConfigError, match="sweep.speeds"):
        expand_sweep(SWEEP, ["sweep.grid={command.speed: [0.1]}"])


def _fake_result(terrain, speed, cot, fell=False):
    return {"name": f"{terrain}-{speed}", "run_dir": "/x", "params": {"terrain": terrain},
            "summary": {"terrain": terrain, "controller_terrain_model": terrain,
                        "commanded_speed_mps": speed, "mean_speed_mps": 0.9 * speed,
                        "cot": cot, "fell": fell, "complete": True, "h_com_m": 0.41,
                        "mpc_solve_ms": {"median": 0.5, "p99": 1.0, "n": 3},
                        "window_s": [1.0, 2.0], "pushes": []}}


def test_table_and_cot_plot_from_summaries(tmp_path):
    speeds = [0.1, 0.2, 0.3, 0.4]
    results = [_fake_result("rigid", v, 0.5 + v) for v in speeds]
    results += [_fake_result("dry_sand", v, 2.0 * (0.5 + v)) for v in speeds]
    results.append(_fake_result("dry_sand", 0.5, 9.9, fell=True))       # left out of the plot
    results.append(_fake_result("dry_sand", 0.5, None))                   # no CoT: NaN
    table = sweep_table(results)
    assert list(table["run"]) == [r["name"] for r in results]           # order kept
    assert table["mpc_solve_ms_median"].iloc[0] == 0.5
    assert table["window_start_s"].iloc[0] == 1.0
    assert np.isnan(table["cot"].iloc[-1]) and table["cot"].dtype == float
    path, ratio, note = sweep_plot(table, tmp_path / "cot.png")
    assert path.is_file() and path.stat().st_size > 10_000
    assert "8 of 10 runs" in note
    sand = ratio[ratio["terrain"] == "dry_sand"].sort_values("commanded_speed_mps")
    assert list(sand["commanded_speed_mps"]) == speeds
    assert np.allclose(sand["cot_ratio"], 2.0)


def test_plot_is_skipped_without_a_finite_cot(tmp_path):
    table = sweep_table([_fake_result("rigid", 0.1, None)])
    path, ratio, note = sweep_plot(table, tmp_path / "cot.png")
    assert path is None and ratio.empty and "no plot" in note
    assert not (tmp_path / "cot.png").exists()


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    _, tasks = expand_sweep(SWEEP, SHORT)
    out = tmp_path_factory.mktemp("sweep") / "local"
    return tasks, run_sweep(tasks, out, workers=2, backend="local", progress=False)


def test_local_sweep_writes_one_row_per_run(local_sweep):
    tasks, res = local_sweep
    assert res.complete
    csv = pd.read_csv(res.csv)
    assert len(csv) == len(tasks) == 4
    assert list(csv["run"]) == [t.name for t in tasks]
    flat = {k for k in SUMMARY_KEYS if k not in ("mpc_solve_ms", "wbc_solve_ms")}
    assert flat | {"mpc_solve_ms_median", "mpc_solve_ms_p99", "wbc_solve_ms_median",
                   "wbc_solve_ms_p99", "run_dir"} <= set(csv.columns)
    assert sorted(set(csv["terrain"])) == ["dry_sand", "rigid"]
    assert sorted(set(csv["commanded_speed_mps"])) == [0.1, 0.3]
    for t, row in zip(tasks, csv.itertuples(index=False)):
        assert row.terrain == t.scenario.terrain.name
        assert row.sim_time_s == pytest.approx(0.3)
        assert (res.out_dir / "runs" / t.name / "summary.json").is_file()
        assert (res.out_dir / "runs" / t.name / "log").is_dir()


def test_in_process_sweep_matches_the_pool(local_sweep, tmp_path):
    tasks, res = local_sweep
    serial = run_sweep(tasks[:2], tmp_path / "serial", workers=1, progress=False)
    for col in PHYSICS:
        a, b = serial.table[col].to_numpy(), res.table[col].to_numpy()[:2]
        if a.dtype.kind == "f":
            assert np.allclose(a, b, rtol=1e-9, atol=1e-12, equal_nan=True), col
        else:
            assert list(a) == list(b), col


@pytest.mark.slow
def test_ray_backend_gives_the_same_table(local_sweep, tmp_path):
    if importlib.util.find_spec("ray") is None:
        pytest.skip("ray is not installed: --backend ray not tested "
                    "(pip install 'granular_mpc[cluster]')")
    import ray

    tasks, res = local_sweep
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        remote = run_sweep(tasks, tmp_path / "ray", backend="ray", progress=False)
    finally:
        ray.shutdown()
    assert remote.complete
    assert list(remote.table["run"]) == list(res.table["run"])
    for col in PHYSICS:
        a, b = remote.table[col].to_numpy(), res.table[col].to_numpy()
        if a.dtype.kind == "f":
            assert np.allclose(a, b, rtol=1e-9, atol=1e-12, equal_nan=True), col
        else:
            assert list(a) == list(b), col
