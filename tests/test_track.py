"""The track terrain (granular_mpc.terrain.track): a ground law that changes along x."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from granular_mpc.config import load_terrain, terrain_from_dict
from granular_mpc.exceptions import ConfigError
from granular_mpc.runner import build_simulation, closed_loop
from granular_mpc.scenario import load_scenario
from granular_mpc.terrain import TrackTerrain, build_terrain
from granular_mpc.terrain.track import sole_point_x

DT = 0.0005
EDGE = 0.3


@pytest.fixture(scope="module")
def track(robot_config):
    cfg = terrain_from_dict({"kind": "track", "name": "t",
                             "segments": [{"until_x": EDGE, "terrain": "rigid"},
                                          {"terrain": "dry_sand"}]})
    return build_terrain(cfg, robot_config)


def foot_kin(x: float, depth: float, radius: float, v_z: float = -0.05) -> np.ndarray:
    """Level foot (frame at the sole arc's centre) whose lowest point is ``depth`` deep."""
    kin = np.zeros(18)
    kin[0:3] = (x, 0.0, radius - depth)
    kin[3:12] = np.eye(3).ravel("F")
    kin[14] = v_z
    return kin


def press(data, kin_of_step, n: int) -> list[np.ndarray]:
    """Evaluate + commit foot 0 for ``n`` steps; the force of each step."""
    out = []
    for k in range(n):
        data.feet[0].kin[:] = kin_of_step(k)
        data.evaluate(0)
        out.append(data.feet[0].force.copy())
        data.commit()
    return out


def test_yaml_builds_a_track_and_rejects_unknown_keys(robot_config):
    cfg = load_terrain("paper_track")
    assert cfg.kind == "track" and cfg.edges == (EDGE,)
    assert [s.terrain.kind for s in cfg.segments] == ["rigid", "granular"]
    assert isinstance(build_terrain(cfg, robot_config), TrackTerrain)
    with pytest.raises(ConfigError, match="bogus"):
        terrain_from_dict({"kind": "track", "segments": [
            {"until_x": 1.0, "terrain": "rigid", "bogus": 1}, {"terrain": "dry_sand"}]})
    with pytest.raises(ConfigError, match="last segment"):
        terrain_from_dict({"kind": "track", "segments": [
            {"until_x": 1.0, "terrain": "rigid"}, {"until_x": 2.0, "terrain": "dry_sand"}]})
    with pytest.raises(ConfigError, match="increase"):
        terrain_from_dict({"kind": "track", "segments": [
            {"until_x": 1.0, "terrain": "rigid"}, {"until_x": 0.5, "terrain": "rigid"},
            {"terrain": "dry_sand"}]})
    with pytest.raises(ConfigError, match="surface_height"):
        terrain_from_dict({"kind": "track", "segments": [
            {"until_x": 1.0, "terrain": "rigid"},
            {"terrain": {"file": "dry_sand", "surface_height": 0.02}}]})


def test_segment_file_with_changed_keys(robot_config):
    cfg = terrain_from_dict({"kind": "track", "segments": [
        {"until_x": 0.0, "terrain": "rigid"}, {"terrain": {"file": "dry_sand", "zeta": 2.72}}]})
    assert cfg.segments[1].terrain.zeta == 2.72
    assert cfg.terrain_at(-0.1).kind == "rigid" and cfg.terrain_at(0.0).kind == "granular"


@pytest.mark.parametrize("x, plain_name", [(EDGE - 0.2, "rigid"), (EDGE + 0.2, "dry_sand")])
def test_a_foot_on_each_segment_feels_that_segments_law(track, robot_config, x, plain_name):
    plain = build_terrain(load_terrain(plain_name), robot_config)
    r = robot_config.foot.radius

    def kin(k):   # pressing down at 5 cm/s from 1 mm deep, 60 steps
        return foot_kin(x, 0.001 + 0.05 * DT * k, r)

    f_track = press(track.new_data(DT), kin, 60)
    f_plain = press(plain.new_data(DT), kin, 60)
    np.testing.assert_array_equal(np.array(f_track), np.array(f_plain))
    assert f_track[-1][:, 2].sum() > 1.0          # it does bear a load


def test_lowest_point_decides_and_a_stance_keeps_its_law(track, robot_config):
    r = robot_config.foot.radius
    ha = robot_config.foot.half_angle
    assert sole_point_x(foot_kin(0.1, 0.0, r), r, ha) == pytest.approx(0.1)
    d = track.new_data(DT)
    # lands 2 mm before the edge: rigid
    press(d, lambda k: foot_kin(EDGE - 0.002, 0.0005, r), 5)
    assert d.segment_of(0) == 0 and d.in_contact(0)
    # slides across the edge while in contact: keeps the rigid law
    press(d, lambda k: foot_kin(EDGE + 0.002 + 1e-4 * k, 0.0005, r), 5)
    assert d.segment_of(0) == 0
    # lifts off, lands beyond the edge: sand, with a fresh intrusion state (C0 here)
    press(d, lambda k: foot_kin(EDGE + 0.01, -0.01, r), 2)
    assert not d.in_contact(0)
    press(d, lambda k: foot_kin(EDGE + 0.01, 0.001, r), 1)
    assert d.segment_of(0) == 1 and d.in_contact(0)
    np.testing.assert_allclose(d.feet[0].diag[:, 2:4], 0.0, atol=1e-12)   # x_s, y_s at touchdown


def test_parameters_by_segment(track):
    d = track.new_data(DT)
    d.set_param("1.zeta", 2.0)
    assert d.param("zeta") == 2.0
    d.set_param("friction", 0.5)
    assert d.param("0.friction") == 0.5
    with pytest.raises(ConfigError):
        d.set_param("nonsense", 1.0)
    with pytest.raises(ConfigError, match="compiled"):
        track.contact


def test_walk_across_the_edge_in_closed_loop():
    """Rigid platform up to x = 5 cm, then sand; the paper's controller with the 39 ms
    double support steps across and keeps walking (2.5 s)."""
    sc = load_scenario("paper_protocol", [
        ("terrain", {"kind": "track", "segments": [{"until_x": 0.05, "terrain": "rigid"},
                                                    {"terrain": "dry_sand"}]}),
        "controller.gait.load_transfer=0.039", "command.start_delay=0.3",
        "command.speed=0.3", "sim.duration=2.5", "output.plots=false"])
    sim = build_simulation(sc)
    st = sim.new_state()
    log = pd.DataFrame(list(closed_loop(sim, st)))
    assert st.fall is None
    assert log["time"].iloc[-1] == pytest.approx(2.5, abs=0.01)
    on_sand = [(log[f"{s}_contact"] > 0.5) & (log[f"{s}_px"] > 0.05) & (log[f"{s}_depth"] > 0.01)
               for s in ("left", "right")]
    assert (on_sand[0] | on_sand[1]).any()          # a foot sank into the sand segment
    assert log["com_x"].iloc[-1] > 0.2


def test_a_track_needs_the_controller_to_name_its_ground():
    sc = load_scenario("sim/paper_protocol.yaml", ["controller.terrain=plant"])
    with pytest.raises(ConfigError) as err:
        build_simulation(sc)
    assert err.value.key == "controller.terrain"
