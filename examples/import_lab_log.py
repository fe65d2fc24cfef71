"""Import a lab's own log: different joint names, degrees, milliseconds, an IMU quaternion
in (x, y, z, w) order, a six-axis force sensor in each foot (foot frame, its own clock and
rate) — no motion capture, no intrusion.

The "lab log" is made here from a short simulated walk on sand (``granular-mpc synth``,
the truth), written as a ROS 2 bag when the ``rosbags`` package is installed, else as CSV
files; then ``import_log`` turns it into a checked data set with a mapping file, and the
loaded data set reports which channels it carries and how its stance labels were derived;
``validate`` and ``diagnose`` then run on it, on the measured channels only, and say
which channels were not measured and which candidate effects cannot be assessed without
them.

    python examples/import_lab_log.py          # GRANULAR_MPC_EXAMPLE_OUT=DIR to choose the folder
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import yaml

from granular_mpc.importers import import_log
from granular_mpc.importers.frames import foot_rotations
from granular_mpc.robot import load_biped
from granular_mpc.rotations import matrix_from_quat_wxyz
from granular_mpc.validation import load_dataset
from granular_mpc.validation.channel_coverage import Coverage
from granular_mpc.validation.diagnose import diagnose
from granular_mpc.validation.diagnosis.coverage import COVERAGE_FILE
from granular_mpc.validation.replay import validate
from granular_mpc.validation.synth import synthesize

OUT = Path(os.environ.get("GRANULAR_MPC_EXAMPLE_OUT", "runs")) / "import_lab_log"
LAB_NAMES = {"left_hip_abd": "LHipRoll", "left_hip_pitch": "LHipPitch", "left_knee": "LKnee",
             "right_hip_abd": "RHipRoll", "right_hip_pitch": "RHipPitch", "right_knee": "RKnee"}
DEG = np.pi / 180.0
FORCE_CLOCK_LAG_S = 0.004        # the force amplifier's clock runs 4 ms behind


def lab_log(truth, biped):
    """The truth trial as a lab records it: dict of streams (time [ms], columns)."""
    df = truth.trials[truth.trial_names[0]]
    t_ms = df["time"].to_numpy() * 1e3
    joints = {"t_ms": t_ms}
    for j, lab in LAB_NAMES.items():
        joints[f"{lab}_pos_deg"] = df[f"q_{j}"].to_numpy() / DEG
        joints[f"{lab}_vel_dps"] = df[f"dq_{j}"].to_numpy() / DEG
        joints[f"{lab}_cur_Nm"] = df[f"tau_{j}"].to_numpy()
    imu = {"t_ms": t_ms, "qx": df.base_qx.to_numpy(), "qy": df.base_qy.to_numpy(),
           "qz": df.base_qz.to_numpy(), "qw": df.base_qw.to_numpy(),
           "gx_dps": df.base_wx.to_numpy() / DEG, "gy_dps": df.base_wy.to_numpy() / DEG,
           "gz_dps": df.base_wz.to_numpy() / DEG}
    # the sensor in each foot: the stance foot's force, in its foot frame, every other sample
    quat = df[["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy()
    r_wb = np.array([matrix_from_quat_wxyz(q) for q in quat])
    q_a = df[[f"q_{j}" for j in biped.joint_names]].to_numpy()
    f_w = df[["grf_x", "grf_y", "grf_z"]].to_numpy()
    force = {"t_ms": t_ms[::2] + FORCE_CLOCK_LAG_S * 1e3}
    for side in ("left", "right"):
        r_bf = foot_rotations(biped, side, q_a)
        f_f = np.einsum("nji,nkj,nk->ni", r_bf, r_wb, f_w)       # R_BFᵀ R_WBᵀ f_W
        f_f[df["stance"].to_numpy() != side] = 0.0
        for k, ax in enumerate("xyz"):
            force[f"{side[0].upper()}F{ax}"] = f_f[::2, k]
    return {"joints": joints, "imu": imu, "force": force}


def mapping(bag: bool):
    """The lab's mapping file (docs/import.md)."""
    def src(name, topic):
        return topic if bag else f"{name}.csv"
    time = {} if bag else {"time": "t_ms", "time_scale": 0.001}
    joints = ({"joint_state": {"q": "position", "dq": "velocity", "tau": "effort"}} if bag else
              {"joint_columns": {"q": "{joint}_pos_deg", "dq": "{joint}_vel_dps",
                                 "tau": "{joint}_cur_Nm"}})
    imu = ([{"to": "trunk_orientation", "field": "orientation", "order": "xyzw"},
            {"to": "trunk_angular_velocity", "field": "angular_velocity", "scale": DEG}] if bag
           else [{"to": "trunk_orientation", "fields": ["qx", "qy", "qz", "qw"], "order": "xyzw"},
                 {"to": "trunk_angular_velocity", "fields": ["gx_dps", "gy_dps", "gz_dps"],
                  "scale": DEG}])
    feet = [{"to": f"{side}_foot_force", "frame": "foot",      # bag: one WrenchStamped per foot
             **({"field": "wrench.force"} if bag else
                {"fields": [f"{side[0].upper()}F{a}" for a in "xyz"]})}
            for side in ("left", "right")]
    streams = [dict(source=src("joints", "/joint_states"), **time, **joints,
                    joint_scale={"q": DEG, "dq": DEG}),
               dict(source=src("imu", "/imu"), **time, channels=imu)]
    if bag:
        streams += [dict(source=f"/{side}_foot/wrench", time_offset_s=-FORCE_CLOCK_LAG_S,
                         channels=[f]) for side, f in zip(("left", "right"), feet)]
    else:
        streams.append(dict(source="force.csv", **time, time_offset_s=-FORCE_CLOCK_LAG_S,
                            channels=feet))
    return {"robot": "yobogo10s", "terrain": "lab sand pit (simulated)", "sample_rate_hz": 500,
            "commanded_speed_mps": 0.25, "trial": "walk_025",
            "joint_names": {v: k for k, v in LAB_NAMES.items()}, "streams": streams}


def write_csv(folder: Path, log) -> Path:
    import pandas as pd
    folder.mkdir(parents=True, exist_ok=True)
    for name, cols in log.items():
        pd.DataFrame(cols).to_csv(folder / f"{name}.csv", index=False)
    return folder


def write_bag(folder: Path, log) -> Path:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types

    def header(ms):
        ns = int(round(ms * 1e6)) + 1_700_000_000 * 10**9
        return ns, T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
            sec=ns // 10**9, nanosec=ns % 10**9), frame_id="")

    def vec(x, y, z):
        return T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    with Writer(folder, version=9) as w:
        def put(topic, typ, ns, msg):
            conn = conns.get(topic) or conns.setdefault(topic, w.add_connection(topic, typ,
                                                                                 typestore=ts))
            w.write(conn, ns, ts.serialize_cdr(msg, typ))
        conns: dict = {}
        J, I, F = log["joints"], log["imu"], log["force"]
        for k, ms in enumerate(J["t_ms"]):
            ns, h = header(ms)
            put("/joint_states", "sensor_msgs/msg/JointState", ns, T["sensor_msgs/msg/JointState"](
                header=h, name=list(LAB_NAMES.values()),
                position=np.array([J[f"{n}_pos_deg"][k] for n in LAB_NAMES.values()]),
                velocity=np.array([J[f"{n}_vel_dps"][k] for n in LAB_NAMES.values()]),
                effort=np.array([J[f"{n}_cur_Nm"][k] for n in LAB_NAMES.values()])))
            put("/imu", "sensor_msgs/msg/Imu", ns, T["sensor_msgs/msg/Imu"](
                header=h, orientation=T["geometry_msgs/msg/Quaternion"](
                    x=I["qx"][k], y=I["qy"][k], z=I["qz"][k], w=I["qw"][k]),
                orientation_covariance=np.zeros(9),
                angular_velocity=vec(I["gx_dps"][k], I["gy_dps"][k], I["gz_dps"][k]),
                angular_velocity_covariance=np.zeros(9), linear_acceleration=vec(0, 0, 9.81),
                linear_acceleration_covariance=np.zeros(9)))
        for k, ms in enumerate(F["t_ms"]):
            ns, h = header(ms)
            for s in ("left", "right"):
                c = s[0].upper()
                put(f"/{s}_foot/wrench", "geometry_msgs/msg/WrenchStamped", ns,
                    T["geometry_msgs/msg/WrenchStamped"](header=h, wrench=T[
                        "geometry_msgs/msg/Wrench"](force=vec(F[f"{c}Fx"][k], F[f"{c}Fy"][k],
                                                              F[f"{c}Fz"][k]),
                                                    torque=vec(0, 0, 0))))
    return folder


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    truth = load_dataset(synthesize("sand_walk", OUT / "truth", speeds=[0.25], steps=4, seed=5,
                                    noise=0.0, workers=1, overwrite=True).path)
    biped = load_biped(truth.meta.robot, with_visuals=False)
    log = lab_log(truth, biped)
    try:
        import rosbags  # noqa: F401
        bag = True
    except ImportError:
        bag = False
    source = write_bag(OUT / "lab_bag", log) if bag else write_csv(OUT / "lab_csv", log)
    (OUT / "mapping.yaml").write_text(yaml.safe_dump(mapping(bag), sort_keys=False))
    print(f"lab log: {source} ({'ROS 2 bag' if bag else 'CSV files'})")
    res = import_log(source, OUT / "mapping.yaml", OUT / "imported", overwrite=True)
    ds = load_dataset(res.path)
    print(ds.channel_report())

    # how close is the import to the truth (on the truth's own samples)?
    got, true = ds.trials["walk_025"], truth.trials[truth.trial_names[0]]
    t_true = true["time"].to_numpy() - true["time"].iloc[0]
    n = min(len(got), len(true))
    q_err = max(float(np.max(np.abs(got[f"q_{j}"].to_numpy()[:n]
                                    - np.interp(got["time"].to_numpy()[:n], t_true,
                                                true[f"q_{j}"].to_numpy()))))
                for j in biped.joint_names)
    agree = float(np.mean(got["stance"].to_numpy()[:n]
                          == true["stance"].to_numpy()[np.minimum(np.searchsorted(
                              t_true, got["time"].to_numpy()[:n] - 1e-9), len(true) - 1)]))
    print(f"resampled: {res.resampled}")
    print(f"max_joint_angle_error_rad: {q_err:.3g}")
    print(f"stance_agreement: {agree:.3f}")

    print(f"data set: {res.path}")

    # ---------------------------------------------------------------- validate / diagnose
    # Only the measured channels are scored; the trunk position and velocity of each
    # replay's start come from leg odometry (stance foot + IMU), docs/import.md.
    val = validate(res.path, OUT / "validate", workers=1, n_boot=100, figures=False)
    cov = val.report["coverage"]
    print(f"validate: {val.report['n_stances']} stances, trunk state: {cov['trunk_state']}")
    print(f"not_measured: {', '.join(cov['missing'])}")
    print(f"not_scored: {', '.join(cov['not_scored_channels'])}")
    for channel, rmse in val.report["overall_rmse"]["granular"].items():
        print(f"  RMSE {channel}: {rmse:.3g} {val.report['units'][channel]}")
    diag = diagnose(res.path, OUT / "diagnose", n_boot=50, workers=1, figures=False)
    cannot = Coverage.from_dict(json.loads((OUT / "diagnose" / COVERAGE_FILE).read_text()))
    print(f"diagnose: {diag.verdict.status} (added: {', '.join(diag.added) or 'nothing'})")
    print(f"not_assessable: {', '.join(cannot.not_assessable) or '-'}")
    print(f"report: {OUT / 'diagnose' / 'report.md'}")


if __name__ == "__main__":
    main()
