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

from workbench import LIBRARY, WB_CASES, diagnose_case, make_clean  # noqa: E402


@pytest.fixture(scope="session")
def workbench_data(tmp_path_factory):
    """``workbench_data(name, noisy=True, noise_seed=None)`` → path of a cached data set
    (tests/workbench.py: WB_CASES; noise seed default: the case's plant seed)."""
    from granular_mpc.validation.synth import noisy_copy

    root = tmp_path_factory.mktemp("workbench")
    cache: dict = {}

    def get(name: str, noisy: bool = True, noise_seed: int | None = None):
        seed = WB_CASES[name]["seed"] if noise_seed is None else int(noise_seed)
        key = (name, seed if noisy else None)
        if key in cache:
            return cache[key]
        if (name, None) not in cache:
            cache[(name, None)] = make_clean(name, root / f"{name}_clean")
        if noisy:
            cache[key] = noisy_copy(cache[(name, None)], root / f"{name}_noisy_{seed}", 1.0,
                                    seed=seed)
        return cache[key]

    return get


@pytest.fixture(scope="session")
def library_candidates():
    """The built-in effects library (tests pass it explicitly: other tests register
    effects of their own in the same session)."""
    return list(LIBRARY)


@pytest.fixture(scope="session")
def workbench_diagnosis(workbench_data, tmp_path_factory):
    """``workbench_diagnosis(name, noise_seed=None)`` → a cached :class:`Diagnosis` of the
    noisy data set. At the default noise seed the candidates are the library plus the
    case's user terms (tests/workbench.py: case_candidates) and figures are written; at
    other noise seeds (the multi-seed recovery test) the library alone, no figures.
    ``workbench_diagnosis.warnings[name]``: the UserWarnings the default diagnosis raised."""
    root = tmp_path_factory.mktemp("workbench_diag")
    cache: dict = {}

    def get(name: str, noise_seed: int | None = None):
        default = noise_seed is None or noise_seed == WB_CASES[name]["seed"]
        key = (name, None if default else int(noise_seed))
        if key not in cache:
            tag = name if default else f"{name}_noise{noise_seed}"
            d, caught = diagnose_case(name, workbench_data(name, noise_seed=noise_seed),
                                      root / tag, user_terms=default, figures=default)
            cache[key] = d
            if default:
                get.warnings[name] = caught
        return cache[key]

    get.warnings = {}
    return get
