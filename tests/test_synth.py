"""granular_mpc.validation.synth: closed-loop data in format v1, hidden effects of every
kind in the plant only, the sensor-noise model, stance labels, the generator block."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from granular_mpc.exceptions import ConfigError
from granular_mpc.scenario import load_scenario
from granular_mpc.validation import load_dataset
from granular_mpc.validation.synth import (NOISE_MODEL, add_noise, build_plant_simulation,
                                           leading_foot_labels, normalise_noise, synthesize,
                                           torque_hold)


def test_data_set_is_format_v1_with_the_true_values_in_the_generator(workbench_data):
    ds = load_dataset(workbench_data("cohesion"))
    assert len(ds.trials) == 3
    assert sorted(t.commanded_speed_mps for t in ds.meta.trials.values()) == [0.15, 0.25, 0.35]
    gen = ds.meta.generator
    assert gen is not None and gen.seed == 22
    # the true parameters, all of them (defaults resolved), for recovery tests
    assert [e.name for e in gen.effects] == ["cohesion"]
    assert gen.effects[0].params == {"suction": 3000.0, "release": 0.003}
    assert gen.noise == {"level": 1.0}
    assert gen.settings["true_terrain"]["zeta"] == 1.36
    assert gen.settings["effect_kinds"] == {"cohesion": "terrain_force"}
    phases = ds.stance_phases(sides=("left", "right"))
    assert sum(p.complete for p in phases) >= 15


def test_stance_phases_start_at_touchdown(workbench_data):
    """Leading-foot labels: a stance run starts when its foot touches down, so its first
    intrusion samples are ≈ 0 and it ends when the other foot touches down."""
    ds = load_dataset(workbench_data("null", noisy=False))
    for ph in ds.stance_phases(sides=("left", "right")):
        if not ph.complete:
            continue
        df = ds.trials[ph.trial].iloc[ph.row_start:ph.row_stop]
        assert df["intrusion_z"].iloc[0] < 3e-3
        assert df["intrusion_z"].max() > 10e-3          # it sinks on sand
        assert df["grf_z"].iloc[-10:].mean() > 40.0     # and carries the robot at the end


def test_leading_foot_labels():
    L = np.array([1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1])
    R = np.array([0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1])
    lab = leading_foot_labels(L, R, max_gap=3, min_samples=3)
    assert list(lab[:3]) == ["left"] * 3
    assert list(lab[3:18]) == ["right"] * 15          # right touched down last
    assert list(lab[18:]) == ["left"] * 4
    # a 2-sample bounce does not start a new stance; a 1-sample touch is ignored
    B = np.array([1, 1, 1, 1, 0, 0, 1, 1, 1, 1, 1, 1])
    assert set(leading_foot_labels(B, np.zeros(12), max_gap=3, min_samples=3)) == {"left"}
    T = np.array([0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0])
    assert set(leading_foot_labels(T, np.zeros(12), max_gap=0, min_samples=2)) == {"none"}


def _frame(n=4000, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.002
    df = pd.DataFrame({"time": t, "stance": np.where(np.arange(n) % 200 < 150, "left", "none")})
    J = ["left_hip_abd", "left_knee"]
    for j in J:
        df[f"q_{j}"] = 0.3 * np.sin(2 * np.pi * t)
        df[f"dq_{j}"] = 0.6 * np.pi * np.cos(2 * np.pi * t)
        df[f"tau_{j}"] = 5.0 + rng.normal(0, 1, n)
    for c in ("base_x", "base_y", "base_z", "base_vx", "base_vy", "base_vz", "base_wx",
              "base_wy", "base_wz", "grf_x", "grf_y", "intrusion_x", "intrusion_y",
              "intrusion_z"):
        df[c] = 0.0
    df["grf_z"] = np.where(df["stance"] == "left", 100.0, 0.0)
    df["base_qw"], df["base_qx"], df["base_qy"], df["base_qz"] = 1.0, 0.0, 0.0, 0.0
    return df, J


def test_noise_model_levels_and_masks():
    df, J = _frame()
    rng = np.random.default_rng(1)
    noisy = add_noise(df, J, 1.0, {}, rng, 500.0)
    q_err = noisy[f"q_{J[0]}"] - df[f"q_{J[0]}"]
    assert q_err.std() == pytest.approx(NOISE_MODEL["q"], rel=0.1)
    # differentiated, low-passed encoder noise: much larger than q noise / s, unbiased
    dq_err = noisy[f"dq_{J[0]}"] - df[f"dq_{J[0]}"]
    assert 0.05 < dq_err.std() < 0.7 and abs(dq_err.mean()) < 0.02
    stance = df["stance"] == "left"
    g_err = noisy["grf_z"] - df["grf_z"]
    assert g_err[~stance].abs().max() == 0.0                       # no sensor read: 0 stays 0
    assert g_err[stance].std() == pytest.approx(1.0 + 0.01 * 100.0, rel=0.1)
    quat = noisy[["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy()
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-12)
    tilt = 2 * np.degrees(np.arcsin(np.linalg.norm(quat[:, 1:], axis=1)))
    assert np.sqrt(np.mean(tilt ** 2)) == pytest.approx(0.5 * np.sqrt(3), rel=0.15)
    # level 0: nothing changes; level 2: twice the q noise
    pd.testing.assert_frame_equal(add_noise(df, J, 0.0, {}, rng, 500.0), df)
    q2 = add_noise(df, J, 2.0, {}, rng, 500.0)[f"q_{J[0]}"] - df[f"q_{J[0]}"]
    assert q2.std() == pytest.approx(2 * NOISE_MODEL["q"], rel=0.1)
    # per-prefix white noise (the command line's --noise grf_=0.5) replaces the model
    white = add_noise(df, J, 0.0, {"grf_": 0.5}, rng, 500.0)
    assert (white["grf_z"] - df["grf_z"])[stance].std() == pytest.approx(0.5, rel=0.1)
    assert (white[f"q_{J[0]}"] == df[f"q_{J[0]}"]).all()


def test_normalise_noise():
    assert normalise_noise(None) == (1.0, {})
    assert normalise_noise(0.5) == (0.5, {})
    assert normalise_noise({}) == (1.0, {})
    assert normalise_noise({"grf_": 0.5}) == (0.0, {"grf_": 0.5})
    assert normalise_noise({"level": 2, "q_": 0.01}) == (2.0, {"q_": 0.01})
    with pytest.raises(ConfigError):
        normalise_noise(-1.0)


def test_effects_go_to_the_plant_only_by_kind():
    sc = load_scenario("sand_walk")
    sim = build_plant_simulation(sc, ["cohesion:suction=2000", "joint_friction",
                                      "terrain_slope:slope_y=0.03", "force_sensor_bias"])
    names = sim.plant.terrain.param_names
    values = dict(zip(names, sim.plant.terrain.param_values))
    assert values["cohesion.suction"] == 2000.0
    assert values["surface_slope_y"] == 0.03
    assert len(sim.plant.joint_effects) == 1
    # the controller's terrain never sees them
    ctrl = sim.controller_terrain
    assert "cohesion.suction" not in ctrl.param_names
    assert dict(zip(ctrl.param_names, ctrl.param_values))["surface_slope_y"] == 0.0
    with pytest.raises(ConfigError, match="unknown effect"):
        build_plant_simulation(sc, ["cohesoin"])


def test_joint_effects_step_on_the_compiled_plant():
    """A data set with a joint effect is made on the compiled plant (it fell back to the
    reference plant until session 26: the hook summed with ``np.asarray(…, float)``, which
    CasADi symbols cannot pass); the hook gives the same torques on symbols as on floats."""
    import casadi as ca

    sc = load_scenario("sand_walk")
    sim = build_plant_simulation(sc, ["joint_friction:coulomb=0.3,viscous=0.05"])
    assert sim.plant_choice.resolved == "compiled", sim.plant_choice
    hook = sim.plant.joint_effects[0]
    q, dq = ca.SX.sym("q", 6), ca.SX.sym("dq", 6)
    traced = ca.Function("tau", [q, dq], [hook(q, dq)])
    rng = np.random.default_rng(5)
    for _ in range(5):
        qa, va = rng.normal(size=6), rng.normal(size=6)
        expect = hook(qa, va)
        assert np.abs(expect).max() > 0.05
        assert np.allclose(np.array(traced(qa, va)).ravel(), expect, rtol=1e-12, atol=1e-14)


def test_sensor_effect_on_the_record_and_seeded_noise(tmp_path, workbench_data, monkeypatch):
    """A sensor effect changes the recorded columns only (grf_z + 7 N on stance rows);
    noise with the same seed is the same. (The plant run itself is replaced by a recorded
    trial: closed-loop runs are not bit-reproducible, see docs/validation.md.)"""
    import granular_mpc.validation.synth as synth_mod
    from granular_mpc.validation.synth import noisy_copy

    clean = load_dataset(workbench_data("null", noisy=False))
    frame = clean.trials["trial_002"].copy()

    def fake_run(payload):
        return {"name": payload["name"], "frame": frame.copy(), "note": "",
                "warmup": payload["warmup"], "joint_names": list(clean.joint_names)}

    monkeypatch.setattr(synth_mod, "_run_trial", fake_run)
    res = synthesize("sand_walk", tmp_path / "b", speeds=[0.25], duration=0.6, seed=5,
                     noise=0.0, effects=["force_sensor_bias:bias_z=7"], format="csv")
    out = load_dataset(res.path).trials["trial_001"]
    assert (tmp_path / "b" / "trial_001.csv").is_file()
    on = (frame["stance"] != "none").to_numpy()
    np.testing.assert_allclose((out["grf_z"] - frame["grf_z"]).to_numpy()[on], 7.0, atol=1e-9)
    np.testing.assert_allclose(out["grf_z"].to_numpy()[~on], 0.0)
    np.testing.assert_allclose(out["q_left_knee"], frame["q_left_knee"])
    a = noisy_copy(workbench_data("null", noisy=False), tmp_path / "n1", 1.0, seed=3)
    b = noisy_copy(workbench_data("null", noisy=False), tmp_path / "n2", 1.0, seed=3)
    c = noisy_copy(workbench_data("null", noisy=False), tmp_path / "n3", 1.0, seed=4)
    ta, tb, tc = (load_dataset(x).trials["trial_001"] for x in (a, b, c))
    pd.testing.assert_frame_equal(ta, tb)
    assert not np.allclose(ta["grf_z"], tc["grf_z"])
    # the torques are the controller's commands, held one 500 Hz tick after their stamp
    assert load_dataset(res.path).meta.torque_hold_s == 0.002
    assert load_dataset(a).meta.torque_hold_s == clean.meta.torque_hold_s == 0.002


def test_torque_hold_is_declared_only_when_rows_fall_on_controller_ticks():
    """A log row logs the command just set when it falls on a tick (every tick, or every
    other): held one controller period; between ticks (1000 or 300 Hz rows for 500 Hz
    ticks) the hold after a row's stamp varies — nothing is declared."""
    assert torque_hold(load_scenario("sand_walk")) == 0.002
    assert torque_hold(load_scenario("sand_walk", ["output.log_rate_hz=250"])) == 0.002
    assert torque_hold(load_scenario("sand_walk", ["controller.wbc.rate_hz=1000"])) == 0.001
    for rate in (1000, 300):
        assert torque_hold(load_scenario("sand_walk", [f"output.log_rate_hz={rate}"])) is None


def test_bad_arguments(tmp_path):
    with pytest.raises(ConfigError, match="steps or duration"):
        synthesize("sand_walk", tmp_path / "x", steps=3, duration=1.0)
    with pytest.raises(ConfigError, match="format"):
        synthesize("sand_walk", tmp_path / "x", format="xlsx")
    with pytest.raises(ConfigError, match="walking scenario"):
        synthesize("drop_sand", tmp_path / "x")
