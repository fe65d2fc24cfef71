"""The `granular-mpc` command line: runs, Ctrl-C, replays, bad input, file swaps.

Real subprocesses where the behaviour depends on the process (exit codes, signals,
tracebacks on stderr); typer's in-process runner for the many bad-input cases.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from granular_mpc.cli import app
from granular_mpc.runlog import read_log
from granular_mpc.scenario import load_scenario
from granular_mpc.viz.meshcat import read_html_commands

ROOT = Path(__file__).resolve().parent.parent
SIM = ROOT / "sim"
RIGID = str(SIM / "rigid_walk.yaml")
SAND = str(SIM / "sand_walk.yaml")


def cli(*args, timeout=300, cwd=None) -> subprocess.CompletedProcess:
    """Run the console script (the one installed next to this interpreter)."""
    exe = Path(sys.executable).with_name("granular-mpc")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "granular_mpc.cli"]
    return subprocess.run(cmd + [str(a) for a in args], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def test_console_script_is_installed():
    exe = Path(sys.executable).with_name("granular-mpc")
    assert exe.exists(), "pip install -e . should create the granular-mpc console script"
    proc = cli("--help")
    assert proc.returncode == 0
    for command in ("run", "sweep", "view", "synth", "validate", "diagnose", "bench"):
        assert command in proc.stdout


def test_run_writes_the_run_folder(tmp_path):
    out = tmp_path / "run"
    proc = cli("run", RIGID, "--set", "sim.duration=0.6", "--html", "--out", out, "-q")
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and summary["sim_time_s"] > 0
    assert "outputs:" in proc.stdout and "CoT:" in proc.stdout
    assert len(list((out / "plots").glob("*.png"))) >= 4
    assert (out / "animation.html").stat().st_size > 100_000
    assert load_scenario(out / "config.resolved.yaml").sim.duration == 0.6


def test_default_output_folder_is_runs_name_timestamp(tmp_path):
    proc = cli("run", RIGID, "--set", "sim.duration=0.05", "--set", "output.plots=false", "-q",
               cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    runs = list((tmp_path / "runs").iterdir())
    assert len(runs) == 1 and runs[0].name.startswith("rigid_walk-")
    assert (runs[0] / "summary.json").is_file()


@pytest.mark.timing
def test_sigint_halfway_leaves_a_replayable_log_and_an_incomplete_summary(tmp_path):
    out = tmp_path / "interrupted"
    exe = Path(sys.executable).with_name("granular-mpc")
    proc = subprocess.Popen([str(exe), "run", str(SIM / "drop_sand.yaml"), "--set",
                             "sim.duration=60", "--set", "output.flush_every=50",
                             "--out", str(out), "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # two 50-row parts take ≈ 1 s idle; 120 s is a generous bound at load 2
        deadline = time.time() + 120
        while len(list((out / "log").glob("part-*.parquet"))) < 2:
            assert proc.poll() is None, proc.communicate()
            assert time.time() < deadline, "no log part written"
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "interrupted" in stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False
    assert summary["reason"] == "interrupted by SIGINT"
    log = read_log(out)
    assert len(log) >= 100 and summary["sim_time_s"] < 60
    page = tmp_path / "replay.html"
    view = cli("view", out, "--html", page)
    assert view.returncode == 0, view.stderr
    commands = read_html_commands(page)
    assert any(c.get("type") == "set_animation" for c in commands)


def test_set_swaps_plant_and_controller_terrain_independently(tmp_path):
    cases = {(): ("dry_sand", "plant"),
             ("terrain=rigid",): ("rigid", "plant"),
             ("controller.terrain=rigid",): ("dry_sand", "rigid"),
             ("terrain=rigid", "controller.terrain=dry_sand"): ("rigid", "dry_sand")}
    for overrides, (plant, ctrl) in cases.items():
        sc = load_scenario(SAND, list(overrides))
        assert sc.terrain.name == plant and sc.controller.terrain == ctrl
        if ctrl == "plant":
            assert sc.controller_terrain is None
        else:
            assert sc.controller_terrain.name == ctrl
    # end to end: the summary and the resolved file say what each side used
    out = tmp_path / "swap"
    proc = cli("run", SAND, "--set", "controller.terrain=rigid", "--set", "sim.duration=0.1",
               "--set", "output.plots=false", "--out", out, "-q")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["terrain"] == "dry_sand" and summary["terrain_kind"] == "granular"
    assert summary["controller_terrain_model"] == "rigid"
    resolved = yaml.safe_load((out / "config.resolved.yaml").read_text())
    assert resolved["terrain"]["kind"] == "granular"
    assert resolved["controller_terrain"]["kind"] == "rigid"
    # a resolved file swaps again: the inlined controller terrain is replaced
    again = load_scenario(out / "config.resolved.yaml", ["controller.terrain=plant"])
    assert again.controller_terrain is None


# --------------------------------------------------------------------------- bad input
def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


BAD_INPUTS = {
    "malformed YAML": (lambda d: ["run", _write(d, "a.yaml", "robot: yobogo10s\nterrain: [rigid\n")],
                       "malformed YAML at line"),
    "unknown key": (lambda d: ["run", _write(d, "b.yaml", "robot: yobogo10s\nterrain: rigid\ncomand: {speed: 0.2}\n")],
                    "did you mean 'command'"),
    "unknown nested key": (lambda d: ["run", _write(d, "c.yaml", "robot: yobogo10s\nterrain: rigid\nsim: {durration: 1}\n")],
                           "sim.durration"),
    "wrong type": (lambda d: ["run", _write(d, "d.yaml", "robot: yobogo10s\nterrain: rigid\nsim: {duration: long}\n")],
                   "sim.duration"),
    "out of range": (lambda d: ["run", RIGID, "--set", "sim.dt=-1"], "sim.dt"),
    "override of a missing key": (lambda d: ["run", RIGID, "--set", "controller.mpc.horizn=5"],
                                  "did you mean 'horizon'"),
    "override without =": (lambda d: ["run", RIGID, "--set", "sim.duration"], "key.path=value"),
    "missing robot file": (lambda d: ["run", _write(d, "e.yaml", "robot: no_such_bot\nterrain: rigid\n")],
                           "robot file 'no_such_bot' not found"),
    "missing terrain file": (lambda d: ["run", RIGID, "--set", "terrain=wet_clay"],
                             "terrain file 'wet_clay' not found"),
    "missing controller terrain file": (lambda d: ["run", RIGID, "--set", "controller.terrain=wet_clay"],
                                        "controller.terrain"),
    "missing scenario file": (lambda d: ["run", d / "nope.yaml"], "scenario file"),
    "unwritable output folder": (lambda d: ["run", RIGID, "--out", _write(d, "f", "") / "sub"],
                                 "cannot write the output folder"),
    "sweep without sweep section": (lambda d: ["sweep", RIGID], "no 'sweep:' section"),
    "unknown sweep grid key": (lambda d: ["sweep", str(SIM / "velocity_sweep.yaml"), "--set",
                                          "sweep.grid={controller.gait.perod: [0.4]}"],
                               "did you mean 'period'"),
    "unknown backend": (lambda d: ["sweep", str(SIM / "velocity_sweep.yaml"), "--backend", "dask"],
                        "unknown backend"),
    "missing run folder": (lambda d: ["view", d / "no_run"], "no run folder"),
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_is_one_clear_message(case, tmp_path):
    make_args, expected = BAD_INPUTS[case]
    args = make_args(tmp_path)
    res = invoke(*args)
    assert res.exit_code == 2, (res.exit_code, res.output)
    assert res.exception is None or isinstance(res.exception, SystemExit)
    err = res.stderr
    assert "Traceback" not in res.output
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines and lines[0].startswith("error: "), err
    assert sum(ln.startswith("error:") for ln in lines) == 1
    assert expected in err, err
    assert res.stdout == ""


def test_bad_input_in_a_real_process_has_no_traceback_unless_debug(tmp_path):
    bad = _write(tmp_path, "bad.yaml", "robot: yobogo10s\nterrain: rigid\ncomand: {}\n")
    proc = cli("run", bad)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and "Traceback" not in proc.stderr
    assert "did you mean 'command'" in proc.stderr
    debug = cli("run", bad, "--debug")
    assert debug.returncode == 2 and "Traceback" in debug.stderr


def test_bench_runs_scripts_and_prints_their_lines(tmp_path):
    bench = tmp_path / "bench"
    bench.mkdir()
    (bench / "speed.py").write_text(
        "import json, sys\n"
        "print('plant_step: 12.5 us')\n"
        "if '--json' in sys.argv:\n"
        "    open(sys.argv[sys.argv.index('--json') + 1], 'w').write(json.dumps({'plant_step': 12.5}))\n")
    res = cli("bench", "--dir", bench, "--json", tmp_path / "figs")
    assert res.returncode == 0, res.stderr
    assert "plant_step: 12.5 us" in res.stdout
    assert json.loads((tmp_path / "figs" / "speed.json").read_text()) == {"plant_step": 12.5}
    (bench / "broken.py").write_text("raise SystemExit(4)\n")
    res = cli("bench", "--dir", bench)
    assert res.returncode == 1 and "broken.py exited with code 4" in res.stderr


def test_readme_has_two_commands_and_ci_runs_the_test_one():
    readme = (ROOT / "README.md").read_text()
    commands = [ln.strip() for ln in readme.splitlines() if ln.strip().startswith("python3.11 -m venv")]
    assert len(commands) == 2, commands
    run_cmd, test_cmd = commands
    assert "granular-mpc run sim/sand_walk.yaml" in run_cmd and "pytest" in test_cmd
    ci = (ROOT / ".ci" / "run").read_text()
    assert test_cmd in ci.splitlines()
    assert "install-browser.sh" in ci and '"$rc" -eq 5' in ci
    image = ROOT / "docs" / "img" / "sand_walk.png"
    assert "docs/img/sand_walk.png" in readme and image.read_bytes()[:4] == b"\x89PNG"


def test_ci_script_fails_on_pytest_no_tests(tmp_path):
    """.ci/run maps pytest's exit code 5 to a failure (checked with stand-in tools)."""
    repo = tmp_path / "repo"
    (repo / ".ci").mkdir(parents=True)
    shutil.copy(ROOT / ".ci" / "run", repo / ".ci" / "run")
    (repo / ".ci" / "install-browser.sh").write_text("exit 0\n")
    fake = tmp_path / "bin"
    fake.mkdir()
    (fake / "python3.11").write_text(
        "#!/bin/sh\nmkdir -p .venv/bin\n"
        "printf '#!/bin/sh\\nexit 0\\n' > .venv/bin/pip\n"
        "printf '#!/bin/sh\\nexit %s\\n' \"$FAKE_PYTEST_RC\" > .venv/bin/python\n"
        "chmod +x .venv/bin/pip .venv/bin/python\n")
    (fake / "python3.11").chmod(0o755)
    for rc, expected in ((0, 0), (5, 1), (2, 2)):
        env = dict(os.environ, PATH=f"{fake}:{os.environ['PATH']}", FAKE_PYTEST_RC=str(rc))
        proc = subprocess.run(["bash", str(repo / ".ci" / "run")], capture_output=True,
                              text=True, env=env, timeout=60)
        assert proc.returncode == expected, (rc, proc.stdout, proc.stderr)


# ----------------------------------------------------------------------------- issue 13
def _exit_2_no_traceback(res, *needles):
    assert res.exit_code == 2, (res.exit_code, res.output)
    text = res.output
    assert "Traceback" not in text and "pydantic" not in text and "validation error for" not in text
    for n in needles:
        assert n in text, (n, text)


@pytest.fixture()
def data_dir(tmp_path):
    """A folder that does not hold a data set (the bad-input checks come first)."""
    return tmp_path / "no_data"


def test_bad_effect_parameter_is_exit_2_without_a_raw_pydantic_error(tmp_path, data_dir):
    res = invoke("validate", data_dir, "--out", tmp_path / "v", "--effect", "cohesion:suction=abc")
    _exit_2_no_traceback(res, "suction", "abc")


def test_yaml_that_is_not_utf8_or_has_a_duplicate_key_is_named(tmp_path):
    latin = tmp_path / "latin.yaml"
    latin.write_bytes(Path(RIGID).read_bytes() + b"description: caf\xe9\n")
    _exit_2_no_traceback(invoke("run", latin, "--out", tmp_path / "r"), "latin.yaml", "UTF-8")
    dup = tmp_path / "dup.yaml"
    dup.write_text(Path(RIGID).read_text() + "name: again\n")
    _exit_2_no_traceback(invoke("run", dup, "--out", tmp_path / "r"), "dup.yaml",
                         "duplicate key 'name'", "line")
    assert not (tmp_path / "r").exists()


def test_effect_files_that_are_not_python_or_raise_are_named(tmp_path, data_dir):
    txt = tmp_path / "effects.txt"
    txt.write_text("x = 1\n")
    _exit_2_no_traceback(invoke("validate", data_dir, "--out", tmp_path / "v", "--effect-file",
                                txt), "effects.txt", "*.py")
    bad = tmp_path / "bad_effect.py"
    bad.write_text("raise RuntimeError('boom at import')\n")
    _exit_2_no_traceback(invoke("validate", data_dir, "--out", tmp_path / "v", "--effect-file",
                                bad), "bad_effect.py", "RuntimeError", "boom at import")


def test_bad_proxsuite_build_in_the_environment_is_exit_2(tmp_path, monkeypatch):
    monkeypatch.setenv("GRANULAR_MPC_PROXSUITE", "turbo")
    _exit_2_no_traceback(invoke("run", RIGID, "--out", tmp_path / "r"),
                         "GRANULAR_MPC_PROXSUITE", "turbo", "native, generic")


def test_synth_rejects_zero_steps_fast_speeds_and_unknown_noise_prefixes(tmp_path):
    out = tmp_path / "d"
    _exit_2_no_traceback(invoke("synth", SAND, "--out", out, "--steps", "0"), "steps", "at least 1")
    _exit_2_no_traceback(invoke("synth", SAND, "--out", out, "--speeds", "5"), "speed", "1.5")
    _exit_2_no_traceback(invoke("synth", SAND, "--out", out, "--noise", "gfr_=0.5"),
                         "gfr_", "grf_", "q_")
    assert not out.exists()


def test_validate_rejects_a_negative_worker_count(tmp_path, data_dir):
    res = invoke("validate", data_dir, "--out", tmp_path / "v", "--workers", "-3")
    assert res.exit_code == 2 and "greater than or equal to 1" in res.output


def test_replay_segments_below_one_or_off_the_granular_model_are_exit_2(tmp_path, data_dir):
    out = tmp_path / "v"
    _exit_2_no_traceback(invoke("validate", data_dir, "--out", out, "--replay-segments", "0"),
                         "replay_segments", "integer ≥ 1")
    _exit_2_no_traceback(invoke("validate", data_dir, "--out", out, "--model", "rigid",
                                "--replay-segments", "2"), "replay_segments", "granular")
    _exit_2_no_traceback(invoke("diagnose", data_dir, "--out", tmp_path / "d",
                                "--replay-segments", "-1"), "replay_segments", "integer ≥ 1")
    assert not out.exists() and not (tmp_path / "d").exists()


def test_missing_data_folder_is_exit_2(tmp_path, data_dir):
    _exit_2_no_traceback(invoke("validate", data_dir, "--out", tmp_path / "v"), "no_data")


def test_synth_never_replaces_measured_data_or_a_foreign_folder(tmp_path):
    measured = tmp_path / "measured"
    measured.mkdir()
    (measured / "meta.yaml").write_text("schema_version: 1\ntrials:\n  t1: {file: t1.csv}\n")
    (measured / "t1.csv").write_text("time\n0\n")
    for extra in ([], ["--overwrite"]):
        _exit_2_no_traceback(invoke("synth", SAND, "--out", measured, "--steps", "1", *extra),
                             "measured data", "never overwritten")
    assert (measured / "t1.csv").read_text() == "time\n0\n"
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    _exit_2_no_traceback(invoke("synth", SAND, "--out", foreign, "--steps", "1"),
                         "not empty", "notes.txt")
    assert [p.name for p in foreign.iterdir()] == ["notes.txt"]


def test_garbled_urdf_is_exit_2_naming_the_file(tmp_path):
    robot = yaml.safe_load((ROOT / "models" / "yobogo10s.yaml").read_text())
    (tmp_path / "yobogo10s.urdf").write_bytes((ROOT / "models" / "yobogo10s.urdf").read_bytes()[:300])
    (tmp_path / "robot.yaml").write_text(yaml.safe_dump(robot))
    scenario = yaml.safe_load((SIM / "drop_sand.yaml").read_text())
    scenario["robot"] = str(tmp_path / "robot.yaml")
    (tmp_path / "drop.yaml").write_text(yaml.safe_dump(scenario))
    _exit_2_no_traceback(invoke("run", tmp_path / "drop.yaml", "--out", tmp_path / "r"),
                         "yobogo10s.urdf")
    assert not (tmp_path / "r").exists()


def test_terrain_force_with_python_if_is_exit_2_naming_effect_file_and_fix(tmp_path):
    """Python control flow on the symbolic patch state (the force is traced once, on
    CasADi symbols) is one bad-input message, not CasADi's "truth value" RuntimeError.
    A subprocess: the effect must not stay registered in this test process."""
    bad = tmp_path / "if_foot.py"
    bad.write_text(
        "from granular_mpc.effects import Param, register_effect\n"
        "@register_effect('if_foot_cli', params={'a': Param(0.3, 0.0, 0.9, '-', 'x')})\n"
        "def if_foot_cli(o, s, p):\n"
        "    if s.foot < 0.5:\n"
        "        return (-p['a'] * s.f_terrain[0], 0.0, 0.0)\n"
        "    return (0.0, 0.0, 0.0)\n")
    res = cli("synth", SAND, "--speeds", "0.15", "--steps", "1", "--effect-file", bad,
              "--effect", "if_foot_cli:a=0.5", "--out", tmp_path / "data")
    assert res.returncode == 2, (res.returncode, res.stderr)
    err = res.stderr
    assert "Traceback" not in err and "unexpected RuntimeError" not in err
    assert str(bad) in err and "'if_foot_cli'" in err and "o.if_else(cond, a, b)" in err
