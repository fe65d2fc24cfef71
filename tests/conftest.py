"""Shared fixtures: models are immutable, so build them once per test session.

Every closed loop in the suite runs on ProxSuite's generic (SSE2, bit-reproducible) build,
so every machine tests the same realisation (docs/user-guide.md §3). The build is fixed
when proxsuite is first imported in a process, hence here, before any test module is
collected; a test that wants the default build sets the variable in a subprocess.
"""
from __future__ import annotations

import os

os.environ.setdefault("GRANULAR_MPC_PROXSUITE", "generic")

import pytest  # noqa: E402  (the environment must be set before proxsuite is imported)

from granular_mpc.config import load_robot, load_terrain
from granular_mpc.robot import Biped
from granular_mpc.terrain import build_terrain


@pytest.fixture(scope="session")
def robot_config():
    return load_robot("yobogo10s")


@pytest.fixture(scope="session")
def biped(robot_config):
    return Biped.from_config(robot_config)


@pytest.fixture(scope="session")
def sand(robot_config):
    return build_terrain(load_terrain("dry_sand"), robot_config)


@pytest.fixture(scope="session")
def rigid(robot_config):
    return build_terrain(load_terrain("rigid"), robot_config)


# --------------------------------------------------------------------------------------
# Validation workbench: small synthetic data sets, generated once per session
# (tests/test_synth.py, test_replay.py, test_diagnose.py). Each plant run is noise-free;
# noisy copies add the realistic sensor model (level 1).
# --------------------------------------------------------------------------------------

#: three speeds × ≈ 7 stances: enough trials for trial-grouped cross-validation
WB_SPEEDS = (0.15, 0.25, 0.35)
WB_STEPS = 7
#: a hidden effect outside the library (registered for the synth only, never a candidate)
WB_HIDDEN = "_test_hidden_skew"


def _register_hidden():
    from granular_mpc.terrain.effects import Param, register_effect, registered_effects

    if WB_HIDDEN in registered_effects():
        return

    @register_effect(WB_HIDDEN, params={"k": Param(12.0, 0.0, 200.0, "N·s/m", "")})
    def _skew(o, s, p):
        """Sideways push proportional to the forward velocity of the sole."""
        return (0.0, -p["k"] * s.v_c[0] * s.in_contact, 0.0)


WB_CASES = {
    "null": dict(effects=[], seed=21, overrides=[]),
    "cohesion": dict(effects=["cohesion:suction=3000"], seed=22, overrides=[]),
    "zeta_off": dict(effects=[], seed=23, overrides=["terrain.zeta=1.768"]),
    "unknown": dict(effects=[f"{WB_HIDDEN}:k=18"], seed=24, overrides=[]),
}


@pytest.fixture(scope="session")
def workbench_data(tmp_path_factory):
    """``workbench_data(name, noisy=True)`` → path of a cached data set (see WB_CASES)."""
    from granular_mpc.validation.synth import noisy_copy, synthesize

    root = tmp_path_factory.mktemp("workbench")
    cache: dict = {}

    def get(name: str, noisy: bool = True):
        key = (name, noisy)
        if key in cache:
            return cache[key]
        clean = root / f"{name}_clean"
        if (name, False) not in cache:
            case = WB_CASES[name]
            if name == "unknown":
                _register_hidden()
            synthesize("sand_walk", clean, speeds=WB_SPEEDS, steps=WB_STEPS, seed=case["seed"],
                       effects=case["effects"], noise=0.0, format="parquet",
                       overrides=case["overrides"])
            cache[(name, False)] = clean
        if noisy:
            cache[key] = noisy_copy(clean, root / f"{name}_noisy", 1.0, seed=WB_CASES[name]["seed"])
        return cache[key]

    return get


@pytest.fixture(scope="session")
def library_candidates():
    """The built-in effects library (tests pass it explicitly: other tests register
    effects of their own in the same session)."""
    return ["inertial_drag", "cohesion", "depth_hardening", "elastic_unloading",
            "joint_friction", "force_sensor_bias", "terrain_slope"]


@pytest.fixture(scope="session")
def workbench_diagnosis(workbench_data, library_candidates, tmp_path_factory):
    """``workbench_diagnosis(name)`` → a cached :class:`Diagnosis` of the noisy data set."""
    from granular_mpc.validation.diagnose import diagnose

    root = tmp_path_factory.mktemp("workbench_diag")
    cache: dict = {}

    def get(name: str):
        if name not in cache:
            cache[name] = diagnose(workbench_data(name), root / name, seed=0, n_boot=100,
                                   candidates=library_candidates)
        return cache[name]

    return get
