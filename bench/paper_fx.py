"""The mid-stance F_x swing of the default sand run: segmentation, sign or gait? (issue 10).

    GRANULAR_MPC_PROXSUITE=generic python bench/paper_fx.py [--out runs/paper_fx]
        [--seconds 8] [--cases base weight_force_x100 ...] [--json PATH] [--reuse]

``plots/grf.png`` of the default run (``sim/sand_walk.yaml``: granular controller, dry
sand, 0.2 m/s) shows the stance foot's F_x ≈ +10 N (propulsive) after touchdown and
≈ −10 N at 60 % of stance. Each *knob* changes one controller or command setting of that
scenario (``--set`` overrides, nothing else) and is run closed loop for ``--seconds``;
for each run the stance foot's mean F_x over ten stance-phase bins is measured on the
contact-based stances (:func:`granular_mpc.analysis.find_stances`, touchdown to lift-off
from the plant's contact state, complete stances after 2 s), with three checks that
need no new run:

* **sign**: the least-squares slope of the net horizontal force ΣF_x (both feet) against
  m·dv_CoM,x/dt (Newton: +1 if the logged force is the force on the robot, −1 if it is
  the force on the ground);
* **segmentation**: the same profile on the planned and on the force-based stances;
* **geometry**: the stance foot's position relative to the CoM at touchdown and
  lift-off [m] (a foot ahead of the CoM brakes an inverted pendulum, one behind it
  propels).

Writes ``OUT/<case>/`` run folders and, with ``--json``, every figure (the paper
comparison's notes §7 quote them; ``bench/paper_gaps.py --fx`` merges them into
``gaps_measured.json``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("GRANULAR_MPC_PROXSUITE", "generic")   # bit-reproducible runs

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

from granular_mpc.analysis.stances import find_stances  # noqa: E402
from granular_mpc.columns import (BASE_POSITION, BASE_QUATERNION, FOOT_SIDES,  # noqa: E402
                                  foot_column, joint_columns)
from granular_mpc.rotations import xyzw_from_wxyz  # noqa: E402
from granular_mpc.robot.model import load_biped  # noqa: E402
from granular_mpc.runlog import read_log  # noqa: E402
from granular_mpc.runner import run_scenario  # noqa: E402
from granular_mpc.scenario import load_scenario  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "sim" / "sand_walk.yaml"
N_BINS = 10
T_STEADY = 2.0          # s: stances after the speed ramp


@dataclass(frozen=True)
class FxKnob:
    """One change of the default sand run.

    Attributes:
        name: short name; what: one line; overrides: ``--set`` overrides.
    """

    name: str
    what: str
    overrides: tuple[str, ...] = ()


FX_KNOBS: tuple[FxKnob, ...] = (
    FxKnob("base", "sim/sand_walk.yaml as shipped (granular controller, 0.2 m/s)"),
    FxKnob("weight_force_x100", "MPC force regularisation 1e-5 → 1e-3 1/N²",
           ("controller.mpc.weight_force=1e-3",)),
    FxKnob("weight_force_div100", "MPC force regularisation 1e-5 → 1e-7 1/N²",
           ("controller.mpc.weight_force=1e-7",)),
    FxKnob("wbc_force_x10", "WBC MPC-force tracking weight 10 → 100",
           ("controller.wbc.w_force=100",)),
    FxKnob("wbc_contact_div10", "WBC contact task weight 1000 → 100",
           ("controller.wbc.w_contact=100",)),
    FxKnob("no_transfer", "no touchdown double support (load_transfer auto → 0)",
           ("controller.gait.load_transfer=0",)),
    FxKnob("in_place", "command 0 m/s (stepping in place)", ("command.speed=0",)),
    FxKnob("vel_weight_x0", "MPC forward-velocity weight 20 → 0",
           ("controller.mpc.weights_velocity=[0,5,10]",)),
    FxKnob("swing_5cm", "swing apex 10 → 5 cm (the swing leg folds less)",
           ("controller.swing.height=0.05",)),
    FxKnob("swing_15cm", "swing apex 10 → 15 cm (the swing leg folds more)",
           ("controller.swing.height=0.15",)),
    FxKnob("foothold_ahead", "foothold speed offset × 1.5 (k_velocity 0 → 0.5)",
           ("controller.foothold.k_velocity=0.5",)),
)


@dataclass(frozen=True)
class FxFigures:
    """The F_x figures of one run.

    Attributes:
        knob: which knob; run_dir: its folder; fell: it fell.
        n_stances: complete contact stances after 2 s.
        profile_N: stance foot's mean F_x per stance-phase bin [N] (contact stances).
        profile_planned_N, profile_force_N: the same on planned / force-based stances [N].
        net_profile_N: ΣF_x of both feet over the stance-phase bins [N].
        first_half_N, second_half_N: stance foot's mean F_x over the first / second half.
        swing_N: max − min of the profile [N].
        newton_slope: least-squares slope of ΣF_x against m dv_CoM,x/dt [-].
        foot_ahead_td_m, foot_ahead_lo_m: stance contact point x − CoM x at touchdown /
            lift-off [m].
        mean_speed_mps: mean forward CoM speed after 2 s [m/s].
        swing_leg_N, stance_leg_N, trunk_N: m·a_x of the other (swing) leg's subtree, of
            the stance leg's and of the rest of the robot per stance-phase bin [N] (their
            sum is m a_CoM,x).
        wall_s: wall time of the run [s].
    """

    knob: str
    run_dir: str
    fell: bool
    n_stances: int
    profile_N: tuple
    profile_planned_N: tuple
    profile_force_N: tuple
    net_profile_N: tuple
    first_half_N: float
    second_half_N: float
    swing_N: float
    newton_slope: float
    foot_ahead_td_m: float
    foot_ahead_lo_m: float
    mean_speed_mps: float
    swing_leg_N: tuple
    stance_leg_N: tuple
    trunk_N: tuple
    wall_s: float


def phase_profile(log, source: str, column: str = "grf_x", net: bool = False,
                  t_min: float = T_STEADY) -> tuple[np.ndarray, int]:
    """Mean of the stance foot's ``<side>_<column>`` (``net``: the sum over both feet)
    per stance-phase bin, over the complete stances of ``source`` touching down after
    ``t_min`` [s]; and their number."""
    t = log["time"].to_numpy(dtype=float)
    sums, counts, n = np.zeros(N_BINS), np.zeros(N_BINS), 0
    both = sum(log[foot_column(s, column)].to_numpy(dtype=float) for s in ("left", "right"))
    for st in find_stances(log, source):
        if not st.complete or st.t_touchdown < t_min:
            continue
        rows = np.arange(st.row_start, st.row_stop)
        y = both[rows] if net else log[foot_column(st.side, column)].to_numpy(dtype=float)[rows]
        ph = (t[rows] - t[rows[0]]) / max(t[rows[-1]] - t[rows[0]], 1e-9)
        b = np.minimum((ph * N_BINS).astype(int), N_BINS - 1)
        np.add.at(sums, b, y)
        np.add.at(counts, b, 1)
        n += 1
    return sums / np.maximum(counts, 1), n


def momentum_split(log, biped) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """m·a_x [N] per stance-phase bin of the swing leg, the stance leg and the rest (trunk):
    each leg's subtree CoM (from its hip joint) on the logged configuration, differentiated
    twice in time; the rest is m a_CoM,x minus both legs."""
    mdl = biped.model
    data = mdl.createData()
    t = log["time"].to_numpy(dtype=float)
    n = len(t)
    q = np.tile(pin.neutral(mdl), (n, 1))
    q[:, 0:3] = log[list(BASE_POSITION)].to_numpy(dtype=float)
    q[:, 3:7] = xyzw_from_wxyz(log[list(BASE_QUATERNION)].to_numpy(dtype=float))
    q[:, biped.idx_q] = log[joint_columns(biped.joint_names, "q")].to_numpy(dtype=float)
    first = {s: next(mdl.getJointId(j) for j in biped.joint_names if j.startswith(s + "_"))
             for s in FOOT_SIDES}                 # each leg's first joint: its hip
    x = {s: np.empty(n) for s in FOOT_SIDES}
    com = np.empty(n)
    for k in range(n):
        pin.centerOfMass(mdl, data, q[k], False)
        com[k] = data.com[0][0]
        for s in FOOT_SIDES:
            x[s][k] = data.com[first[s]][0]
    acc = lambda y: np.gradient(np.gradient(y, t), t)  # noqa: E731
    frame = log[["time", *[foot_column(s, "contact") for s in FOOT_SIDES]]].copy()
    total = biped.mass * acc(com)
    for s, o in (("left", "right"), ("right", "left")):
        frame[foot_column(s, "own")] = data.mass[first[s]] * acc(x[s])
        frame[foot_column(s, "swing")] = data.mass[first[o]] * acc(x[o])
        frame[foot_column(s, "total")] = total
    own, _ = phase_profile(frame, "contact", "own")
    swing, _ = phase_profile(frame, "contact", "swing")
    tot, _ = phase_profile(frame, "contact", "total")
    return swing, own, tot - swing - own


def fx_figures(knob: FxKnob, folder: Path, biped, wall: float) -> FxFigures:
    """:class:`FxFigures` of one run folder."""
    mass = biped.mass
    log = read_log(folder)
    summary = json.loads((folder / "summary.json").read_text())
    prof, n = phase_profile(log, "contact")
    net, _ = phase_profile(log, "contact", net=True)
    prof_p, _ = phase_profile(log, "planned")
    prof_f, _ = phase_profile(log, "force")
    t = log["time"].to_numpy(dtype=float)
    steady = t >= T_STEADY
    fx = (log["left_grf_x"] + log["right_grf_x"]).to_numpy(dtype=float)
    acc = np.gradient(log["com_vx"].to_numpy(dtype=float), t) * mass
    a, f = acc[steady], fx[steady]
    slope = float(np.dot(a - a.mean(), f - f.mean()) / np.dot(a - a.mean(), a - a.mean()))
    ahead_td, ahead_lo = [], []
    for st in find_stances(log, "contact"):
        if st.complete and st.t_touchdown >= T_STEADY:
            px = log[foot_column(st.side, "px")].to_numpy(dtype=float)
            cx = log["com_x"].to_numpy(dtype=float)
            ahead_td.append(px[st.row_start] - cx[st.row_start])
            ahead_lo.append(px[st.row_stop - 1] - cx[st.row_stop - 1])
    half = N_BINS // 2
    swing, own, trunk = momentum_split(log, biped)
    rnd = lambda a: tuple(np.round(a, 2))  # noqa: E731
    return FxFigures(
        knob.name, str(folder), bool(summary.get("fell")), n,
        tuple(np.round(prof, 2)), tuple(np.round(prof_p, 2)), tuple(np.round(prof_f, 2)),
        tuple(np.round(net, 2)), float(prof[:half].mean()), float(prof[half:].mean()),
        float(prof.max() - prof.min()), slope,
        float(np.mean(ahead_td)) if ahead_td else float("nan"),
        float(np.mean(ahead_lo)) if ahead_lo else float("nan"),
        float(log.loc[steady, "com_vx"].mean()), rnd(swing), rnd(own), rnd(trunk), wall)


def run_fx_knob(knob: FxKnob, out: Path, seconds: float, reuse: bool) -> Path:
    """Run one knob (``reuse``: keep a complete run already there)."""
    folder = out / knob.name
    if reuse and (folder / "summary.json").is_file():
        return folder
    sc = load_scenario(SCENARIO, [f"sim.duration={seconds:g}", "output.plots=false",
                                  *knob.overrides])
    run_scenario(sc, folder, progress=False, overwrite=True)
    return folder


def fx_table(res: list[FxFigures]) -> str:
    """Markdown table: one row per knob."""
    lines = ["| knob | F_x profile over stance, 10 bins [N] | 1st / 2nd half [N] | swing [N] "
             "| foot − CoM x at TD / LO [mm] | speed [m/s] | fell |", "|" + "---|" * 7]
    for r in res:
        prof = " ".join(f"{x:+.1f}" for x in r.profile_N)
        lines.append(f"| {r.knob} | {prof} | {r.first_half_N:+.1f} / {r.second_half_N:+.1f} | "
                     f"{r.swing_N:.1f} | {1e3 * r.foot_ahead_td_m:+.0f} / "
                     f"{1e3 * r.foot_ahead_lo_m:+.0f} | {r.mean_speed_mps:.3f} | "
                     f"{'yes' if r.fell else 'no'} |")
    return "\n".join(lines)


def main(argv=None) -> list[FxFigures]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="runs/paper_fx")
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--cases", nargs="+", default=None)
    ap.add_argument("--json", default=None)
    ap.add_argument("--reuse", action="store_true")
    args = ap.parse_args(argv)
    by = {k.name: k for k in FX_KNOBS}
    names = args.cases or list(by)
    biped = load_biped(with_visuals=False)
    res = []
    for name in names:
        t0 = time.perf_counter()
        folder = run_fx_knob(by[name], Path(args.out), args.seconds, args.reuse)
        r = fx_figures(by[name], folder, biped, time.perf_counter() - t0)
        res.append(r)
        print(f"{name:20s} {' '.join(f'{x:+.1f}' for x in r.profile_N)}  slope "
              f"{r.newton_slope:.2f}  TD {1e3 * r.foot_ahead_td_m:+.0f} mm  fell {r.fell}  "
              f"[{r.wall_s:.0f} s]", flush=True)
    print(fx_table(res))
    if args.json:
        doc = {"command": " ".join(["python bench/paper_fx.py", *(argv or sys.argv[1:])]),
               "seconds": args.seconds, "knobs": {k: dataclasses.asdict(by[k]) for k in names},
               "runs": [dataclasses.asdict(r) for r in res]}
        Path(args.json).write_text(json.dumps(doc, indent=1, default=str))
    return res


if __name__ == "__main__":
    main()
