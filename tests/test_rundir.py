"""Run folders: never replaced without overwrite, locked while written, a status file
that tells a dead run from a live one, a final summary on every exit path, provenance."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest

import granular_mpc.runner.run as run_module
from granular_mpc import __version__
from granular_mpc.columns import LOCK_FILE
from granular_mpc.exceptions import OutputError
from granular_mpc.output import OutputLock, pid_alive
from granular_mpc.runlog import read_log
from granular_mpc.runner import run_scenario
from granular_mpc.runner.status import StatusWriter, run_status
from granular_mpc.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
SHORT = ["sim.duration=0.05", "output.flush_every=10", "output.plots=false"]


def _json(path: Path) -> dict:
    return json.loads(path.read_text())


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_a_previous_run_is_kept_without_overwrite(tmp_path):
    out = tmp_path / "r"
    sc = load_scenario("drop_sand", SHORT)
    run_scenario(sc, out, progress=False)
    before = (out / "summary.json").read_text()
    with pytest.raises(OutputError, match="already holds a previous run"):
        run_scenario(sc, out, progress=False)
    assert (out / "summary.json").read_text() == before
    assert not (out / LOCK_FILE).exists()                       # released on refusal too
    res = run_scenario(sc, out, progress=False, overwrite=True)
    assert res.complete and not (out / LOCK_FILE).exists()


def test_summary_and_status_record_version_and_proxsuite_build(tmp_path):
    res = run_scenario(load_scenario("drop_sand", SHORT), tmp_path / "r", progress=False)
    status = _json(res.out_dir / "status.json")
    for doc in (res.summary, _json(res.out_dir / "summary.json"), status):
        assert doc["package_version"] == __version__
        assert doc["proxsuite_build"].startswith("proxsuite_pywrap")
    assert status["state"] == "complete" and status["end"] and status["pid"] == os.getpid()
    st = run_status(res.out_dir)
    assert st.state == "complete" and not st.alive


def test_a_live_lock_refuses_a_second_writer_and_a_stale_one_is_taken_over(tmp_path):
    out = tmp_path / "locked"
    out.mkdir()
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (out / LOCK_FILE).write_text(json.dumps({"pid": sleeper.pid, "host": os.uname().nodename,
                                                 "start": "t0", "command": "other run"}))
        with pytest.raises(OutputError, match=f"in use by PID {sleeper.pid}"):
            run_scenario(load_scenario("drop_sand", SHORT), out, progress=False)
        assert not (out / "summary.json").exists()              # nothing written
    finally:
        sleeper.kill()
        sleeper.wait()
    assert not pid_alive(sleeper.pid)
    with pytest.warns(UserWarning, match=f"stale lock .* PID {sleeper.pid}"):
        res = run_scenario(load_scenario("drop_sand", SHORT), out, progress=False)
    assert res.complete and not (out / LOCK_FILE).exists()


def test_output_lock_is_exclusive_within_a_process(tmp_path):
    with OutputLock(tmp_path):
        with pytest.raises(OutputError, match="already being written by this process"):
            OutputLock(tmp_path).acquire()
    assert not (tmp_path / LOCK_FILE).exists()


def test_status_heartbeat_and_dead_writer(tmp_path):
    w = StatusWriter(tmp_path, interval=0.1).start()
    first = _json(tmp_path / "status.json")["heartbeat"]
    time.sleep(0.35)
    assert _json(tmp_path / "status.json")["heartbeat"] != first     # beating
    assert run_status(tmp_path).state == "running"
    w.finish("interrupted", "interrupted by SIGINT")
    assert run_status(tmp_path).state == "interrupted"
    # a writer that vanished: its PID is gone
    data = _json(tmp_path / "status.json")
    data.update(state="running", pid=_dead_pid(), end=None)
    (tmp_path / "status.json").write_text(json.dumps(data))
    st = run_status(tmp_path)
    assert st.state == "dead" and "no longer runs" in st.reason
    # ... or it is alive but silent (heartbeat stale)
    data.update(pid=os.getpid())
    (tmp_path / "status.json").write_text(json.dumps(data))
    time.sleep(0.3)
    assert run_status(tmp_path, stale_after=0.1).state == "dead"
    assert run_status(tmp_path, stale_after=60).state == "running"


def test_signal_during_start_up_leaves_a_final_summary(tmp_path, monkeypatch):
    real = run_module.RunLog

    def log_then_sigterm(*a, **k):
        os.kill(os.getpid(), signal.SIGTERM)
        return real(*a, **k)

    monkeypatch.setattr(run_module, "RunLog", log_then_sigterm)
    res = run_scenario(load_scenario("drop_sand", SHORT), tmp_path / "r", progress=False)
    assert res.interrupted and res.reason == "interrupted by SIGTERM during start-up"
    assert _json(tmp_path / "r" / "summary.json")["reason"] == res.reason
    assert run_status(tmp_path / "r").state == "interrupted"
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL or callable(
        signal.getsignal(signal.SIGTERM))


def test_start_up_error_leaves_a_final_summary(tmp_path, monkeypatch):
    def broken(*a, **k):
        raise OutputError("disk full (test)")

    monkeypatch.setattr(run_module, "RunLog", broken)
    with pytest.raises(OutputError, match="disk full"):
        run_scenario(load_scenario("drop_sand", SHORT), tmp_path / "r", progress=False)
    summary = _json(tmp_path / "r" / "summary.json")
    assert summary["complete"] is False and summary["reason"].startswith("start-up failed")
    st = run_status(tmp_path / "r")
    assert st.state == "failed" and not (tmp_path / "r" / LOCK_FILE).exists()


def test_two_signals_in_a_row_still_give_a_final_summary(tmp_path):
    sc = load_scenario("drop_sand", ["sim.duration=1.0", "output.flush_every=5",
                                     "output.plots=false"])
    sent = []

    def on_row(row):
        if row["time"] >= 0.02 and not sent:
            for _ in range(2):              # the second one raises at once
                sent.append(row["time"])
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)

    res = run_scenario(sc, tmp_path / "r", progress=False, on_row=on_row)
    summary = _json(tmp_path / "r" / "summary.json")
    assert len(sent) == 2 and summary["reason"] == ("interrupted by SIGINT (second signal: "
                                                    "stopped at once)")
    assert summary["complete"] is False and res.interrupted
    assert run_status(tmp_path / "r").state == "interrupted"
    assert len(read_log(tmp_path / "r")) >= 5


def _cli(*args):
    exe = Path(sys.executable).with_name("granular-mpc")
    return [str(exe), *map(str, args)]


def test_second_cli_writer_is_refused_and_a_killed_run_reads_dead(tmp_path):
    out = tmp_path / "live"
    a = subprocess.Popen(_cli("run", ROOT / "sim" / "drop_sand.yaml", "--set", "sim.duration=60",
                              "--set", "output.flush_every=20", "--out", out, "-q"),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 120
        while not list((out / "log").glob("part-*.parquet")):
            assert a.poll() is None, a.communicate()
            assert time.time() < deadline
            time.sleep(0.1)
        st = run_status(out)
        assert st.state == "running" and st.pid == a.pid
        b = subprocess.run(_cli("run", ROOT / "sim" / "drop_sand.yaml", "--out", out, "-q",
                                "--overwrite"), capture_output=True, text=True, timeout=120)
        assert b.returncode == 2 and f"in use by PID {a.pid}" in b.stderr
        assert "Traceback" not in b.stderr
        a.send_signal(signal.SIGKILL)
        a.wait(timeout=30)
    finally:
        if a.poll() is None:
            a.kill()
    st = run_status(out)
    assert st.state == "dead" and str(a.pid) in st.reason
    assert _json(out / "summary.json")["reason"] == "running"       # what SIGKILL leaves
    assert len(read_log(out)) >= 20                                  # the log stays readable
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        c = subprocess.run(_cli("run", ROOT / "sim" / "drop_sand.yaml", "--set",
                                "sim.duration=0.02", "--set", "output.plots=false", "--out",
                                out, "-q", "--overwrite"), capture_output=True, text=True,
                           timeout=120)
    assert c.returncode == 0, c.stderr
    assert "stale lock" in c.stderr and run_status(out).state == "complete"


def test_an_unreadable_log_part_mid_run_is_named_with_its_time_gap(tmp_path):
    sc = load_scenario("drop_sand", ["sim.duration=0.05", "output.flush_every=5",
                                     "output.plots=false"])
    out = run_scenario(sc, tmp_path / "r", progress=False).out_dir
    parts = sorted((out / "log").glob("part-*.parquet"))
    assert len(parts) >= 3
    full = read_log(out)
    parts[-1].write_bytes(b"half written")                   # the end: skipped quietly
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(read_log(out)) < len(full)
    parts[1].write_bytes(b"garbled")                          # a hole mid-run: warned
    with pytest.warns(UserWarning, match=rf"{parts[1].name} cannot be read .* t = [0-9.]+ s to "
                                         r"[0-9.]+ s is missing"):
        read_log(out)
