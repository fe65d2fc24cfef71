"""Import from ROS 2 bags (rosbags' own writer makes the bags): round trip, mapping errors."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from test_dataformat import FS, JOINTS, make_trial

from granular_mpc.exceptions import ConfigError
from granular_mpc.importers import import_log, load_mapping
from granular_mpc.validation.dataformat import ChannelGroup, load_dataset

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

TS = get_typestore(Stores.ROS2_HUMBLE)
T = TS.types
BASE_NS = 1_700_000_000 * 10**9          # an epoch-like start: stamps are large integers


def _header(ns: int):
    return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
        sec=ns // 10**9, nanosec=ns % 10**9), frame_id="")


def _vec(x, y, z):
    return T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))


def write_bag(path, df, storage=StoragePlugin.SQLITE3, names=JOINTS):
    """Every v1 channel of ``df`` as the messages a lab's bag holds (SI, ROS conventions)."""
    stamps = [BASE_NS + int(round(t * 1e9)) for t in df["time"]]
    with Writer(path, version=9, storage_plugin=storage) as w:
        conns = {topic: w.add_connection(topic, f"{typ}", typestore=TS) for topic, typ in (
            ("/joint_states", "sensor_msgs/msg/JointState"), ("/imu", "sensor_msgs/msg/Imu"),
            ("/odom", "nav_msgs/msg/Odometry"), ("/grf", "geometry_msgs/msg/WrenchStamped"),
            ("/intrusion", "geometry_msgs/msg/Vector3Stamped"))}
        for k, ns in enumerate(stamps):
            r = df.iloc[k]
            q = np.array([r[f"q_{j}"] for j in JOINTS])
            msgs = {
                "/joint_states": T["sensor_msgs/msg/JointState"](
                    header=_header(ns), name=list(names), position=q,
                    velocity=np.array([r[f"dq_{j}"] for j in JOINTS]),
                    effort=np.array([r[f"tau_{j}"] for j in JOINTS])),
                "/imu": T["sensor_msgs/msg/Imu"](
                    header=_header(ns),
                    orientation=T["geometry_msgs/msg/Quaternion"](
                        x=r.base_qx, y=r.base_qy, z=r.base_qz, w=r.base_qw),
                    orientation_covariance=np.zeros(9),
                    angular_velocity=_vec(r.base_wx, r.base_wy, r.base_wz),
                    angular_velocity_covariance=np.zeros(9),
                    linear_acceleration=_vec(0, 0, 9.81),
                    linear_acceleration_covariance=np.zeros(9)),
                "/odom": T["nav_msgs/msg/Odometry"](
                    header=_header(ns), child_frame_id="base",
                    pose=T["geometry_msgs/msg/PoseWithCovariance"](
                        pose=T["geometry_msgs/msg/Pose"](
                            position=T["geometry_msgs/msg/Point"](x=r.base_x, y=r.base_y,
                                                                  z=r.base_z),
                            orientation=T["geometry_msgs/msg/Quaternion"](x=0., y=0., z=0., w=1.)),
                        covariance=np.zeros(36)),
                    twist=T["geometry_msgs/msg/TwistWithCovariance"](
                        twist=T["geometry_msgs/msg/Twist"](linear=_vec(r.base_vx, r.base_vy,
                                                                       r.base_vz),
                                                           angular=_vec(0, 0, 0)),
                        covariance=np.zeros(36))),
                "/grf": T["geometry_msgs/msg/WrenchStamped"](
                    header=_header(ns), wrench=T["geometry_msgs/msg/Wrench"](
                        force=_vec(r.grf_x, r.grf_y, r.grf_z), torque=_vec(0, 0, 0))),
                "/intrusion": T["geometry_msgs/msg/Vector3Stamped"](
                    header=_header(ns), vector=_vec(r.intrusion_x, r.intrusion_y, r.intrusion_z)),
            }
            for topic, msg in msgs.items():
                typ = conns[topic].msgtype
                w.write(conns[topic], ns, TS.serialize_cdr(msg, typ))
    return path


IDENTITY = {
    "robot": "yobogo10s", "terrain": "lab sand pit", "sample_rate_hz": FS,
    "commanded_speed_mps": 0.2, "trial": "walk_01",
    "streams": [
        {"source": "/joint_states", "joint_state": {"q": "position", "dq": "velocity",
                                                    "tau": "effort"}},
        {"source": "/imu", "channels": [
            {"to": "trunk_orientation", "field": "orientation", "order": "xyzw"},
            {"to": "trunk_angular_velocity", "field": "angular_velocity"}]},
        {"source": "/odom", "channels": [
            {"to": "trunk_position", "field": "pose.pose.position"},
            {"to": "trunk_linear_velocity", "field": "twist.twist.linear"}]},
        {"source": "/grf", "channels": [{"to": "foot_force", "field": "wrench.force"}]},
        {"source": "/intrusion", "channels": [{"to": "intrusion", "field": "vector"}]},
    ]}


def mapping_file(tmp_path, data=IDENTITY, name="map.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data), encoding="utf-8")
    return p


@pytest.mark.parametrize("storage", [StoragePlugin.SQLITE3, StoragePlugin.MCAP])
def test_bag_round_trip_is_bit_exact(tmp_path, storage):
    df = make_trial()
    bag = write_bag(tmp_path / "bag", df, storage)
    res = import_log(bag, mapping_file(tmp_path), tmp_path / "ds")
    assert not res.resampled and res.rows == len(df)
    assert set(res.channels) == set(ChannelGroup)
    ds = load_dataset(res.path)
    got = ds.trials["walk_01"]
    assert ds.channels.declared and ds.stance_source == "force"
    for col in ds.channels.columns(JOINTS):
        np.testing.assert_array_equal(got[col].to_numpy(), df[col].to_numpy(), err_msg=col)
    np.testing.assert_allclose(got["time"].to_numpy(), df["time"].to_numpy(), rtol=0, atol=1e-9)


def test_bag_subset_of_channels(tmp_path):
    """Joint encoders + IMU only: the data set declares four groups, the rest is absent."""
    df = make_trial()
    bag = write_bag(tmp_path / "bag", df)
    data = dict(IDENTITY, streams=IDENTITY["streams"][:2])
    ds = load_dataset(import_log(bag, mapping_file(tmp_path, data), tmp_path / "ds").path)
    assert set(ds.channels) == {ChannelGroup.JOINT_ANGLES, ChannelGroup.JOINT_VELOCITIES,
                                ChannelGroup.JOINT_TORQUES, ChannelGroup.TRUNK_ORIENTATION,
                                ChannelGroup.TRUNK_ANGULAR_VELOCITY}
    assert not ds.has(ChannelGroup.FOOT_FORCE) and "grf_z" not in ds.trials["walk_01"].columns
    assert ds.stance_source == "kinematics"


def test_joint_name_map_and_missing_joint(tmp_path):
    df = make_trial()
    lab = [f"J{k}" for k in range(6)]
    bag = write_bag(tmp_path / "bag", df, names=lab)
    data = dict(IDENTITY, joint_names=dict(zip(lab, JOINTS)))
    ds = load_dataset(import_log(bag, mapping_file(tmp_path, data), tmp_path / "ds").path)
    np.testing.assert_array_equal(ds.trials["walk_01"][f"q_{JOINTS[2]}"], df[f"q_{JOINTS[2]}"])
    with pytest.raises(ConfigError) as info:
        import_log(bag, mapping_file(tmp_path, IDENTITY, "plain.yaml"), tmp_path / "ds2")
    assert info.value.key == "joint_names" and "/joint_states" in str(info.value)
    assert "J0" in str(info.value)


def test_errors_name_topic_field_and_key(tmp_path):
    bag = write_bag(tmp_path / "bag", make_trial(n=20))
    bad_topic = dict(IDENTITY, streams=[{"source": "/imu_typo", "channels": []}])
    with pytest.raises(ConfigError) as info:
        import_log(bag, mapping_file(tmp_path, bad_topic), tmp_path / "a")
    assert info.value.key == "streams[0].source" and "/imu_typo" in str(info.value)
    assert "/imu" in str(info.value)                     # the topics that exist are listed
    bad_field = dict(IDENTITY, streams=[{"source": "/imu", "channels": [
        {"to": "trunk_angular_velocity", "field": "angular_speed"}]}])
    with pytest.raises(ConfigError) as info:
        import_log(bag, mapping_file(tmp_path, bad_field), tmp_path / "b")
    assert info.value.key == "streams[0].channels[0].field"
    assert "angular_speed.x" in str(info.value) and "/imu" in str(info.value)


def test_mapping_unknown_key_is_rejected(tmp_path):
    data = dict(IDENTITY, sample_rate=100)
    with pytest.raises(ConfigError, match="sample_rate"):
        load_mapping(mapping_file(tmp_path, data))
    data = dict(IDENTITY, streams=[{"source": "/imu", "channels": [
        {"to": "trunk_orientation", "field": "orientation", "order": "zyxw"}]}])
    with pytest.raises(ConfigError, match=r"streams\.0\.channels\.0\.order|order"):
        load_mapping(mapping_file(tmp_path, data))


def test_incomplete_group_is_a_mapping_error(tmp_path):
    bag = write_bag(tmp_path / "bag", make_trial(n=20))
    data = dict(IDENTITY, streams=[IDENTITY["streams"][0], {"source": "/odom", "channels": [
        {"to": "base_z", "field": "pose.pose.position.z"}]}])
    with pytest.raises(ConfigError, match="trunk_position is incomplete: base_x, base_y"):
        import_log(bag, mapping_file(tmp_path, data), tmp_path / "ds")
