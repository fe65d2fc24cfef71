"""Shared fixtures: models are immutable, so build them once per test session."""
from __future__ import annotations

import pytest

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
