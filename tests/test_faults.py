"""Fault injection: runs and sweeps stopped by SIGINT, SIGTERM or SIGKILL at random
(seeded) moments leave a readable log, a truthful status and no orphan process; a
SIGTERM to a sweep stops its workers, drops the queued runs and writes sweep.csv."""
from __future__ import annotations

import json
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import psutil
import pytest
import yaml

from granular_mpc.runlog import read_log
from granular_mpc.runner.status import run_status

ROOT = Path(__file__).resolve().parent.parent
EXE = Path(sys.executable).with_name("granular-mpc")


def _drop_sweep(tmp_path: Path, n_runs: int) -> Path:
    """A sweep file of ``n_runs`` long drop runs (they never end by themselves in time)."""
    data = yaml.safe_load((ROOT / "sim" / "drop_sand.yaml").read_text())
    data["name"] = "drop_sweep"
    data["output"] = {"flush_every": 20}
    data["sweep"] = {"speeds": [0.1 * (k + 1) for k in range(n_runs)], "terrains": ["dry_sand"],
                     "duration": 60.0}
    path = tmp_path / "drop_sweep.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _wait_for_logs(out: Path, n: int, proc: subprocess.Popen, timeout: float = 150.0) -> None:
    """Wait until ``n`` different run folders under ``out`` have a log part."""
    deadline = time.time() + timeout
    while len({p.parent.parent for p in out.glob("**/log/part-*.parquet")}) < n:
        assert proc.poll() is None, proc.communicate()
        assert time.time() < deadline, f"fewer than {n} log parts in {out}"
        time.sleep(0.1)


def _descendants(pid: int) -> list[psutil.Process]:
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def _assert_no_orphans(children: list[psutil.Process], timeout: float = 15.0) -> None:
    deadline = time.time() + timeout
    alive = children
    while alive and time.time() < deadline:
        alive = [p for p in alive if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        time.sleep(0.1)
    assert not alive, f"orphan processes: {[p.pid for p in alive]}"


def test_sigterm_stops_a_sweep_drops_queued_runs_and_writes_the_table(tmp_path):
    out = tmp_path / "sweep"
    proc = subprocess.Popen([str(EXE), "sweep", str(_drop_sweep(tmp_path, 3)), "--workers", "2",
                             "--out", str(out), "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for_logs(out / "runs", 2, proc)
        children = _descendants(proc.pid)
        proc.send_signal(signal.SIGTERM)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, stderr
    assert "Traceback" not in stderr and "interrupted by SIGTERM" in stderr
    table = pd.read_csv(out / "sweep.csv")
    assert len(table) == 2                                   # the third run was dropped
    assert set(table["state"]) == {"interrupted"} and not table["complete"].any()
    assert all(r.startswith("interrupted by SIGTERM") for r in table["reason"])
    started = sorted(p.name for p in (out / "runs").iterdir() if any(p.iterdir()))
    assert started == sorted(table["run"])
    for name in table["run"]:
        assert run_status(out / "runs" / name).state == "interrupted"
        assert len(read_log(out / "runs" / name)) >= 20
    assert run_status(out).state == "interrupted"
    assert not (out / "cot_vs_speed.png").exists()           # no plot of interrupted runs
    _assert_no_orphans(children)


# the sweep's SIGTERM: the test above; a sweep's SIGINT
# takes the same path (both are forwarded to the workers); a run's SIGINT: test_cli.py
CASES = [("run", sig) for sig in (signal.SIGTERM, signal.SIGKILL)] \
    + [("sweep", signal.SIGKILL)]


@pytest.mark.parametrize("kind,sig", CASES, ids=[f"{k}-{s.name}" for k, s in CASES])
def test_killed_at_a_random_moment(kind, sig, tmp_path):
    rng = random.Random(f"{kind}-{sig.name}")                # seeded per case
    delay = rng.uniform(0.0, 1.5)
    out = tmp_path / "out"
    if kind == "run":
        cmd = [str(EXE), "run", str(ROOT / "sim" / "drop_sand.yaml"), "--set", "sim.duration=60",
               "--set", "output.flush_every=20", "--set", "output.plots=false", "--out",
               str(out), "-q"]
    else:
        cmd = [str(EXE), "sweep", str(_drop_sweep(tmp_path, 2)), "--workers", "2", "--out",
               str(out), "-q"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for_logs(out, 1, proc)
        time.sleep(delay)
        children = _descendants(proc.pid)
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    expected = {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGKILL: -9}[sig]
    assert proc.returncode == expected, stderr
    assert "Traceback" not in stderr
    run_dirs = [out] if kind == "run" else [p for p in (out / "runs").iterdir()
                                            if (p / "status.json").exists()]
    assert run_dirs
    for d in run_dirs:
        assert len(read_log(d)) >= 1                          # readable after any signal
        st = run_status(d)
        summary = json.loads((d / "summary.json").read_text())
        if sig == signal.SIGKILL:
            assert st.state == "dead" and summary["reason"] == "running"
        else:
            assert st.state == "interrupted" and summary["complete"] is False
            assert summary["reason"].startswith(f"interrupted by {sig.name}")
    if kind == "sweep":
        assert run_status(out).state == ("dead" if sig == signal.SIGKILL else "interrupted")
        if sig != signal.SIGKILL:
            assert len(pd.read_csv(out / "sweep.csv")) == len(run_dirs)
    _assert_no_orphans(children)
