"""Scenario files (granular_mpc.scenario): the error branches of the resolve pipeline and of
sweep expansion. Each raises the package's ConfigError (or its ModelFileError subclass)
naming the offending key and, where a file is involved, the file."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from granular_mpc.exceptions import ConfigError, ModelFileError
from granular_mpc.scenario import (expand_sweep, find_scenario, load_scenario,
                                   resolve_scenario_dict, scenario_from_dict)

BASE = {"name": "t", "robot": "yobogo10s", "terrain": "dry_sand",
        "controller": {"terrain": "plant"}, "command": {"speed": 0.2},
        "sim": {"duration": 1.0, "dt": 0.0005, "seed": 0}}
SWEEP = {"speeds": [0.1], "terrains": ["dry_sand"]}


def _write(tmp_path: Path, data: dict, name: str = "case.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def test_unknown_scenario_names_it_and_lists_the_shipped_ones():
    with pytest.raises(ModelFileError) as err:
        find_scenario("no_such_scenario")
    e = err.value
    assert e.value == "no_such_scenario" and "'no_such_scenario' not found" in str(e)
    assert "sand_walk" in e.allowed and "velocity_sweep" in e.allowed


def test_shipped_scenario_found_by_name_with_or_without_suffix():
    assert find_scenario("sand_walk") == find_scenario("sand_walk.yaml")
    assert find_scenario("sand_walk").name == "sand_walk.yaml"


@pytest.mark.parametrize("override", ["sim..dt=0.001", ".sim=1"])
def test_override_with_an_empty_key_part(override):
    with pytest.raises(ConfigError, match="has an empty part") as err:
        resolve_scenario_dict(BASE, [override])
    assert err.value.key == "--set"


def test_file_reference_of_the_wrong_type():
    with pytest.raises(ConfigError, match="must be a robot name, a path or a mapping, got int") as err:
        resolve_scenario_dict({**BASE, "robot": 12})
    assert err.value.key == "robot" and err.value.value == 12


def test_mapping_whose_file_is_not_a_string():
    with pytest.raises(ConfigError, match="must be a file name") as err:
        resolve_scenario_dict({**BASE, "terrain": {"file": 3, "zeta": 1.0}})
    assert err.value.key == "terrain.file" and err.value.value == 3


def test_file_swap_with_a_number():
    with pytest.raises(ConfigError, match="must be a file name or a mapping") as err:
        resolve_scenario_dict(BASE, [(["terrain"], 5)])
    assert err.value.key == "terrain"


def test_controller_terrain_swap_with_a_mapping():
    with pytest.raises(ConfigError, match="must be 'plant' or a terrain file name") as err:
        resolve_scenario_dict(BASE, [(["controller", "terrain"], {"file": "rigid"})])
    assert err.value.key == "controller.terrain"


def test_controller_terrain_key_when_the_controller_uses_the_plant_terrain():
    with pytest.raises(ConfigError, match="uses the plant's terrain") as err:
        resolve_scenario_dict(BASE, ["controller_terrain.zeta=1.5"])
    assert err.value.key == "controller_terrain.zeta"
    # with its own terrain the same override is accepted and applied
    out = resolve_scenario_dict(BASE, ["controller.terrain=dry_sand", "controller_terrain.zeta=1.5"])
    assert out["controller_terrain"]["zeta"] == 1.5


def test_unknown_terrain_file_is_a_model_file_error_naming_it():
    with pytest.raises(ModelFileError, match="terrain file 'mud' not found") as err:
        resolve_scenario_dict(BASE, ["terrain=mud"])
    assert err.value.key == "terrain"


def test_load_scenario_names_the_file_and_the_key(tmp_path):
    """An error raised while resolving gets the scenario file as its source."""
    path = _write(tmp_path, BASE)
    with pytest.raises(ConfigError) as err:
        load_scenario(path, ["sim.no_such_key=1"])
    e = err.value
    assert e.source == str(path) and str(e).startswith(str(path))
    assert "no_such_key" in str(e)
    with pytest.raises(ConfigError) as err:
        load_scenario(_write(tmp_path, {**BASE, "robot": 12}, "bad.yaml"))
    assert err.value.source.endswith("bad.yaml") and err.value.key == "robot"


def test_value_out_of_range_names_the_key(tmp_path):
    with pytest.raises(ConfigError, match=r"sim\.dt") as err:
        load_scenario(_write(tmp_path, BASE), ["sim.dt=-1"])
    assert err.value.source.endswith("case.yaml")


def test_expand_sweep_without_a_sweep_section(tmp_path):
    path = _write(tmp_path, BASE)
    with pytest.raises(ConfigError, match="no 'sweep:' section") as err:
        expand_sweep(path)
    assert err.value.key == "sweep" and err.value.source == str(path)


def test_sweep_grid_key_that_does_not_exist(tmp_path):
    path = _write(tmp_path, {**BASE, "sweep": {**SWEEP, "grid": {"sim.no_such": [1, 2]}}})
    with pytest.raises(ConfigError, match="grid key 'sim.no_such'") as err:
        expand_sweep(path)
    assert "sweep.grid" in str(err.value)


@pytest.mark.parametrize("key", ["terrain", "command.speed", "controller.terrain"])
def test_sweep_grid_key_that_has_its_own_list(tmp_path, key):
    path = _write(tmp_path, {**BASE, "sweep": {**SWEEP, "grid": {key: ["a", "b"]}}})
    with pytest.raises(ConfigError, match="has its own list") as err:
        expand_sweep(path)
    assert f"grid key '{key}'" in str(err.value)


def test_sweep_combination_that_fails_names_the_combination(tmp_path):
    """The base resolves, one combination (period out of range) does not: the message
    names that combination."""
    path = _write(tmp_path, {**BASE, "sweep": {"speeds": [0.1], "terrains": ["dry_sand"],
                                               "grid": {"controller.gait.period": [0.4, -1.0]}}})
    with pytest.raises(ConfigError, match=r"sweep run \(terrain=dry_sand, .*speed=0.1, "
                                          r"controller\.gait\.period=-1\.0\)") as err:
        expand_sweep(path)
    assert "period" in str(err.value)


def test_scenario_from_dict_validates_the_sweep_section_with_its_key():
    with pytest.raises(ConfigError, match=r"sweep\.speeds"):
        scenario_from_dict({**BASE, "sweep": {"speeds": "fast"}})
