"""granular_mpc.validation.restarts (and the segmented replay of replay.granular): a
stance replayed again from the measured state mid-stance."""
from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.robot.model import load_biped
from granular_mpc.validation import load_dataset
from granular_mpc.validation.dataformat.drop import drop_channels
from granular_mpc.validation.prepare import stance_windows
from granular_mpc.validation.replay import (Variant, build_replay_model, model_terrain,
                                            replay_granular)
from granular_mpc.validation.replay.granular import segment_windows
from granular_mpc.validation.restarts import MIN_SEGMENT_SAMPLES, SWING_CLEARANCE, joint_rates

KNEES = ("q_left_knee", "q_right_knee")


@pytest.fixture(scope="module")
def null(workbench_data):
    ds = load_dataset(workbench_data("null", noisy=False))
    biped = load_biped(ds.meta.robot, with_visuals=False)
    rm = build_replay_model(biped, model_terrain("dry_sand"),
                            sample_rate_hz=ds.meta.sample_rate_hz)
    whole = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness)
    cut = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness, segments=2)
    return ds, biped, rm, whole, cut


def test_joint_rates_differentiate_a_quartic_exactly():
    dt = 0.002
    t = np.arange(200) * dt
    coef = np.array([[3.0, -2.0, 0.5, 1.5, 0.1], [-1.0, 4.0, -0.3, 0.2, -0.7]])  # high first
    qa = np.column_stack([np.polyval(c, t) for c in coef])
    for k in (100, 3, 199):                   # the middle, and rows near either end
        expected = [np.polyval(np.polyder(c), t[k]) for c in coef]
        np.testing.assert_allclose(joint_rates(qa, k, dt), expected, rtol=1e-7, atol=1e-9)


def test_restarts_start_from_the_measured_contact_state(null):
    ds, biped, rm, whole, cut = null
    assert all(not w.restarts for w in whole)
    placed = [w for w in cut if w.restarts]
    assert len(placed) >= 0.8 * len(cut)
    for w in placed:
        (r,) = w.restarts
        assert MIN_SEGMENT_SAMPLES <= r.start <= w.n - MIN_SEGMENT_SAMPLES
        assert abs(r.start - w.n / 2) <= 1
        lead, other = r.feet[w.foot], r.feet[1 - w.foot]
        # the stance foot buried at the measured (noise-free) depth and force of that row
        assert lead.in_contact and not other.in_contact
        assert lead.depth == pytest.approx(w.meas["intrusion_z"][r.start - 1], abs=2e-4)
        np.testing.assert_allclose(lead.e.sum(axis=0) * -rm.contact_stiffness,
                                   [w.meas[c][r.start - 1] for c in ("grf_x", "grf_y", "grf_z")],
                                   atol=3.0)
        assert lead.depth_max >= lead.depth and lead.t_stance == pytest.approx(
            w.time[r.start - 1] - w.time[0] + (w.time[1] - w.time[0]), abs=1e-9)
        # the other foot in the air, at least the clearance above its own surface
        assert other.point[2] - other.surface >= SWING_CLEARANCE
        # the same local frame as the window's start: the configuration moved by the
        # measured trunk displacement only
        assert np.linalg.norm(r.q0[:2] - w.q0[:2]) < 0.2


def test_a_restarted_replay_follows_the_plant_closer_after_the_restart(null):
    """Noise-free null data: before the restart the replay is the whole-stance replay,
    sample for sample; after it, it is closer to the plant's own run than the whole-stance
    replay over the same samples."""
    ds, biped, rm, whole, cut = null
    after_whole, after_cut = [], []
    for w0, w in zip(whole, cut):
        if not w.restarts:
            continue
        s = w.restarts[0].start
        a, b = replay_granular(rm, w0, Variant()), replay_granular(rm, w, Variant())
        assert not a["diverged"] and not b["diverged"]
        for c in KNEES:
            np.testing.assert_array_equal(a[c][:s], b[c][:s])
            after_whole.append(a[c][s:] - w.meas[c][s:])
            after_cut.append(b[c][s:] - w.meas[c][s:])
    rms_whole = float(np.sqrt(np.mean(np.concatenate(after_whole) ** 2)))
    rms_cut = float(np.sqrt(np.mean(np.concatenate(after_cut) ** 2)))
    assert rms_cut < 0.5 * rms_whole and rms_cut < 3e-3


def test_segment_windows_cover_the_window_once(null):
    ds, biped, rm, whole, cut = null
    w = next(w for w in cut if w.restarts)
    parts = segment_windows(w)
    assert len(parts) == len(w.restarts) + 1
    np.testing.assert_array_equal(np.concatenate([p.time for p in parts]), w.time)
    np.testing.assert_array_equal(np.concatenate([p.tau for p in parts]), w.tau)
    assert parts[1].q0 is w.restarts[0].q0 and not parts[1].restarts


def test_no_restart_without_measured_intrusion(workbench_data, tmp_path):
    src = workbench_data("null", noisy=False)
    ds = load_dataset(drop_channels(src, tmp_path / "no_intrusion", ["intrusion"]))
    biped = load_biped(ds.meta.robot, with_visuals=False)
    ws = stance_windows(ds, biped, segments=3)
    assert ws and all(not w.restarts for w in ws)



def test_validate_with_restarts_reports_them_and_a_smaller_knee_error(workbench_data, null):
    """End to end on the noise-free null set: ``validate(replay_segments=2)`` says how many
    restarts it placed and its knee RMSE is below the whole-stance replay's."""
    from granular_mpc.validation.replay import validate

    ds, biped, rm, whole, cut = null
    data = workbench_data("null", noisy=False)
    reps = {n: validate(data, None, replay_segments=n, n_boot=20, workers=1, figures=False)
            for n in (1, 2)}
    assert reps[1].report["restarts"] == 0
    assert reps[2].report["restarts"] == sum(len(w.restarts) for w in cut) > 0
    assert reps[2].report["replay_segments"] == 2
    for c in KNEES:
        assert reps[2].rmse("granular", c) < 0.7 * reps[1].rmse("granular", c)


def test_an_encoder_offset_at_its_true_value_restores_a_restarted_replay(null):
    """Data whose left-knee encoder reads 0.05 rad high: every segment starts from the
    inverted (true) angle, so the term at its true value brings the restarted replay back
    to the unbiased data's, in both segments."""
    import dataclasses

    from granular_mpc.effects import effect_info
    from granular_mpc.effects.measurement import register_measurement
    from granular_mpc.validation.replay import effect_variant

    ds, biped, rm, whole, cut = null
    register_measurement()
    info = effect_info("encoder_offset")
    delta = 0.05
    trials = {n: df.assign(q_left_knee=df["q_left_knee"] + delta) for n, df in ds.trials.items()}
    biased = dataclasses.replace(ds, trials=trials)
    wb = stance_windows(biased, biped, contact_stiffness=rm.contact_stiffness, segments=2)
    p = {**info.neutral_params(), "delta_left_knee": delta}
    fixed = effect_variant([(info, p)])
    for k in [i for i, w in enumerate(cut) if w.side == "left" and w.restarts][:3]:
        assert len(wb[k].restarts) == 1
        s = cut[k].restarts[0].start
        ref = replay_granular(rm, cut[k], Variant())["q_left_knee"] - cut[k].meas["q_left_knee"]
        off = replay_granular(rm, wb[k], Variant())["q_left_knee"] - wb[k].meas["q_left_knee"]
        fix = replay_granular(rm, wb[k], fixed)["q_left_knee"] - wb[k].meas["q_left_knee"]
        for part in (slice(0, s), slice(s, None)):
            e_ref, e_off, e_fix = (float(np.sqrt(np.mean(e[part] ** 2))) for e in (ref, off, fix))
            assert e_fix < 0.5 * e_off and e_fix <= 1.2 * e_ref + 1e-3
