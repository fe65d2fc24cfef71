"""Typed configuration (granular_mpc.config) and model-file errors: every failure path
names the dotted key (or file and line) and what was wrong."""
from __future__ import annotations

import shutil
import textwrap
from pathlib import Path

import pytest

from granular_mpc.config import (FootGeometry, RobotConfig, SimConfig, load_robot, load_terrain,
                                 load_yaml, terrain_from_dict, validate)
from granular_mpc.exceptions import ConfigError, ModelError, ModelFileError
from granular_mpc.paths import models_dirs
from granular_mpc.robot import Biped, load_biped


def _raises(fn, *args, **kwargs) -> ConfigError:
    with pytest.raises(ConfigError) as err:
        fn(*args, **kwargs)
    return err.value


# ------------------------------------------------------------------ unknown keys and types


def test_unknown_terrain_key_with_did_you_mean():
    err = _raises(terrain_from_dict, {"kind": "granular", "zetaa": 1.4})
    assert err.key == "terrain.zetaa"
    assert "did you mean 'zeta'" in str(err)


def test_unknown_nested_key_has_dotted_path():
    err = _raises(terrain_from_dict, {"kind": "granular", "rft": {"Cm1": 0.2}})
    assert err.key == "terrain.rft.Cm1"
    assert "did you mean 'Cm11'" in str(err)


def test_unknown_robot_key_in_a_file(tmp_path):
    data = load_yaml(next(d for d in models_dirs() if (d / "yobogo10s.yaml").is_file()) / "yobogo10s.yaml")
    data["foot"]["chrod"] = data["foot"].pop("chord")
    data["source_dir"] = "."
    err = _raises(validate, RobotConfig, data, source="robot.yaml")
    assert err.key == "foot.chrod"
    assert "did you mean 'chord'" in str(err)
    assert "robot.yaml" in str(err)


def test_unknown_terrain_kind():
    err = _raises(terrain_from_dict, {"kind": "quicksand"})
    assert "quicksand" in str(err)
    assert "granular" in str(err) and "rigid" in str(err)


def test_wrong_type():
    err = _raises(terrain_from_dict, {"kind": "granular", "density": "heavy"})
    assert err.key == "terrain.density"
    assert err.value == "heavy"
    err = _raises(validate, SimConfig, {"integrator": "rk4"})
    assert err.key == "integrator"
    assert "verlet" in str(err)


def test_several_problems_are_listed_at_once():
    err = _raises(terrain_from_dict, {"kind": "granular", "zeta": -1, "phi_s_deg": 100, "colour": "red"})
    text = str(err)
    assert "3 problems" in text
    for key in ("terrain.zeta", "terrain.phi_s_deg", "terrain.colour"):
        assert key in text


# ------------------------------------------------------------------ physical ranges


@pytest.mark.parametrize("zeta", [0.0, -0.5, float("nan"), float("inf")])
def test_zeta_must_be_positive_and_finite(zeta):
    err = _raises(terrain_from_dict, {"kind": "granular", "zeta": zeta})
    assert err.key == "terrain.zeta"


@pytest.mark.parametrize("phi", [0.0, -5.0, 90.0, 120.0])
def test_phi_s_must_be_inside_0_90_degrees(phi):
    err = _raises(terrain_from_dict, {"kind": "granular", "phi_s_deg": phi})
    assert err.key == "terrain.phi_s_deg"


@pytest.mark.parametrize("phi", [0.5, 38.0, 89.5])
def test_phi_s_inside_range_is_accepted(phi):
    assert terrain_from_dict({"kind": "granular", "phi_s_deg": phi}).phi_s_deg == phi


def test_load_terrain_overrides_are_validated():
    assert load_terrain("dry_sand", zeta=2.0).zeta == 2.0
    err = _raises(load_terrain, "dry_sand", zeta=0.0)
    assert err.key == "terrain.zeta"
    assert "dry_sand" in err.source


def test_sim_and_foot_ranges():
    assert _raises(validate, SimConfig, {"dt": 0.05}).key == "dt"
    assert _raises(validate, SimConfig, {"dt": 0.0}).key == "dt"
    err = _raises(validate, FootGeometry, {"chord": 0.05, "height": 0.03})
    assert "chord/2" in str(err)


# ------------------------------------------------------------------ files


def test_missing_terrain_file_lists_what_exists():
    with pytest.raises(ModelFileError) as err:
        load_terrain("wet_snow")
    assert isinstance(err.value, FileNotFoundError)
    assert err.value.value == "wet_snow"
    assert "dry_sand" in err.value.allowed and "rigid" in err.value.allowed


def test_malformed_yaml_reports_the_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("kind: granular\nzeta: 1.2\ndensity: [1660\nlayer_depth: 0.12\n")
    err = _raises(load_terrain, str(path))
    assert "malformed YAML" in str(err)
    assert "line 4" in str(err)              # where the parser noticed the open bracket
    assert str(path) in str(err)


def test_yaml_top_level_must_be_a_mapping(tmp_path):
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n")
    assert "mapping" in str(_raises(load_yaml, path))


def _robot_copy(tmp_path: Path, edit) -> Path:
    """Copy the shipped robot (YAML + URDF) to tmp_path, applying ``edit`` to the URDF text."""
    cfg = load_robot()
    shutil.copy(Path(cfg.source_dir) / "yobogo10s.yaml", tmp_path / "robot.yaml")
    urdf = cfg.urdf_path.read_text()
    (tmp_path / "yobogo10s.urdf").write_text(edit(urdf))
    return tmp_path / "robot.yaml"


def test_negative_link_mass_is_rejected_naming_the_link(tmp_path):
    def edit(text):
        head, sep, tail = text.partition('<link name="left_thigh">')
        return head + sep + tail.replace('<mass value="0.8500"/>', '<mass value="-0.8500"/>', 1)

    path = _robot_copy(tmp_path, edit)
    with pytest.raises(ModelError) as err:
        load_biped(str(path))
    assert "left_thigh" in str(err.value) and "-0.8500" in str(err.value)


def test_negative_inertia_is_rejected(tmp_path):
    path = _robot_copy(tmp_path, lambda t: t.replace('iyy="3.872667e-02"', 'iyy="-3.872667e-02"', 1))
    with pytest.raises(ModelError, match="'trunk'.*iyy"):
        load_biped(str(path))


def test_unmodified_copy_loads(tmp_path):
    path = _robot_copy(tmp_path, lambda t: t)
    assert load_biped(str(path), with_visuals=False).mass == pytest.approx(10.64)


def test_missing_urdf_and_unknown_joint(tmp_path):
    cfg = load_robot()
    missing = cfg.model_copy(update={"urdf": str(tmp_path / "nope.urdf")})
    with pytest.raises(ModelFileError, match="URDF not found"):
        Biped.from_config(missing)
    joints = list(cfg.joints)
    joints[2] = "left_kneee"
    with pytest.raises(ModelError, match="left_kneee"):
        Biped.from_config(cfg.model_copy(update={"joints": joints}))


def test_robot_file_with_unknown_key(tmp_path):
    cfg = load_robot()
    text = (Path(cfg.source_dir) / "yobogo10s.yaml").read_text()
    (tmp_path / "yobogo10s.urdf").write_text(cfg.urdf_path.read_text())
    (tmp_path / "robot.yaml").write_text(text + textwrap.dedent("""\
        joint_dampnig: 0.1
        """))
    err = _raises(load_robot, str(tmp_path / "robot.yaml"))
    assert err.key == "joint_dampnig"
    assert "did you mean 'joint_damping'" in str(err)


def test_a_terrain_file_with_a_key_given_twice_names_the_key_and_line(tmp_path, monkeypatch):
    monkeypatch.setenv("GRANULAR_MPC_MODELS", str(tmp_path))
    (tmp_path / "terrain").mkdir()
    (tmp_path / "terrain" / "twice.yaml").write_text(
        "name: twice\nkind: granular\nzeta: 1.36\nzeta: 5.0\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"duplicate key 'zeta'.*line 4"):
        load_terrain("twice")


def test_a_models_folder_that_does_not_exist_is_warned_about_by_name(tmp_path, monkeypatch):
    missing = tmp_path / "no-such-folder"
    monkeypatch.setenv("GRANULAR_MPC_MODELS", str(missing))
    with pytest.warns(UserWarning, match="no-such-folder"):
        models_dirs()


def test_every_mpc_qp_setting_can_be_chosen_from_yaml():
    """``controller.mpc.qp`` accepts exactly the names of the MPC's QP settings (a setting
    that the config rejects cannot be chosen; ``scaled_rows`` once could not) and rejects
    another name with the key in the message."""
    from pydantic import ValidationError

    from granular_mpc.config import MPCConfig
    from granular_mpc.control.mpc import QP_SETTINGS

    for name in QP_SETTINGS:
        assert MPCConfig(qp=name).qp == name
    with pytest.raises(ValidationError, match="qp"):
        MPCConfig(qp="fastest")
