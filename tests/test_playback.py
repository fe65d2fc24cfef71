"""Joint playback (``mode: playback``, granular_mpc.runner.playback)."""

from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.columns import joint_columns
from granular_mpc.exceptions import ConfigError
from granular_mpc.runlog import RunLog, read_log
from granular_mpc.runner import JointPlayback, JointReference, run_scenario
from granular_mpc.scenario import load_scenario

JOINTS = ("a", "b")


def write_log(folder, time, q, dq, tau, drop=None):
    with RunLog(folder / "log") as log:
        for i, t in enumerate(time):
            row = {"time": float(t)}
            for kind, arr in (("q", q), ("dq", dq), ("tau", tau)):
                for c, x in zip(joint_columns(JOINTS, kind), arr[i]):
                    if c != drop:
                        row[c] = float(x)
            log.append(row)


def test_reference_interpolates_and_holds_after_the_end(tmp_path):
    t = np.array([0.0, 0.1, 0.3])
    q = np.array([[0.0, 1.0], [1.0, 3.0], [2.0, 3.0]])
    write_log(tmp_path, t, q, 2 * q, 3 * q)
    ref = JointReference.from_run(tmp_path, JOINTS)
    qr, dqr, taur = ref.at(0.2)              # half-way between rows 1 and 2
    np.testing.assert_allclose(qr, [1.5, 3.0])
    np.testing.assert_allclose(dqr, [3.0, 6.0])
    np.testing.assert_allclose(taur, [4.5, 9.0])
    np.testing.assert_array_equal(ref.at(0.1)[0], q[1])     # exactly at a row: that row
    q_end, dq_end, tau_end = ref.at(5.0)
    np.testing.assert_array_equal(q_end, q[-1])
    assert not dq_end.any() and not tau_end.any()
    assert ref.window_s is None and ref.duration == 0.3


def test_pd_law_clips_and_adds_the_feedforward(tmp_path):
    t = np.array([0.0, 1.0])
    q = np.array([[1.0, 0.0], [1.0, 0.0]])
    write_log(tmp_path, t, q, 0 * q, np.array([[0.5, -0.5], [0.5, -0.5]]))
    ref = JointReference.from_run(tmp_path, JOINTS)
    pd_only = JointPlayback(ref, kp=10.0, kd=1.0, feedforward=False, tau_max=np.array([5.0, 5.0]))
    tau = pd_only.torque(0.5, np.array([0.8, 0.0]), np.array([0.0, 2.0]))
    np.testing.assert_allclose(tau, [10.0 * 0.2, -1.0 * 2.0])
    with_ff = JointPlayback(ref, kp=10.0, kd=1.0, feedforward=True, tau_max=np.array([1.0, 5.0]))
    tau = with_ff.torque(0.5, np.array([0.8, 0.0]), np.array([0.0, 2.0]))
    np.testing.assert_allclose(tau, [1.0, -2.5])         # 2.5 clipped to the 1 N·m limit


def test_a_missing_joint_column_is_named(tmp_path):
    t = np.array([0.0, 0.1])
    q = np.zeros((2, 2))
    write_log(tmp_path, t, q, q, q, drop="dq_b")
    with pytest.raises(ConfigError, match="dq_b") as err:
        JointReference.from_run(tmp_path, JOINTS)
    assert err.value.key == "playback.reference"
    with pytest.raises(ConfigError, match="not a folder"):
        JointReference.from_run(tmp_path / "nowhere", JOINTS)


def test_playback_mode_needs_a_reference():
    with pytest.raises(ConfigError, match="playback.reference"):
        load_scenario("sim/paper_playback.yaml", ["playback.reference=null"])


def test_torque_replay_repeats_the_recorded_run(tmp_path):
    """With k_p = k_d = 0 and the recorded torques fed forward at the recording's own tick
    times, the plant repeats the recorded walk exactly (same plant, same start)."""
    rec = tmp_path / "rec"
    run_scenario(load_scenario("sim/rigid_walk.yaml", ["sim.duration=0.8"]), rec, progress=False)
    s = run_scenario(load_scenario("sim/rigid_walk.yaml", [
        "sim.duration=0.8", "mode=playback", f"playback.reference={rec}", "playback.kp=0",
        "playback.kd=0", "playback.feedforward=true"]), tmp_path / "replay", progress=False).summary
    a, b = read_log(rec), read_log(tmp_path / "replay")
    cols = [c for c in a.columns if c.startswith(("q_", "base_", "tau_"))]
    assert len(a) == len(b) == 401
    np.testing.assert_array_equal(a[cols].to_numpy(), b[cols].to_numpy())
    assert s["mode"] == "playback" and not s["fell"]
    # the PD alone (no feed-forward) does not hold the gait: a different, failing walk
    s2 = run_scenario(load_scenario("sim/rigid_walk.yaml", [
        "sim.duration=0.8", "mode=playback", f"playback.reference={rec}"]),
        tmp_path / "pd", progress=False).summary
    c = read_log(tmp_path / "pd")
    assert np.abs(c[cols].to_numpy() - a[cols].to_numpy()).max() > 1e-3
    assert s2["mode"] == "playback"
