"""The fast path (granular_mpc.dynamics.select and its users): the compiled plant steps
the replays, the closed loop and ``synth`` where it models everything asked for, the
reference plant where it does not (with the reason), and both give the same results."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from dataclasses import replace

import numpy as np
import pytest

from granular_mpc.config import SimConfig, load_terrain
from granular_mpc.dynamics import FastPlant, Plant
from granular_mpc.dynamics.select import (PLANT_ENV, compiled_unsupported,
                                          default_plant_choice, select_plant)
from granular_mpc.effects import effect_info
from granular_mpc.exceptions import ConfigError
from granular_mpc.robot import load_biped
from granular_mpc.runner import build_simulation, closed_loop
from granular_mpc.scenario import load_scenario
from granular_mpc.terrain import build_terrain
from granular_mpc.validation.dataformat import load_dataset
from granular_mpc.validation.prepare import stance_windows
from granular_mpc.validation.replay import (Variant, build_replay_model, effect_variant,
                                            model_terrain, replay_granular,
                                            resolve_effect_specs)


# ------------------------------------------------------------------ the choice
def test_select_plant_compiled_reference_and_fallbacks(biped, sand, robot_config):
    """compiled → FastPlant; reference → the Plant itself; a track terrain and
    sim.actuators fall back to the reference plant with the reason named."""
    plant = Plant(biped, sand, SimConfig())
    fast, choice = select_plant(plant, "compiled")
    assert isinstance(fast, FastPlant) and choice.resolved == "compiled" and not choice.note
    ref, choice = select_plant(plant, "reference")
    assert ref is plant and choice.resolved == "reference" and not choice.reason
    act = Plant(biped, sand, SimConfig.model_validate({"actuators": {"friction": {"enabled": True}}}))
    same, choice = select_plant(act, "compiled")
    assert same is act and choice.resolved == "reference" and "sim.actuators" in choice.note
    track = Plant(biped, build_terrain(load_terrain("paper_track"), robot_config), SimConfig())
    assert "track" in compiled_unsupported(track)
    same, choice = select_plant(track, "compiled")
    assert same is track and "track" in choice.note
    with pytest.raises(ConfigError, match="unknown plant"):
        select_plant(plant, "fastest")


def test_untraceable_joint_effect_falls_back_named(biped, rigid):
    """A joint effect CasADi cannot trace: the reference plant steps, the reason names it."""
    def floats_only(q_a, dq_a):
        return np.array([-0.1 * float(x) for x in dq_a])

    plant = Plant(biped, rigid, SimConfig(), joint_effects=(floats_only,))
    same, choice = select_plant(plant, "compiled")
    assert same is plant and choice.resolved == "reference" and "joint effect" in choice.reason


def test_environment_variable_sets_the_default(monkeypatch):
    monkeypatch.delenv(PLANT_ENV, raising=False)
    assert default_plant_choice() == "compiled"
    monkeypatch.setenv(PLANT_ENV, "reference")
    assert default_plant_choice() == "reference"
    monkeypatch.setenv(PLANT_ENV, "gpu")
    with pytest.raises(ConfigError, match=PLANT_ENV):
        default_plant_choice()


# ------------------------------------------------------------------ the closed loop
def _short_run(plant: str, seconds: float = 0.25):
    sc = load_scenario("sim/sand_walk.yaml", [f"sim.duration={seconds}", f"sim.plant={plant}"])
    sim = build_simulation(sc)
    state = sim.new_state()
    rows = list(closed_loop(sim, state))
    return sim, state, rows


def test_closed_loop_on_both_plants_agrees():
    """0.25 s of the README's sand walk (standing, weight on the sand, first MPC and WBC
    ticks) on the compiled and on the reference plant: the choice is recorded and the log
    rows agree (joint angles to 1e-7 rad, forces to 1e-3 N)."""
    sim_c, st_c, rows_c = _short_run("compiled")
    sim_r, st_r, rows_r = _short_run("reference")
    assert isinstance(sim_c.plant, FastPlant) and sim_c.plant_choice.resolved == "compiled"
    assert isinstance(sim_r.plant, Plant) and sim_r.plant_choice.resolved == "reference"
    assert len(rows_c) == len(rows_r) > 10
    np.testing.assert_allclose(st_c.plant.q, st_r.plant.q, rtol=0, atol=1e-7)
    for rc, rr in zip(rows_c, rows_r):
        for key in ("q_left_knee", "q_right_hip_pitch", "base_z", "grf_z", "left_grf_z"):
            if key in rc:
                assert rc[key] == pytest.approx(rr[key], abs=1e-3 if "grf" in key else 1e-7)
    assert max(r.get("left_grf_z", 0.0) for r in rows_c) > 50.0      # really on the sand


# ------------------------------------------------------------------ the replay
@pytest.fixture(scope="module")
def replay_setup(workbench_data):
    ds = load_dataset(workbench_data("null", noisy=False))
    biped = load_biped(ds.meta.robot, with_visuals=False)
    models = {p: build_replay_model(biped, model_terrain("dry_sand"),
                                    sample_rate_hz=ds.meta.sample_rate_hz,
                                    terrain_effects=["cohesion"], plant=p)
              for p in ("compiled", "reference")}
    ws = stance_windows(ds, biped, contact_stiffness=models["compiled"].contact_stiffness)
    return models, ws


REPLAY_VARIANTS = {
    "calibrated": Variant(),
    "cohesion_touchdown": Variant(theta={"cohesion.suction": 3000.0, "touchdown_depth": 0.002}),
    "joint_friction": effect_variant(resolve_effect_specs(
        [{"name": "joint_friction", "params": {"coulomb": 0.3, "viscous": 0.05}}])),
}


@pytest.mark.parametrize("name", list(REPLAY_VARIANTS))
def test_replay_on_both_plants_agrees(replay_setup, name):
    """Four stance windows replayed on the compiled and the reference plant (both feet's
    measured contact state set through ``d.contact.feet[i]``): every channel agrees.
    Measured (3 speeds × 7 stances data set): joint angles ≤ 2e-10 rad (joint friction
    8e-9), intrusion ≤ 3e-11 m (1e-9), forces ≤ 6e-6 N (1e-3 N: CasADi's tanh vs NumPy's
    in the last bit, amplified by the stiff contact spring)."""
    models, ws = replay_setup
    variant = REPLAY_VARIANTS[name]
    fast, choice = models["compiled"].replay_plant(variant)
    assert isinstance(fast, FastPlant) and choice.resolved == "compiled"
    ref, choice = models["reference"].replay_plant(variant)
    assert isinstance(ref, Plant) and choice.resolved == "reference"
    for w in ws[:4]:
        a = replay_granular(models["reference"], w, variant)
        b = replay_granular(models["compiled"], w, variant)
        assert a["diverged"] == b["diverged"] is False
        for key, x in a.items():
            if key == "diverged":
                continue
            tol = 5e-3 if ("grf" in key) else 1e-7
            np.testing.assert_allclose(b[key], x, rtol=0, atol=tol, err_msg=key)
        assert np.nanmax(np.abs(a["grf_z"])) > 20.0          # a real stance


def test_a_diverging_replay_stops_alike_on_both_plants(replay_setup):
    """Torques far beyond the motors' make the replay diverge: both plants flag it and
    leave the samples after the divergence undefined (NaN) from the same sample on."""
    models, ws = replay_setup
    w = replace(ws[0], tau=ws[0].tau * 400.0)
    a = replay_granular(models["reference"], w, Variant())
    b = replay_granular(models["compiled"], w, Variant())
    assert a["diverged"] is True and b["diverged"] is True
    col = next(k for k in a if k.startswith("q_"))
    n_a, n_b = int(np.isfinite(a[col]).sum()), int(np.isfinite(b[col]).sum())
    assert n_a == n_b < w.n


def test_replay_falls_back_for_an_uncompiled_joint_effect(replay_setup):
    """A variant with a joint effect the compiled model does not carry replays on the
    reference plant, and the choice names the effect."""
    models, _ = replay_setup
    info = effect_info("joint_friction")
    stranger = replace(info, name="not_compiled_friction")
    variant = Variant(joints=((stranger, info.resolve_params({})),))
    plant, choice = models["compiled"].replay_plant(variant)
    assert isinstance(plant, Plant) and "not_compiled_friction" in choice.reason


# ------------------------------------------------------------------ the build cache
_BUILD = textwrap.dedent("""
    import casadi as ca, sys
    from granular_mpc.codegen import compile_functions
    x = ca.SX.sym("x", 3)
    f = ca.Function("fp_lock_probe", [x], [ca.sin(x) * {salt} + x ** 2])
    g = compile_functions("probe", [f])["fp_lock_probe"]
    print(float(g([1.0, 2.0, 3.0])[2]))
""")


def test_concurrent_builds_are_safe(tmp_path):
    """Three processes needing the same new library at once: one compiles (one line on
    stderr), the others wait for it; all load a working library."""
    env = dict(os.environ, GRANULAR_MPC_CACHE=str(tmp_path))
    salt = 1.0 + (os.getpid() % 1000) / 1e4
    procs = [subprocess.Popen([sys.executable, "-c", _BUILD.format(salt=salt)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(3)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    expected = np.sin(3.0) * salt + 9.0
    assert all(float(o.strip()) == pytest.approx(expected, rel=1e-12) for o, _ in outs)
    lines = [ln for _, e in outs for ln in e.splitlines() if "compiling probe" in ln]
    assert len(lines) == 1
    assert len(list(tmp_path.glob("probe_*.so"))) == 1
    assert not list(tmp_path.glob("*.tmp"))


def test_without_a_c_compiler_the_reference_plant_steps_and_says_why(monkeypatch):
    """CasADi's interpreter is slower than Pinocchio: no compiler → the reference plant."""
    monkeypatch.setenv("GRANULAR_MPC_JIT", "0")
    sim = build_simulation(load_scenario("sand_walk", ["sim.duration=0.1", "sim.plant=reference"]))
    plant, choice = select_plant(sim.plant, "compiled")
    assert plant is sim.plant
    assert (choice.requested, choice.resolved) == ("compiled", "reference")
    assert "C compiler" in choice.reason
