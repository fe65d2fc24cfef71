"""The ablations behind the paper comparison's measured reasons (issue 10): the rigid and
planar replay knobs (granular_mpc.validation.replay.rigid / planar), the F_x-profile
measurement of bench/paper_fx.py, and the reason cells of granular_mpc.paper.gaps."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pinocchio as pin
import pytest

from granular_mpc.paper.gaps import RIGID_KNOBS, load_gaps
from granular_mpc.robot.model import load_biped
from granular_mpc.validation import load_dataset
from granular_mpc.validation.prepare import stance_windows
from granular_mpc.validation.replay import build_replay_model, model_terrain, replay_planar
from granular_mpc.validation.replay.rigid import (CONTACT_MODES, measured_contact_path,
                                                  replay_rigid)

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
from paper_fx import N_BINS, phase_profile  # noqa: E402


@pytest.fixture(scope="module")
def windows(workbench_data):
    ds = load_dataset(workbench_data("null", noisy=False))
    biped = load_biped(ds.meta.robot, with_visuals=False)
    rm = build_replay_model(biped, model_terrain("dry_sand"),
                            sample_rate_hz=ds.meta.sample_rate_hz)
    ws = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness)
    return rm, ws[2:6]


def _mean_fz(rm, ws, **kw):
    return float(np.mean([np.nanmean(replay_rigid(rm, w, **kw)["grf_z"]) for w in ws]))


def test_rigid_default_is_the_papers_pin(windows):
    """The knobs are opt-in: the default replay equals the explicit paper options, with or
    without diagnostics."""
    rm, ws = windows
    a = replay_rigid(rm, ws[0])
    b = replay_rigid(rm, ws[0], contact="pin", impact="project", diagnostics=True)
    np.testing.assert_array_equal(a["grf_z"], b["grf_z"])
    np.testing.assert_array_equal(a["q_left_knee"], b["q_left_knee"])
    assert "com_z" in b and "com_z" not in a
    with pytest.raises(ValueError, match="contact must be one of"):
        replay_rigid(rm, ws[0], contact="glue")


def test_sinking_pin_raises_fz_toward_the_data(windows):
    """The pinned foot does not sink; under the measured torques the robot falls and F_z is
    low. Making the contact point sink as measured raises F_z toward the measured mean and
    keeps the CoM from falling."""
    rm, ws = windows
    measured = float(np.mean([np.mean(w.meas["grf_z"]) for w in ws]))
    pinned = _mean_fz(rm, ws)
    sinking = _mean_fz(rm, ws, contact="measured_sink")
    following = _mean_fz(rm, ws, contact="measured")
    assert pinned < 0.9 * measured
    assert sinking > pinned + 5.0
    assert abs(following - measured) < 0.1 * measured
    d_pin = replay_rigid(rm, ws[0], diagnostics=True)
    d_sink = replay_rigid(rm, ws[0], contact="measured_sink", diagnostics=True)
    fall = lambda d: d["com_z"][0] - d["com_z"][-1]  # noqa: E731
    assert fall(d_sink) < fall(d_pin)


def test_measured_contact_path_sinks(windows):
    """The measured contact point of a stance on sand goes down by the sinkage [m]."""
    rm, ws = windows
    w = ws[0]
    path = measured_contact_path(rm.biped, w)
    assert path.shape == (w.n, 3)
    sink = path[0, 2] - path[-1, 2]
    assert sink == pytest.approx(w.meas["intrusion_z"][-1] - w.meas["intrusion_z"][0], abs=4e-3)
    assert sink > 0.01
    assert set(CONTACT_MODES) >= {"pin", "measured", "measured_sink", "rolling"}


def test_planar_frontal_knob(windows):
    rm, ws = windows
    a = replay_planar(rm, ws[0])
    b = replay_planar(rm, ws[0], frontal="measured")
    assert not b["diverged"] and np.all(np.isfinite(b["intrusion_z"]))
    assert not np.array_equal(a["grf_y"], b["grf_y"])
    with pytest.raises(ValueError, match="frontal must be one of"):
        replay_planar(rm, ws[0], frontal="sideways")


def test_phase_profile_recovers_a_known_stance_force():
    """Synthetic log: alternating 0.3 s stances with F_x = 10 sin(2π phase) on the stance
    foot; the binned profile is the bin mean of that curve."""
    t = np.arange(0.0, 4.0, 0.001)
    log = pd.DataFrame({"time": t})
    for side, t0 in (("left", 0.1), ("right", 0.45)):
        ph = ((t - t0) % 0.7) / 0.3
        on = (ph < 1.0) & (t >= t0)
        log[f"{side}_contact"] = on.astype(float)
        log[f"{side}_grf_x"] = np.where(on, 10.0 * np.sin(2 * np.pi * ph), 0.0)
    prof, n = phase_profile(log, "contact", t_min=0.5)
    assert n >= 8
    edges = np.linspace(0.0, 1.0, N_BINS + 1)
    expect = [10.0 / (2 * np.pi * (b - a)) * (np.cos(2 * np.pi * a) - np.cos(2 * np.pi * b))
              for a, b in zip(edges[:-1], edges[1:])]
    np.testing.assert_allclose(prof, expect, atol=0.6)
    net, _ = phase_profile(log, "contact", net=True, t_min=0.5)
    np.testing.assert_allclose(net, prof, atol=1e-9)       # no double support here


def test_reason_cells_quote_the_ablations(tmp_path):
    doc = {"runs": [], "pairs": {}, "readings": {
        "rigid_grf": {"n_stances": 7, "measured_mean_fz_N": 92.0,
                      "measured_newton": {"com_dz_mm": 0.4},
                      **{k: {"ratio": {"grf_z": 0.5 + 0.05 * i}, "mean_fz_N": 70.0 + i,
                             "other_foot_fz_N": 13.0, "m_g_plus_a_N": 87.0,
                             "com_dz_mm": -25.0, "com_vz_end_mps": -0.34}
                         for i, (k, _) in enumerate(RIGID_KNOBS)}},
        "planar_intrusion": {"n_stances": 7, "granular": {"rmse_mm": 1.38,
                             "grf_z_error_by_phase_N": [0.0] * 10},
                             **{f"planar_{m}": {"rmse_mm": 2.4 + i / 100, "bias_mm": -1.47,
                                                "error_by_phase_mm": [0.0] * 5 + [-2.42] * 5,
                                                "grf_z_error_by_phase_N": [-9.25] * 10,
                                                "knee_error_by_phase_rad": [0.1] * 10}
                                for i, m in enumerate(("model", "measured", "measured_roll",
                                                       "measured_lateral"))}}}}
    p = tmp_path / "g.json"
    p.write_text(json.dumps(doc))
    g = load_gaps(p)
    text = g.rigid_grf()
    assert "contact point sinking as measured 0.80" in text and "76.0 N" in text
    assert "the cause is the pin at the touchdown point" in text
    pl = g.planar_intrusion()
    assert "2.41 mm with the 3-D plant's measured frontal state" in pl and "2.4 mm less" in pl
    empty = load_gaps(tmp_path / "absent.json")
    assert empty is None
    p.write_text(json.dumps({"runs": [], "pairs": {}, "readings": {}}))
    assert "not separated by an ablation yet" in load_gaps(p).planar_intrusion()


def test_replay_only_merge_keeps_the_other_entries(tmp_path):
    """bench/paper_gaps.py --replay-only merges its readings into an existing JSON."""
    from paper_gaps import merge_readings

    p = tmp_path / "gaps.json"
    p.write_text(json.dumps({"runs": [{"knob": "base"}], "readings": {"cot_electrical": 1}}))
    merge_readings(p, {"rigid_grf": {"n_stances": 3}}, "python bench/paper_gaps.py -x")
    doc = json.loads(p.read_text())
    assert doc["runs"] == [{"knob": "base"}]
    assert doc["readings"] == {"cot_electrical": 1, "rigid_grf": {"n_stances": 3}}
    assert doc["merged"] == [{"command": "python bench/paper_gaps.py -x",
                              "readings": ["rigid_grf"]}]


def test_planar_load_knobs_are_opt_in(windows):
    """The default planar replay is the paper's model (force through the contact
    coordinates only, the other foot loaded); ``moment='apply'`` adds the terrain moment
    about the sole-arc centre, ``swing_force='off'`` never loads the other foot."""
    rm, ws = windows
    a = replay_planar(rm, ws[0])
    b = replay_planar(rm, ws[0], moment="drop", swing_force="terrain", diagnostics=True)
    np.testing.assert_array_equal(a["grf_z"], b["grf_z"])
    np.testing.assert_array_equal(a["q_left_knee"], b["q_left_knee"])
    assert "com_z" in b and "com_z" not in a and b["sagittal_q"].shape == (ws[0].n, 7)
    # the COM lies well above the stance contact point
    assert np.all(np.isfinite(b["com_z"])) and 0.2 < b["com_z"][0] - b["sagittal_q"][0, 6] < 0.6
    m = replay_planar(rm, ws[0], moment="apply")
    assert not np.array_equal(a["q_left_knee"], m["q_left_knee"])
    off = replay_planar(rm, ws[0], swing_force="off", diagnostics=True)
    assert np.all(off["other_force"][np.isfinite(off["other_force"])] == 0.0)
    with pytest.raises(ValueError, match="moment must be one of"):
        replay_planar(rm, ws[0], moment="twist")
    with pytest.raises(ValueError, match="swing_force must be one of"):
        replay_planar(rm, ws[0], swing_force="half")


def test_held_plant_holds_the_trunk_yaw(windows):
    """bench/paper_planar.py's hold: a yaw of the trunk since the start gives a restoring
    moment about z of −k ψ and nothing about x; no hold, no wrench."""
    from paper_planar import HOLD_ROT, held_plant

    rm, ws = windows
    w = ws[0]
    plant, held = held_plant(rm, ("yaw",))
    d = plant.new_data(w.q0, np.zeros(rm.biped.model.nv))
    q = d.q.copy()
    psi = 0.01
    quat = pin.Quaternion(pin.rpy.rpyToMatrix(0.0, 0.0, psi)
                          @ pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix())
    q[3:7] = [quat.x, quat.y, quat.z, quat.w]
    wr = d.base_wrench(q, np.zeros(rm.biped.model.nv))
    assert wr[5] == pytest.approx(-HOLD_ROT[0] * psi, rel=1e-6)
    assert abs(wr[3]) < 1e-9 and abs(wr[1]) < 1e-9
    assert held.replay_plant(None)[0] is plant
    free, _ = held_plant(rm, ())
    assert free.new_data(w.q0, w.v0).base_wrench is None
    with pytest.raises(ValueError, match="holds must be among"):
        held_plant(rm, ("pitch",))


def test_planar_load_reason_cell(tmp_path):
    """The planar row quotes the under-load ablation (Newton and the held freedoms)."""
    case = lambda b: {"rmse_mm": 2.0, "bias_mm": b,  # noqa: E731
                      "grf_z_error_by_phase_N": [-1.0] * 9 + [-7.25]}
    load = {"planar_paper": {**case(-1.47), "newton": {"mean_fz_both_N": 98.8,
                                                       "m_g_plus_a_N": 98.9,
                                                       "com_dz_mm": -9.3}},
            "planar_moment": case(-1.38), "held_none": case(0.03), "held_yaw": case(-0.73),
            "held_abduction": case(-0.41), "held_roll": case(0.06),
            "held_lateral": case(0.42), "held_all": case(-0.87),
            "measured_yaw": {"abs_change_mrad": 90.2}}
    p = tmp_path / "g.json"
    p.write_text(json.dumps({"runs": [], "pairs": {}, "readings": {
        "planar_intrusion": {"n_stances": 7}, "planar_load": load}}))
    text = load_gaps(p).planar_intrusion()
    assert "falls 9.3 mm" in text and "trunk yaw -0.73 mm" in text
    assert "7.2 N low" in text and "all four -0.87 mm" in text
    assert "turns 90 mrad about z" in text
    p.write_text(json.dumps({"runs": [], "pairs": {}, "readings": {
        "planar_intrusion": {"n_stances": 7}}}))
    assert "trunk yaw" not in load_gaps(p).planar_intrusion()


def test_planar_only_needs_a_dataset():
    from paper_gaps import main

    with pytest.raises(SystemExit):
        main(["--planar-only"])
