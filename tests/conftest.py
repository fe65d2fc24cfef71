"""Shared fixtures: models are immutable, so build them once per test session.

Every closed loop in the suite runs on ProxSuite's generic (SSE2, bit-reproducible) build,
so every machine tests the same realisation (docs/user-guide.md §3). The build is fixed
when proxsuite is first imported in a process, hence here, before any test module is
collected; a test that wants the default build sets the variable in a subprocess.
"""
from __future__ import annotations

import os

os.environ.setdefault("GRANULAR_MPC_PROXSUITE", "generic")
# One BLAS thread in every process of the run (xdist workers and the subprocesses tests
# start inherit it): two workers on two cores, each with OpenBLAS's own threads,
# oversubscribe the machine (measured: the MPC's condensation 8–30 ms instead of 0.4 ms).
# The closed loop already runs on one BLAS thread (runner/loop.py).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest  # noqa: E402  (the environment must be set before proxsuite is imported)

from granular_mpc.config import load_robot, load_terrain
from granular_mpc.robot import Biped
from granular_mpc.terrain import build_terrain


#: most xdist workers `-n auto` starts (each imports the whole stack: ≈ 0.5 GB)
MAX_WORKERS = 4


def pytest_xdist_auto_num_workers(config):
    """Workers for ``-n auto`` (pyproject.toml's addopts): one per usable CPU (at most
    :data:`MAX_WORKERS`) when the run names a folder or nothing (the whole suite), none
    (serial, no start-up cost) when it names only files or test ids, or on one CPU.
    ``PYTEST_XDIST_AUTO_NUM_WORKERS`` or an explicit ``-n N`` (``-n 0``: serial) win."""
    env = os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS")
    if env:
        return int(env)
    if config.args_source == pytest.Config.ArgsSource.ARGS and not any(
            os.path.isdir(a) for a in config.args):
        return 0
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:                  # not Linux
        cpus = os.cpu_count() or 1
    return min(cpus, MAX_WORKERS) if cpus > 1 else 0


#: the longest files, longest first (serial run, 2-core machine at load ≈ 6: the sum of
#: their tests' durations 105 … 14 s). Under xdist (``--dist loadfile``, files handed out
#: in collection order) they are handed out first, so no worker is left with a long file
#: while the other idles at the end. Serial runs keep the default order.
SLOW_FILES = ("test_diagnose.py", "test_examples.py", "test_replay.py", "test_faults.py",
              "test_examples_frontdoor.py", "test_paper.py", "test_proxqp.py", "test_sweep.py",
              "test_channels_workbench.py", "test_rundir.py", "test_import_example.py",
              "test_cli.py", "test_plots.py", "test_viz_meshcat.py", "test_diagnosis_proposal.py",
              "test_runner.py", "test_playback.py")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """In an xdist worker: the :data:`SLOW_FILES` first (a stable sort: the other files and
    the tests inside each file keep their order). Runs before pytest-random-order, which
    then shuffles as asked (``--random-order-seed``)."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return
    rank = {name: i for i, name in enumerate(SLOW_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


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

from workbench import (HIDDEN_CASES, LIBRARY, WB_CASES, build_once,  # noqa: E402
                       diagnose_case, make_clean, register_hidden)


def shared_run_dir(tmp_path_factory, name: str):
    """A folder of this test run shared by all its xdist workers (serially: one folder of
    the session). Each worker's base temp is ``<run base temp>/popen-gwN``; the run's base
    temp is new for every run, so nothing is shared between runs."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent
    root = base / name
    root.mkdir(parents=True, exist_ok=True)
    return root


@pytest.fixture(scope="session")
def workbench_data(tmp_path_factory):
    """``workbench_data(name, noisy=True, noise_seed=None)`` → path of a cached data set
    (tests/workbench.py: WB_CASES; noise seed default: the case's plant seed). Each data
    set is made once per test run, by whichever xdist worker needs it first
    (tests/workbench.py: build_once); the others read it."""
    from granular_mpc.validation.synth import noisy_copy

    root = shared_run_dir(tmp_path_factory, "workbench")
    cache: dict = {}

    def get(name: str, noisy: bool = True, noise_seed: int | None = None):
        seed = WB_CASES[name]["seed"] if noise_seed is None else int(noise_seed)
        key = (name, seed if noisy else None)
        if key in cache:
            return cache[key]
        if name in HIDDEN_CASES:
            register_hidden()               # as in the worker that made it (make_clean)
        if (name, None) not in cache:
            cache[(name, None)] = build_once(root / f"{name}_clean",
                                             lambda out: make_clean(name, out))
        if noisy:
            clean = cache[(name, None)]
            cache[key] = build_once(root / f"{name}_noisy_{seed}",
                                    lambda out: noisy_copy(clean, out, 1.0, seed=seed,
                                                           overwrite=True))
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
