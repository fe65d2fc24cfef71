"""granular_mpc.validation.prepare / replay (model, granular, rigid, planar, pool, scoring,
validation): stance windows, multiple-shooting replays of
the granular, rigid and planar models, RMSE tables, report and figures, validate --effect."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from granular_mpc.exceptions import ConfigError
from granular_mpc.robot.model import load_biped
from granular_mpc.validation import load_dataset
from granular_mpc.validation.prepare import channel_names, stance_windows
from granular_mpc.validation.replay import (ReplayPool, Variant, build_replay_model,
                                            effect_variant, load_fitted, model_terrain,
                                            replay_granular, resolve_effect_specs, validate)


@pytest.fixture(scope="module")
def clean_windows(workbench_data):
    ds = load_dataset(workbench_data("null", noisy=False))
    biped = load_biped(ds.meta.robot, with_visuals=False)
    rm = build_replay_model(biped, model_terrain("dry_sand"), sample_rate_hz=ds.meta.sample_rate_hz,
                            terrain_effects=["cohesion"])
    return ds, rm, stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness)


def test_stance_windows(clean_windows):
    ds, rm, ws = clean_windows
    complete = [p for p in ds.stance_phases(sides=("left", "right")) if p.complete]
    assert len(ws) == len(complete) >= 15
    for w in ws:
        assert w.phase[0] >= 0 and w.phase[-1] == pytest.approx(100.0) and np.all(np.diff(w.phase) > 0)
        assert w.tau.shape == (w.n, 6)
        lead, trail = w.feet[w.foot], w.feet[1 - w.foot]
        # touchdown: the stance foot starts just above its own surface, at the origin
        assert not lead.in_contact and -3e-3 < -lead.depth <= 0.0 + 1e-12
        assert abs(lead.surface) < 1e-9 and np.linalg.norm(lead.point[:2]) < 1e-9
        # the other foot carries the robot, buried as its last stance left it
        # held-out (seed 121): trailing force ≥ 97 N, depth 26.7–29.7 mm
        assert trail.in_contact and trail.force[2] > 20.0 and 0.01 < trail.depth < 0.06
        np.testing.assert_allclose(trail.e.sum(axis=0) * -rm.contact_stiffness, trail.force)


def test_noise_free_replay_reproduces_the_plant(clean_windows):
    """Replaying the plant's own data with the same model: the joint angles stay within
    ≈ 1° and the sinkage within ≈ 0.5 mm over a stance (multiple shooting, one window)."""
    ds, rm, ws = clean_windows
    err = {c: [] for c in ("q_left_knee", "q_right_knee", "grf_z", "intrusion_z")}
    for w in ws:
        out = replay_granular(rm, w, Variant(theta={"touchdown_depth": 2e-4}))
        assert not out["diverged"]
        for c in err:
            err[c].append(out[c] - w.meas[c])
    rms = {c: float(np.sqrt(np.mean(np.concatenate(v) ** 2))) for c, v in err.items()}
    # held-out (null, plant seed 121): knees 0.0084/0.0076 rad, intrusion 0.34 mm, grf_z
    # 2.8 N → margins 2.4×, 1.8×, 2.9× (docs/testing.md)
    assert rms["q_left_knee"] < 0.02 and rms["q_right_knee"] < 0.02
    assert rms["intrusion_z"] < 0.6e-3
    assert rms["grf_z"] < 8.0


def test_variants_change_the_replay(clean_windows):
    """On every stance: a softer sand (ζ 1.36 → 0.9) sinks deeper, a cohesive one holds a
    knee back."""
    ds, rm, ws = clean_windows
    coh_variant = effect_variant([(*resolve_effect_specs(["cohesion"])[0],)])
    for w in ws:
        base = replay_granular(rm, w, Variant())
        soft = replay_granular(rm, w, Variant(theta={"zeta": 0.9}))
        # derived: the RFT force is linear in ζ and (near the operating point) in depth, so
        # at the same load the peak depth scales by 1.36/0.9 (+51 %); asserted: at least
        # half of it (held-out seed 121: +16.4 … +19.2 mm on a ≈ 30 mm peak, ≥ 2× margin)
        gain = 0.5 * (1.36 / 0.9 - 1.0) * base["intrusion_z"].max()
        assert soft["intrusion_z"].max() > base["intrusion_z"].max() + gain, w.index
        coh = replay_granular(rm, w, coh_variant)
        # held-out: one knee moves 0.66 … 0.72 rad on every window; bound 0.1 rad (6×)
        moved = max(np.max(np.abs(coh[c] - base[c])) for c in ("q_left_knee", "q_right_knee"))
        assert moved > 0.1, w.index
    with pytest.raises(ConfigError, match="unknown terrain parameter"):
        replay_granular(rm, ws[3], Variant(theta={"zetta": 1.0}))


def test_pool_matches_serial(clean_windows):
    ds, rm, ws = clean_windows
    few = ws[:6]
    with ReplayPool(rm, few, workers=2) as pool:
        par = pool.run({"a": Variant()})["a"]
    ser = [replay_granular(rm, w, Variant()) for w in few]
    for p, s_ in zip(par, ser):
        np.testing.assert_allclose(p["q_left_knee"], s_["q_left_knee"], rtol=0, atol=1e-12)


def test_pool_workers_serve_every_run_and_unpicklable_variants_fork(clean_windows):
    """The workers are forked once and serve later runs (variants sent pickled); a variant
    that cannot be pickled (a sensor effect made in a closure) runs in a pool of its own,
    with the same outputs as in this process."""
    import dataclasses

    from granular_mpc.effects import all_effects, effect_info

    ds, rm, ws = clean_windows
    few = ws[:6]
    coh = effect_variant([(effect_info("cohesion"), {"suction": 3000.0})])
    scale = 1.5

    def closure_sensor(cols, p, ctx):                       # not picklable
        return {"q_left_knee": scale * np.asarray(cols["q_left_knee"])}

    info = next(i for i in all_effects(("sensor",)).values())
    odd = Variant(sensors=((dataclasses.replace(info, name="_closure", fn=closure_sensor),
                            {}),))
    with ReplayPool(rm, few, workers=2) as pool:
        first = pool.run({"a": Variant()})["a"]
        second = pool.run({"c": coh})["c"]
        assert pool.forks == 1
        third = pool.run({"o": odd})["o"]
        assert pool.forks == 2
    for k, w in enumerate(few):
        for out, var in ((first[k], Variant()), (second[k], coh), (third[k], odd)):
            ser = replay_granular(rm, w, var)
            np.testing.assert_array_equal(out["q_left_knee"], ser["q_left_knee"])


@pytest.fixture(scope="module")
def reports(workbench_data, tmp_path_factory):
    data = workbench_data("cohesion")
    root = tmp_path_factory.mktemp("validate")
    out = {m: validate(data, root / m, model=m, n_boot=200) for m in ("rigid", "planar")}
    # the granular model's tables come from the same validation as "granular+effects" (its
    # baseline is the granular model: one set of granular replays, not two)
    out["added"] = validate(data, root / "granular", effects=["cohesion:suction=3000"],
                            n_boot=200)
    out["granular"] = out["added"]
    return root, out


def test_report_tables_and_figures(reports):
    root, rep = reports
    r = rep["granular"]
    j = json.loads((root / "granular" / "report.json").read_text())
    chans = channel_names(load_biped("yobogo10s", with_visuals=False).joint_names)
    assert j["channels"] == chans and j["n_stances"] == r.report["n_stances"] > 10
    tables = j["models"]["granular"]
    by_sp = tables["by_speed_phase"]
    assert {row["phase_bin"] for row in by_sp} == {f"{10 * k}-{10 * (k + 1)}" for k in range(10)}
    assert sorted({row["commanded_speed_mps"] for row in by_sp}) == [0.15, 0.25, 0.35]
    overall = {row["channel"]: row for row in tables["overall"]}
    for c in chans:                      # intervals from resampling (stances: 1 trial/speed)
        row = overall[c]
        assert row["ci_lo"] <= row["rmse"] <= row["ci_hi"]
    assert j["interval"]["unit"] == "stance"
    for f in ("bands.png", "rmse_vs_speed.png", "heatmap_granular.png"):
        assert (root / "granular" / f).stat().st_size > 10_000


def test_models_compare_as_the_paper_says(reports):
    """Rigid ground (no sinkage, pinned foot) predicts no intrusion and larger GRF errors
    than the granular model on sand data; all three models replay every stance."""
    _, rep = reports
    g, rg, pl = (rep[m].report["overall_rmse"][m] for m in ("granular", "rigid", "planar"))
    # held-out (cohesion, seed 122): rigid/granular intrusion 21×, grf_z 3.3×; planar/rigid 0.06
    assert rg["intrusion_z"] > 5 * g["intrusion_z"]
    assert rg["grf_z"] > g["grf_z"]
    for m in ("granular", "rigid", "planar"):
        assert rep[m].report["diverged_stances"][m] == 0
        assert all(math.isfinite(v) for v in rep[m].report["overall_rmse"][m].values())
    assert pl["intrusion_z"] < rg["intrusion_z"]


def test_adding_the_true_effect_lowers_the_error(reports):
    _, rep = reports
    ba = rep["added"].report["before_after"]
    for c in ("q_left_knee", "q_right_knee", "q_left_hip_pitch"):
        # held-out (seed 122): after/before 0.18, 0.12, 0.41 → margin ≥ 1.7×
        assert ba[c]["after"] < 0.7 * ba[c]["before"], (c, ba[c])
    assert set(rep["added"].tables) == {"granular", "granular+effects"}


def test_fitted_parameters_from_a_diagnosis(tmp_path):
    diag = {"calibration": {"values": {"zeta": 1.5, "touchdown_depth": 2e-4}},
            "fitted_effects": {"cohesion": {"suction": 2500.0, "release": 0.004}}}
    p = tmp_path / "diagnosis.json"
    p.write_text(json.dumps(diag))
    cal, eff = load_fitted(tmp_path)
    assert cal == {"zeta": 1.5, "touchdown_depth": 2e-4}
    specs = resolve_effect_specs(["cohesion", "elastic_unloading:pressure=10"], eff)
    assert specs[0][1] == {"suction": 2500.0, "release": 0.004}       # fitted values
    assert specs[1][1]["pressure"] == 10.0                             # explicit wins
    cfg = model_terrain("dry_sand", cal)
    assert cfg.zeta == 1.5
    with pytest.raises(ConfigError, match="unknown calibrated parameter"):
        model_terrain("dry_sand", {"zetta": 1.0})
    with pytest.raises(ConfigError):
        validate(tmp_path, None, model="soft")


@pytest.mark.parametrize("command", ["validate", "diagnose"])
def test_unwritable_report_folder_fails_before_any_replay(workbench_data, tmp_path,
                                                          monkeypatch, command):
    """A report folder that cannot be written is an OutputError naming it, raised before
    the replays run (a bad --out must not cost the computation)."""
    from granular_mpc.exceptions import OutputError
    from granular_mpc.validation.diagnose import diagnose
    from granular_mpc.validation.diagnosis import pipeline
    from granular_mpc.validation.replay import validation

    def no_replays(*args, **kwargs):
        raise AssertionError("replays started before the output folder was checked")

    # where validate() and diagnose() build their pools
    monkeypatch.setattr(validation, "ReplayPool", no_replays)
    monkeypatch.setattr(pipeline, "ReplayPool", no_replays)
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    fn = validate if command == "validate" else diagnose
    with pytest.raises(OutputError, match="a_file exists and is not a folder"):
        fn(workbench_data("null"), blocker)


# ------------------------------------------------------------- user effects of every kind
def _user_sensor(name, fn, params):
    from granular_mpc.effects import register_sensor_effect, registered_names

    if name not in registered_names():
        register_sensor_effect(name, params=params)(fn)
    from granular_mpc.effects import effect_info
    return effect_info(name)


def _torque_gain(cols, p, ctx):
    """Current-based torque sensing with a gain error: τ_meas = g τ on every joint."""
    return {f"tau_{j}": p["gain"] * np.asarray(cols[f"tau_{j}"]) for j in ctx.joint_names}


def _knee_offset(cols, p, ctx):
    """Zero offset of the left knee encoder: q_meas = q + δ."""
    return {"q_left_knee": np.asarray(cols["q_left_knee"]) + p["offset"]}


def test_a_sensor_effect_on_the_torques_drives_the_replay(clean_windows):
    """A user sensor effect on the tau_* columns (inputs of the replay) used to crash
    (KeyError 'tau_left_hip_abd': sensor effects saw only the replayed channels); now the
    replay is driven by the true torques τ_meas / g."""
    from granular_mpc.effects import Param

    info = _user_sensor("_test_torque_gain", _torque_gain,
                        {"gain": Param(1.1, 0.5, 2.0, "-", "torque gain")})
    ds, rm, ws = clean_windows
    w = ws[3]
    base = replay_granular(rm, w, Variant())
    same = replay_granular(rm, w, effect_variant([(info, {"gain": 1.0})]))
    np.testing.assert_allclose(same["q_left_knee"], base["q_left_knee"], atol=1e-12)
    weak = replay_granular(rm, w, effect_variant([(info, {"gain": 1.3})]))
    assert not weak["diverged"]
    assert np.max(np.abs(weak["q_right_knee"] - base["q_right_knee"])) > 0.01


def test_an_encoder_offset_at_its_true_value_restores_the_replay(clean_windows):
    """Data whose left-knee encoder reads 0.05 rad high: the term with the true offset
    must bring the replay back to the plant's (the window starts from the true angle, the
    offset is added to the output), not double the error."""
    import dataclasses

    from granular_mpc.effects import Param

    info = _user_sensor("_test_knee_offset", _knee_offset,
                        {"offset": Param(0.01, -0.2, 0.2, "rad", "encoder zero offset")})
    ds, rm, ws = clean_windows
    delta = 0.05
    trials = {}
    for name, df in ds.trials.items():
        df = df.copy()
        df["q_left_knee"] = df["q_left_knee"] + delta
        trials[name] = df
    biased = dataclasses.replace(ds, trials=trials)
    wb = stance_windows(biased, rm.biped, contact_stiffness=rm.contact_stiffness)
    k = next(i for i, w in enumerate(ws) if w.side == "left")
    ref = replay_granular(rm, ws[k], Variant())            # unbiased data, no term
    off = replay_granular(rm, wb[k], Variant())            # biased data, no term
    fix = replay_granular(rm, wb[k], effect_variant([(info, {"offset": delta})]))

    def err(out, w):
        return float(np.sqrt(np.mean((out["q_left_knee"] - w.meas["q_left_knee"]) ** 2)))

    e_ref, e_off, e_fix = err(ref, ws[k]), err(off, wb[k]), err(fix, wb[k])
    assert e_fix < e_off
    # as good as the unbiased data's replay; held-out (all 12 left windows of the null case
    # at plant seed 121): e_fix − e_ref ≤ 0.47 mrad, ≥ 1.75 mrad inside this bound
    assert e_fix <= 1.2 * e_ref + 2e-3
    assert np.sqrt(np.mean((fix["grf_z"] - ref["grf_z"]) ** 2)) < 0.03 * np.abs(ref["grf_z"]).max()


def test_position_dependent_terms_see_world_coordinates(clean_windows):
    """A terrain force acting only beyond a world x: the replay sees the contact point in
    the data set's world x (as synth's plant does), not in the stance's local frame."""
    import dataclasses

    from granular_mpc.effects import Param, register_effect, registered_names

    name = "_test_beyond_x"
    if name not in registered_names():
        @register_effect(name, params={"f": Param(0.0, 0.0, 500.0, "N", ""),
                                       "x0": Param(0.0, -100.0, 100.0, "m", "")})
        def _beyond(o, s, p):
            """A vertical push on patches beyond the world x0."""
            return (0.0, 0.0, p["f"] * s.in_contact * o.if_else(s.p_c[0] > p["x0"], 1.0, 0.0))
    ds, _, ws = clean_windows
    rm = build_replay_model(load_biped(ds.meta.robot, with_visuals=False),
                            model_terrain("dry_sand"), sample_rate_hz=ds.meta.sample_rate_hz,
                            terrain_effects=[name])
    w = ws[3]
    far = dataclasses.replace(w, origin=w.origin + np.array([50.0, 0.0, 0.0]))
    base = replay_granular(rm, far, Variant())
    on = replay_granular(rm, far, Variant(theta={f"{name}.f": 200.0, f"{name}.x0": 45.0}))
    off = replay_granular(rm, far, Variant(theta={f"{name}.f": 200.0, f"{name}.x0": 55.0}))
    np.testing.assert_allclose(off["grf_z"], base["grf_z"], atol=1e-9)
    assert np.max(np.abs(on["grf_z"] - base["grf_z"])) > 20.0
    # moving the whole stance does not change the replay (the dynamics are translation-free)
    np.testing.assert_allclose(base["q_left_knee"], replay_granular(rm, w, Variant())["q_left_knee"],
                               atol=1e-6)


def test_a_sensor_effect_reading_a_missing_column_is_refused_up_front(workbench_data):
    from granular_mpc.effects import Param

    def _bad(cols, p, ctx):
        """Reads a column the data set does not have."""
        return {"grf_z": np.asarray(cols["load_cell_raw"]) * p["k"]}

    _user_sensor("_test_bad_sensor", _bad, {"k": Param(1.0, 0.0, 2.0, "-", "")})
    with pytest.raises(ConfigError, match="_test_bad_sensor.*'load_cell_raw'"):
        validate(workbench_data("null"), None, model="rigid", effects=["_test_bad_sensor"],
                 workers=1, figures=False)


@pytest.mark.parametrize("content", [[1, 2, 3], {"zeta": "abc"}, {"cohesion": {"suction": [1]}},
                                     {"fitted_effects": {"cohesion": 3}}, "text"])
def test_fitted_parameters_of_the_wrong_shape_name_the_file(tmp_path, content):
    p = tmp_path / "params.json"
    p.write_text(json.dumps(content))
    with pytest.raises(ConfigError, match="params.json") as err:
        load_fitted(p)
    assert err.value.key == "--params"


def test_reused_plant_data_replays_like_a_fresh_one(clean_windows):
    """The compiled replay resets one plant data per model instead of building one per
    window: after replays of other windows and variants (joint-effect θ, other terrain θ,
    other feet in contact), a window's replay equals bit for bit its first replay on a
    freshly built model (whose first replay builds a new data)."""
    ds, rm0, ws = clean_windows
    biped = rm0.biped
    joint = effect_variant(resolve_effect_specs(["joint_friction"]))
    variants = [Variant(), Variant(theta={"zeta": 0.9}), joint]
    for w, var in zip((ws[0], ws[3], ws[-1]), variants):
        rm = build_replay_model(biped, model_terrain("dry_sand"),
                                sample_rate_hz=ds.meta.sample_rate_hz,
                                terrain_effects=["cohesion"])
        fresh = replay_granular(rm, w, var)              # the model's first data: new
        for other in (ws[1], ws[5], w):
            for v2 in variants[::-1]:
                replay_granular(rm, other, v2)
        again = replay_granular(rm, w, var)
        assert set(again) == set(fresh)
        for c, val in fresh.items():
            assert np.array_equal(np.asarray(again[c]), np.asarray(val)), (w.index, c)


def _windows_measured(ds, rm, sensor):
    """Stance windows of ``ds`` with every trial passed through ``sensor(df)`` (which
    changes a copy of the trial's table in place: the "measured" data)."""
    import dataclasses

    trials = {}
    for name, df in ds.trials.items():
        df = df.copy()
        sensor(df)
        trials[name] = df
    return stance_windows(dataclasses.replace(ds, trials=trials), rm.biped,
                          contact_stiffness=rm.contact_stiffness)


def _user_delay(cols, p, ctx):
    """Torque stream stamped d late, written without an inverse: τ_meas(t) = τ(t − d)."""
    t = np.asarray(ctx.time, dtype=float)
    return {f"tau_{j}": np.interp(t - p["d"], t, np.asarray(cols[f"tau_{j}"], dtype=float))
            for j in ctx.joint_names}


def test_a_torque_delay_at_its_true_value_restores_the_replay(clean_windows):
    """Data whose torque stream is 2 samples late: the measurement family's
    ``torque_time_offset`` (which carries its inverse) at the true delay brings the replay
    back to the plant's; the same map without an inverse cannot be replayed and says so."""
    from granular_mpc.effects import Param, effect_info
    from granular_mpc.effects.measurement import register_measurement
    from granular_mpc.validation.diagnosis.candidates import (
        build_candidates, check_sensor_candidates, drop_uninvertible_sensor_candidates)
    from granular_mpc.validation.replay import check_sensor_inversion

    register_measurement()
    info = effect_info("torque_time_offset")
    ds, rm, ws = clean_windows
    delay = 0.004                                   # 2 samples at 500 Hz
    def late(df):
        t = df["time"].to_numpy()
        for c in df.columns:
            if c.startswith("tau_"):
                df[c] = np.interp(t - delay, t, df[c].to_numpy())

    wl = _windows_measured(ds, rm, late)
    k = 3
    ref = replay_granular(rm, ws[k], Variant())
    off = replay_granular(rm, wl[k], Variant())
    fix = replay_granular(rm, wl[k], effect_variant([(info, {"delay": delay})]))

    def err(out):
        return float(np.sqrt(np.mean((out["q_right_knee"] - ref["q_right_knee"]) ** 2)))

    assert err(fix) < 0.01 * err(off)
    # written by a user without an inverse: refused up front, dropped as a candidate
    user = _user_sensor("_test_user_delay", _user_delay,
                        {"d": Param(0.004, 0.0, 0.05, "s", "torque stream lag")})
    with pytest.raises(ConfigError, match="_test_user_delay.*cannot be inverted"):
        check_sensor_inversion([(user, {"d": delay})], wl[k], rm.biped.joint_names)
    cands = check_sensor_candidates(build_candidates(["_test_user_delay", "torque_time_offset"]),
                                    wl[k], rm.biped.joint_names)
    kept, warns = drop_uninvertible_sensor_candidates(cands, wl[k], rm.biped.joint_names)
    assert list(kept.infos) == ["torque_time_offset"]
    assert len(warns) == 1 and "_test_user_delay" in warns[0] and "inverse=" in warns[0]


def test_a_trunk_attitude_bias_at_its_true_value_restores_the_replay(clean_windows):
    """Data whose trunk attitude reads 1.5° too pitched: every window starts with the trunk
    tilted and the stance foot's free surface estimated through tilted kinematics; the
    measurement family's ``trunk_attitude_bias`` at the true pitch undoes both, and the
    replay is the unbiased data's."""
    from granular_mpc.effects import effect_info
    from granular_mpc.effects.measurement import register_measurement
    from granular_mpc.rotations import quat_mul_rows_wxyz, quat_rows_wxyz_from_rotvec

    register_measurement()
    info = effect_info("trunk_attitude_bias")
    ds, rm, ws = clean_windows
    pitch = np.deg2rad(1.5)
    cols = ["base_qw", "base_qx", "base_qy", "base_qz"]

    def tilted(df):
        q = df[cols].to_numpy()
        qb = np.repeat(quat_rows_wxyz_from_rotvec([[0.0, pitch, 0.0]]), len(q), axis=0)
        df[cols] = quat_mul_rows_wxyz(q, qb)

    wt = _windows_measured(ds, rm, tilted)
    k = 3
    ref = replay_granular(rm, ws[k], Variant())
    off = replay_granular(rm, wt[k], Variant())
    fix = replay_granular(rm, wt[k], effect_variant([(info, {"roll": 0.0, "pitch": pitch})]))

    def err(out, c):
        return float(np.sqrt(np.mean((out[c] - ref[c]) ** 2)))

    # measured: grf_x 3.04 N → 6e-9 N, grf_z 2.95 N → 5e-9 N, hip pitch 6.1 mrad → 1e-13
    # rad: the replay of the untilted data, up to round-off (with the stance foot's free
    # surface moved by the start sample's correction alone, grf_x was 0.69 N)
    for c in ("grf_x", "grf_z", "q_right_hip_pitch", "q_left_knee", "intrusion_x"):
        assert err(fix, c) < 1e-4 * err(off, c), c
