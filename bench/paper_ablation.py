"""Why the rigid-ground controller falls on sand with the paper's gait: an ablation (issue 10, item 4).

    GRANULAR_MPC_PROXSUITE=generic python bench/paper_ablation.py [--speeds 0.2 0.4]
        [--seconds 20] [--cases rigid a_zeta_x2 ...] [--json PATH] [--quick]

The paper's robot walked on sand under its rigid-ground MPC-WBC with a 0.4 s period, 50 %
swing, no double support and a 10 cm cycloid swing. Here the rigid-assumption controller
(``controller.terrain=rigid`` on the dry-sand plant, which is that gait: ``load_transfer``
is 0 for a rigid ground model) falls within about two seconds. Each case below changes
one thing — the plant's touchdown (a), the torque path between controller and plant (b),
the WBC's stance contact task (c), the controller rates (d), the gait / protocol (e) — and
is run closed loop, one run at a time, at each speed. Everything goes through the public
API (``load_scenario`` overrides, ``build_simulation``, the plant's ``step``), and the
two things the package has no option for are emulated here only:

* a first-order torque lag (motor current loop / torque bandwidth): the torques the
  controller computes are filtered at the plant rate before the plant sees them;
* the stance contact task's feedback gain (``a* = −k v`` of the contact points; the
  rigid branch of ``control/wbc.py`` hard-codes k = 40 1/s): the WBC is rebuilt with a
  ground model whose ``granular`` flag selects the branch ``a* = −contact_damping·v``
  and the rigid ground's force polytope, so only k changes (the controller still plans
  no sinkage: the predicted sinkage acceleration is zero on a rigid ground model).

The paper's track (walk on rigid ground, then step onto sand) is emulated by running the
rigid plant and switching the plant's ground to sand at a scheduled touchdown
(``switch_to_sand_at``), keeping the robot's state.

One table row per case and speed: fall time (— = walked), mean speed (after the ramp +
2 s), per-stance peak sinkage and slip (``stance_metrics``: planned stance, stance foot),
deepest foot, the touchdown figures (first touchdowns on sand: depth and vertical force
20 ms and 50 ms after contact, force relative to the closed-form capacity at that depth,
the CoM's vertical speed) and the first failing signals with their times:
``pitch>5``/``roll>5`` [deg], ``com_drop>30mm`` (CoM below its height at the start of
stepping), ``tau_sat:<joint>`` (a joint torque at its URDF limit), ``slip>30mm`` (stance
foot's horizontal intrusion), ``sink>40mm``, ``qp_fail``.

``--quick`` runs two cases for 3 s (a test of the script, not a result).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

os.environ.setdefault("GRANULAR_MPC_PROXSUITE", "generic")   # bit-reproducible runs

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pinocchio as pin  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from granular_mpc.columns import foot_column, joint_columns  # noqa: E402
from granular_mpc.control.contact_model import GroundModel  # noqa: E402
from granular_mpc.control.wbc import WholeBodyController  # noqa: E402
from granular_mpc.dynamics import Plant  # noqa: E402
from granular_mpc.exceptions import PlantDivergedError  # noqa: E402
from granular_mpc.robot.model import Biped  # noqa: E402
from granular_mpc.rotations import rpy_rows_from_quat_wxyz  # noqa: E402
from granular_mpc.runlog import PlantRecorder  # noqa: E402
from granular_mpc.runner import build_simulation, check_fall, stance_metrics  # noqa: E402
from granular_mpc.runner.loop import planned_stance  # noqa: E402
from granular_mpc.runner.state import FallEvent  # noqa: E402
from granular_mpc.scenario import load_scenario  # noqa: E402
from granular_mpc.terrain import build_terrain  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "sim" / "sand_walk.yaml"
RIGID_CTRL = ("controller.terrain=rigid",)
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True)
class Case:
    """One ablation case.

    Attributes:
        name: short name (table row).
        group: the brief's candidate cause: ``ref``, ``a`` … ``e``.
        what: one line on what changes.
        overrides: scenario ``--set`` overrides on top of ``sim/sand_walk.yaml``.
        torque_lag: time constant of a first-order lag on the joint torques [s] (0: none).
        contact_gain: stance contact task gain k of ``a* = −k v`` [1/s] (None: the package's).
        switch_to_sand_at: run on rigid ground and switch the plant to sand at the first
            scheduled touchdown after this time [s] (None: sand from the start).
        armature: reflected rotor inertia of the plant's joints (abd, hip, knee; both
            legs) [kg·m²], unknown to the controller (None: none, as in the package).
        handover_fix: when the MPC force of the plan step in use disagrees with the gait
            schedule at t (a stance foot planned at zero force, or a swinging foot planned
            to carry load: the plan step's contacts are sampled at its mid-point), the WBC
            tracks gravity-sharing forces over the scheduled stance feet instead.
    """

    name: str
    group: str
    what: str
    overrides: tuple[str, ...] = ()
    torque_lag: float = 0.0
    contact_gain: float | None = None
    switch_to_sand_at: float | None = None
    armature: tuple[float, float, float] | None = None
    handover_fix: bool = False


#: reflected rotor inertia N² I_rotor of Mini-Cheetah-class actuators, per leg (abd, hip,
#: knee) [kg·m²]: I_rotor ≈ 33e-6 kg·m² (recalled from MIT Cheetah-Software's model,
#: rotorInertiaX; an estimate), gears 6, 6, 9.33
ROTOR_ARMATURE = (36 * 33e-6, 36 * 33e-6, 9.33 ** 2 * 33e-6)


CASES: tuple[Case, ...] = (
    Case("granular", "ref", "granular-aware controller (defaults, 39 ms load transfer)"),
    Case("rigid", "ref", "rigid-assumption controller, paper gait (0.4 s, 50 % swing)", RIGID_CTRL),
    Case("rigid_transfer", "ref", "rigid controller + 39 ms double support at touchdown",
         RIGID_CTRL + ("controller.gait.load_transfer=0.039",)),
    # (a) plant touchdown
    Case("a_no_added_mass", "a", "plant: no solidified-wedge added mass",
         RIGID_CTRL + ("terrain.added_mass_scale=0.0",)),
    Case("a_added_mass_x10", "a", "plant: added mass x10",
         RIGID_CTRL + ("terrain.added_mass_scale=10.0",)),
    Case("a_inertial_drag", "a", "plant: + v^2 inertial drag, c_d = 2 (Katsuragi-Durian)",
         RIGID_CTRL + ("terrain.effects=['inertial_drag:c_d=2.0']",)),
    Case("a_contact_soft", "a", "plant: contact stiffness /10 (2e4 N/m per patch)",
         RIGID_CTRL + ("terrain.contact_stiffness=2.0e4",)),
    Case("a_contact_stiff", "a", "plant: contact stiffness x10 (2e6 N/m per patch)",
         RIGID_CTRL + ("terrain.contact_stiffness=2.0e6",)),
    Case("a_zeta_x2", "a", "plant: sand twice as strong (zeta 2.72)",
         RIGID_CTRL + ("terrain.zeta=2.72",)),
    Case("a_zeta_x4", "a", "plant: sand four times as strong (zeta 5.44)",
         RIGID_CTRL + ("terrain.zeta=5.44",)),
    # (b) torque bandwidth / joint compliance
    Case("b_lag_5ms", "b", "first-order torque lag 5 ms", RIGID_CTRL, torque_lag=0.005),
    Case("b_lag_20ms", "b", "first-order torque lag 20 ms", RIGID_CTRL, torque_lag=0.020),
    Case("b_rotor_inertia", "b", "plant: reflected rotor inertia (1.2/1.2/2.9e-3 kg m^2)",
         RIGID_CTRL, armature=ROTOR_ARMATURE),
    Case("b_joint_damping", "b", "plant: viscous joint damping 0.2 N m s/rad",
         RIGID_CTRL + ("robot.joint_damping=0.2",)),
    # (c) WBC stance contact task
    Case("c_contact_k20", "c", "stance contact task a* = -20 v (the granular branch's gain)",
         RIGID_CTRL, contact_gain=20.0),
    Case("c_contact_k0", "c", "stance contact task a* = 0 (no velocity feedback)",
         RIGID_CTRL, contact_gain=0.0),
    # (d) controller rates
    Case("d_mpc_20hz", "d", "MPC at 20 Hz", RIGID_CTRL + ("controller.mpc.rate_hz=20",)),
    Case("d_mpc_100hz", "d", "MPC at 100 Hz", RIGID_CTRL + ("controller.mpc.rate_hz=100",)),
    Case("d_wbc_250hz", "d", "WBC at 250 Hz", RIGID_CTRL + ("controller.wbc.rate_hz=250",)),
    Case("d_wbc_1khz", "d", "WBC at 1 kHz", RIGID_CTRL + ("controller.wbc.rate_hz=1000",)),
    Case("d_handover_fix", "d", "WBC forces follow the schedule at t (emulated fix of the "
         "early unloading)", RIGID_CTRL, handover_fix=True),
    # (e) gait and protocol
    Case("e_paper_track", "e", "rigid plant until 4 s, then sand (the paper's track)",
         RIGID_CTRL, switch_to_sand_at=4.0),
    Case("e_touchdown_depth", "e", "swing aims 23 mm below the surface (foot pre-sunk)",
         RIGID_CTRL + ("controller.swing.touchdown_depth=0.023",)),
)
QUICK_CASES = ("rigid", "granular")

#: thresholds of the failing-signal detector
PITCH_DEG, ROLL_DEG, COM_DROP_M, SLIP_M, SINK_M = 5.0, 5.0, 0.030, 0.030, 0.040


@dataclass(frozen=True)
class Touchdowns:
    """Means over the first touchdowns on sand (up to three per foot, before any fall).

    Attributes:
        n: touchdowns averaged.
        vz_td: foot frame's vertical speed one log row before contact [m/s] (negative: down).
        depth_20ms, depth_50ms: depth of the foot 20 / 50 ms after touchdown [mm].
        fz_20ms, fz_50ms: its vertical ground force then, over the robot's weight [-].
        cap_ratio_20ms: that force over the closed-form capacity of the foot (all its
            patches) at that depth [-]
            (1: the plant is on the closed form's yield point; > 1: added mass / drag).
        other_fz_td: the other foot's vertical force at touchdown, over the weight [-].
        com_vz_min: most negative CoM vertical speed in the first 50 ms [m/s].
        t_to_weight: time until the new foot carries the weight (F_z ≥ W) [ms] (nan: never
            within the stance's first 150 ms).
    """

    n: int
    vz_td: float
    depth_20ms: float
    depth_50ms: float
    fz_20ms: float
    fz_50ms: float
    cap_ratio_20ms: float
    other_fz_td: float
    com_vz_min: float
    t_to_weight: float


@dataclass(frozen=True)
class CaseResult:
    """One case at one speed (see the module docstring for the columns)."""

    case: str
    group: str
    speed: float
    seconds: float
    fell_at: float | None
    fall_reason: str
    mean_speed: float | None
    sinkage_peak_mm: float | None
    slip_mm: float | None
    max_depth_mm: float
    touchdowns: Touchdowns | None
    first_signals: tuple[tuple[str, float], ...]
    wall_s: float
    notes: tuple[str, ...] = field(default_factory=tuple)

    def row(self) -> str:
        """One Markdown table row."""
        def f(x, fmt):
            return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)
        fell = f"{self.fell_at:.2f} s" if self.fell_at is not None else "—"
        td = self.touchdowns
        tds = (f"{f(td.vz_td, '+.2f')} | {f(td.depth_20ms, '.0f')}/{f(td.depth_50ms, '.0f')} | "
               f"{f(td.fz_20ms, '.2f')}/{f(td.fz_50ms, '.2f')} | {f(td.cap_ratio_20ms, '.2f')} | "
               f"{f(td.t_to_weight, '.0f')}" if td else "— | — | — | — | —")
        sig = ", ".join(f"{n}@{t:.2f}" for n, t in self.first_signals[:3]) or "none"
        return (f"| {self.case} | {self.speed:.1f} | {fell} | {f(self.mean_speed, '.3f')} | "
                f"{f(self.sinkage_peak_mm, '.1f')} | {f(self.slip_mm, '.1f')} | "
                f"{self.max_depth_mm:.1f} | {tds} | {sig} |")


HEADER = ("| case | v [m/s] | fell | mean v [m/s] | sink peak [mm] | slip [mm] | deepest [mm] | "
          "v_z at td [m/s] | depth +20/+50 ms [mm] | F_z/W +20/+50 ms | F_z/F_cap +20 ms | "
          "t to F_z=W [ms] | first failing signals (t [s]) |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|")


# ----------------------------------------------------------------------------- emulations
def with_contact_gain(sim, gain: float):
    """The simulation with the WBC's stance contact task ``a* = −gain·v`` (rigid ground
    model otherwise): a WBC whose ground model reports ``granular`` (selecting the branch
    ``a* = −contact_damping·v − sink_accel``, sink_accel = 0 for a rigid ground model) with
    the rigid ground's polytope."""
    ctrl = sim.controller
    g = ctrl.ground
    proxy = GroundModel("granular", g.polytope, g.surface_height,
                        np.array([0.0, 1.0]), np.array([g.polytope.f_max, g.polytope.f_max]))
    wbc = dataclasses.replace(ctrl.wbc, ground=proxy, contact_damping=float(gain))
    return dataclasses.replace(sim, controller=dataclasses.replace(ctrl, wbc=wbc))


class ScheduledForcesWBC(WholeBodyController):
    """The package's WBC, but the MPC forces it tracks are replaced by gravity sharing over
    the scheduled stance feet whenever the plan step disagrees with the schedule at t."""

    def solve(self, data, q, v, ref, feet):
        fz = ref.forces[:, :, 2].sum(axis=1)
        st = ref.stance
        if any((st[i] and fz[i] <= 1e-9) or (not st[i] and fz[i] > 1e-9) for i in range(2)):
            forces = np.zeros_like(ref.forces)
            n = max(sum(st), 1)
            for i in range(2):
                if st[i]:
                    forces[i, :, 2] = self.biped.weight / n / forces.shape[1]
            ref = dataclasses.replace(ref, forces=forces)
        return super().solve(data, q, v, ref, feet)


def with_handover_fix(sim):
    """The simulation with :class:`ScheduledForcesWBC` in place of the WBC."""
    ctrl = sim.controller
    w = ctrl.wbc
    wbc = ScheduledForcesWBC(**{f.name: getattr(w, f.name) for f in dataclasses.fields(w)})
    return dataclasses.replace(sim, controller=dataclasses.replace(ctrl, wbc=wbc))


def with_armature(sim, armature):
    """The simulation whose plant (only) has reflected rotor inertia ``armature`` per leg
    (abd, hip, knee) [kg·m²]: a second robot model for the plant; the controller's model
    stays without it."""
    biped = Biped.from_config(sim.scenario.robot)
    arm = np.tile(np.asarray(armature, dtype=float), 2)      # actuator order, both legs
    biped.model.armature[biped.idx_v] = arm
    plant = Plant(biped, sim.plant.terrain, sim.scenario.sim)
    return dataclasses.replace(sim, plant=plant)


def switch_plant(sim, pd, sand_terrain):
    """A sand plant and its data continuing from ``pd`` (same time, state and torque)."""
    plant = dataclasses.replace(sim.plant, terrain=sand_terrain)
    nd = plant.new_data(pd.q.copy(), pd.v.copy())
    nd.t, nd.steps = pd.t, pd.steps
    nd.set_torque(pd.tau_a)
    return plant, nd


# ----------------------------------------------------------------------------- one run
def run_case(case: Case, speed: float, seconds: float) -> tuple[CaseResult, pd.DataFrame]:
    """Run ``case`` at ``speed`` [m/s] for ``seconds`` [s]; the result and the log rows."""
    # the reference plant: switch_plant rebuilds it with another terrain and reads its
    # Pinocchio data (the compiled plant has neither)
    overrides = [f"command.speed={speed}", f"sim.duration={seconds}", "output.plots=false",
                 "sim.plant=reference"]
    overrides += list(case.overrides)
    sand_terrain = None
    if case.switch_to_sand_at is not None:
        sand_sc = load_scenario(SCENARIO, overrides)
        overrides.append("terrain=rigid")
    sc = load_scenario(SCENARIO, overrides)
    sim = build_simulation(sc)
    if case.switch_to_sand_at is not None:
        sand_terrain = build_terrain(sand_sc.terrain, sand_sc.robot)
    if case.contact_gain is not None:
        sim = with_contact_gain(sim, case.contact_gain)
    if case.armature is not None:
        sim = with_armature(sim, case.armature)
    if case.handover_fix:
        sim = with_handover_fix(sim)
    st = sim.new_state()
    ctrl, cd = sim.controller, st.controller
    plant, pdata = sim.plant, st.plant
    recorder = PlantRecorder(sim.biped)
    t_switch = None
    if case.switch_to_sand_at is not None:
        sched = ctrl.schedule
        t = case.switch_to_sand_at
        while not (sched.contacts(t) != sched.contacts(t - sim.dt) and any(
                sched.contacts(t)[i] and not sched.contacts(t - sim.dt)[i] for i in range(2))):
            t += sim.dt
        t_switch = t
    lag = case.torque_lag
    alpha = sim.dt / (lag + sim.dt) if lag > 0.0 else 1.0
    tau_cmd = np.zeros(len(sim.biped.joint_names))
    tau_app = tau_cmd.copy()
    rows = []
    fall = None
    t0 = time.perf_counter()
    with threadpool_limits(limits=1, user_api="blas"):
        for k in range(sim.n_steps + 1):
            t = pdata.t
            if t_switch is not None and t >= t_switch - 0.5 * sim.dt:
                plant, pdata = switch_plant(sim, pdata, sand_terrain)
                st.plant = pdata
                t_switch = None
            if k % sim.control_every == 0:
                tau_cmd = ctrl.compute(cd, t, pdata.q, pdata.v)
                why = check_fall(sim, pdata.q)
                if why is not None and fall is None:
                    fall = FallEvent(t, why)
            if lag > 0.0:
                tau_app = tau_app + alpha * (tau_cmd - tau_app)
                pdata.set_torque(tau_app)
            elif k % sim.control_every == 0:
                pdata.set_torque(tau_cmd)
            if k % sim.log_every == 0 or fall is not None:
                extra = {"qp_failures": int(cd.qp_failures),
                         "on_sand": int(plant.terrain.kind != "rigid")}
                for side in ("left", "right"):   # foot-frame velocity (last evaluation)
                    extra[foot_column(side, "vz")] = float(pin.getFrameVelocity(
                        sim.biped.model, pdata.pin, sim.biped.foot_frame[side], LWA).linear[2])
                rows.append(recorder.row(pdata, stance=planned_stance(ctrl.schedule, t),
                                         extra=extra))
            if fall is not None or k == sim.n_steps:
                break
            try:
                plant.step(pdata)
            except PlantDivergedError as exc:   # recorded as a fall, with the reason
                fall = FallEvent(pdata.t, f"plant diverged ({exc.reason})")
                break
    wall = time.perf_counter() - t0
    df = pd.DataFrame.from_records(rows)
    return analyse(case, speed, seconds, sim, df, fall, wall), df


# ----------------------------------------------------------------------------- analysis
def analyse(case: Case, speed: float, seconds: float, sim, df: pd.DataFrame,
            fall: FallEvent | None, wall: float) -> CaseResult:
    sc = sim.scenario
    t_walk = sim.controller.schedule.start
    t_after = sc.command.start_delay + 2.0
    if case.switch_to_sand_at is not None:
        t_after = max(t_after, case.switch_to_sand_at + 1.0)
    tail = df[df.time > t_after]
    mean_speed = None
    if fall is None and len(tail) > 10:
        mean_speed = float((tail.com_x.iloc[-1] - tail.com_x.iloc[0])
                           / (tail.time.iloc[-1] - tail.time.iloc[0]))
    sand = df[df.on_sand == 1]
    m = stance_metrics(sand) if len(sand) else {}
    depth = np.maximum(sand[foot_column("left", "depth")].to_numpy(),
                       sand[foot_column("right", "depth")].to_numpy()) if len(sand) else np.zeros(1)
    return CaseResult(case.name, case.group, speed, seconds,
                      fall.time if fall else None, fall.reason if fall else "",
                      mean_speed, m.get("sinkage_peak_mm_mean"), m.get("slip_mm_mean"),
                      1e3 * float(depth.max()), touchdown_stats(sim, sand),
                      failing_signals(sim, df[df.time >= t_walk]), wall)


def touchdown_stats(sim, df: pd.DataFrame, per_foot: int = 3) -> Touchdowns | None:
    """Touchdown figures over the first ``per_foot`` sand touchdowns of each foot."""
    if len(df) < 10:
        return None
    W = sim.biped.weight
    n_patch = sim.biped.config.foot.slices     # cap_z is the mean over the foot's patches
    t = df.time.to_numpy()
    dt = float(np.median(np.diff(t)))
    t_walk = sim.controller.schedule.start
    recs = []
    for i, side in enumerate(("left", "right")):
        other = ("left", "right")[1 - i]
        c = df[foot_column(side, "contact")].to_numpy()
        vz = df[foot_column(side, "vz")].to_numpy()
        fz = df[foot_column(side, "grf_z")].to_numpy()
        cap = df[foot_column(side, "cap_z")].to_numpy()
        dep = df[foot_column(side, "depth")].to_numpy()
        fo = df[foot_column(other, "grf_z")].to_numpy()
        vcz = df["com_vz"].to_numpy()
        starts = [j for j in range(1, len(c)) if c[j] == 1 and c[j - 1] == 0 and t[j] > t_walk]
        for j in starts[:per_foot]:
            j20, j50 = j + int(round(0.02 / dt)), j + int(round(0.05 / dt))
            if j50 >= len(c):
                continue
            j150 = min(j + int(round(0.15 / dt)), len(c))
            above = np.flatnonzero(fz[j:j150] >= W)
            recs.append((
                vz[j - 1], 1e3 * dep[j20], 1e3 * dep[j50], fz[j20] / W,
                fz[j50] / W, fz[j20] / (n_patch * cap[j20]) if cap[j20] > 1e-6 else math.nan,
                fo[j] / W,
                float(vcz[j:j50].min()),
                1e3 * above[0] * dt if len(above) else math.nan))
    if not recs:
        return None
    a = np.array(recs, dtype=float)
    with np.errstate(all="ignore"):
        mean = [float(np.nanmean(a[:, k])) if np.isfinite(a[:, k]).any() else math.nan
                for k in range(a.shape[1])]
    return Touchdowns(len(recs), *mean)


def failing_signals(sim, df: pd.DataFrame) -> tuple[tuple[str, float], ...]:
    """First time each failing signal trips (sorted by time)."""
    if len(df) == 0:
        return ()
    t = df.time.to_numpy()
    out: dict[str, float] = {}

    def first(name, mask):
        idx = np.flatnonzero(mask)
        if len(idx):
            out[name] = float(t[idx[0]])

    rpy = rpy_rows_from_quat_wxyz(df[["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy())
    first(f"pitch>{PITCH_DEG:g}", np.abs(np.degrees(rpy[:, 1])) > PITCH_DEG)
    first(f"roll>{ROLL_DEG:g}", np.abs(np.degrees(rpy[:, 0])) > ROLL_DEG)
    first("com_drop>30mm", df.com_z.to_numpy() < df.com_z.iloc[0] - COM_DROP_M)
    names = sim.biped.joint_names
    lim = sim.biped.torque_limits
    tau = df[joint_columns(names, "tau")].to_numpy()
    sat = np.abs(tau) >= 0.99 * np.asarray(lim)[None, :]
    for j, n in enumerate(names):
        first(f"tau_sat:{n}", sat[:, j])
    first("slip>30mm", np.hypot(df.intrusion_x.to_numpy(), df.intrusion_y.to_numpy()) > SLIP_M)
    first("sink>40mm", np.maximum(df[foot_column("left", "depth")].to_numpy(),
                                  df[foot_column("right", "depth")].to_numpy()) > SINK_M)
    first("qp_fail", df.qp_failures.to_numpy() > 0)
    return tuple(sorted(out.items(), key=lambda kv: kv[1]))


# ----------------------------------------------------------------------------- main
def to_json(r: CaseResult) -> dict:
    d = dataclasses.asdict(r)
    d["first_signals"] = [list(s) for s in r.first_signals]
    return d


def main(argv=None) -> list[CaseResult]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=float, nargs="+", default=[0.2, 0.4])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--cases", nargs="+", default=None, help="case names (default: all)")
    ap.add_argument("--json", default=None, help="write the results as JSON to this path")
    ap.add_argument("--logs", default=None, help="folder for each run's rows (Parquet)")
    ap.add_argument("--quick", action="store_true", help="2 cases x 3 s at the first speed")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    args = ap.parse_args(argv)
    by_name = {c.name: c for c in CASES}
    if args.list:
        for c in CASES:
            print(f"{c.name:20s} ({c.group}) {c.what}")
        return []
    names = args.cases or [c.name for c in CASES]
    speeds, seconds = args.speeds, args.seconds
    if args.quick:
        names, speeds, seconds = list(QUICK_CASES), speeds[:1], 3.0
    unknown = [n for n in names if n not in by_name]
    if unknown:
        ap.error(f"unknown case(s) {unknown}; known: {sorted(by_name)}")
    print(f"GRANULAR_MPC_PROXSUITE={os.environ['GRANULAR_MPC_PROXSUITE']}, "
          f"{seconds:g} s per run, speeds {speeds}", flush=True)
    print(HEADER, flush=True)
    results = []
    for name in names:
        for v in speeds:
            res, df = run_case(by_name[name], v, seconds)
            results.append(res)
            print(res.row(), flush=True)
            if args.logs:
                Path(args.logs).mkdir(parents=True, exist_ok=True)
                df.to_parquet(Path(args.logs) / f"{name}_v{v:.1f}.parquet")
            if args.json:
                Path(args.json).write_text(json.dumps([to_json(r) for r in results], indent=1))
    print(f"total wall time {sum(r.wall_s for r in results):.0f} s", file=sys.stderr)
    return results


if __name__ == "__main__":
    main()
