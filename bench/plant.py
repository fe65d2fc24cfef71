"""Plant and terrain-law speed: one `name: value unit` line per figure.

    python bench/plant.py [--json PATH]

Figures (all measured in this process, side by side):

* plant_steps_per_s_sand / _rigid — one plant, both feet in contact (robot settled by a
  guide-rig drop, rig then removed), PD torques recomputed every step, default dt and
  integrator; wall time of ``Plant.step`` plus the PD law, nothing else.
* plant_realtime_factor_sand — the same as simulated seconds per wall second.
* plant_steps_per_s_sand_compiled / _rigid_compiled — the same robot, state and PD law on
  :class:`granular_mpc.dynamics.compiled.CompiledPlant` (the whole step one compiled C
  function, the PD law inside it, ``chunk`` = 10 steps per call), measured right after the
  reference from the same settled state; ``plant_compiled_speedup_sand`` is the ratio.
* plant_steps_per_s_sand_fast_plant — the same through ``FastPlant``, the drop-in with
  ``Plant``'s interface (``plant.step(d, tau)``, read-outs as ``PlantData``).
* plant_cpu_us_per_step_sand / _sand_compiled — process CPU time per step [µs] of the
  two (much less sensitive than wall-clock rates to a machine loaded by other processes).
* plant_steps_per_s_sand_compiled_per_step — compiled, one call per step with the PD
  torque computed in Python and written into ``CompiledData.tau``
  (``CompiledPlant.advance``: what a Python controller stepping the plant sees).
* contact_call_us_jit / _vm — one evaluation of a foot's compiled contact function (2
  patches) through its buffer interface, C-compiled vs CasADi's VM (GRANULAR_MPC_JIT=0);
  contact_jit_speedup is their ratio.
* closed_form_call_us — one float closed-form evaluation (sagittal_forces) of a slice.
* closed_form_speedup — closed form vs the brute-force RFT integration of
  terrain.rft_numeric (default resolution n = 4000), same inputs.

Profile (cProfile of 4000 sand steps, both feet in contact, plus micro-timings of each
C++ call at the same state; shared 2-core machine, 90–140 µs per step): the step is
dominated by Python/NumPy glue, not by physics. Pinocchio (aba 4.6 µs, computeMinverse
4.2 µs — paid every step because the PD torque changes every step and Verlet corrects
the reused acceleration by M⁻¹Δτ —, forward kinematics 1.3 µs, frame placement/velocity
≈ 1 µs per foot, integrate 1.3 µs) is ≈ 15 µs, and the two compiled contact calls
≈ 6.5 µs; the rest (≈ 75 %) is interpreter work in ``Plant.forward`` (self time ≈ 45 µs:
array slicing into the contact buffers, ``pin.Force`` construction, the end-stop check,
the ``_clear_height`` property recomputing the sole radius) and ``Plant.step`` (≈ 25 µs:
vector arithmetic, the divergence check's reductions), ``PlantData.set_torque``
(``np.array_equal``, ≈ 12 µs) and ``ContactData.commit`` (≈ 4 µs). The compiled plant
removes that glue: the whole step is one C function (``CompiledPlant``; its own profile,
in ``granular_mpc/dynamics/compiled.py``, is dominated by the two feet's terrain law,
≈ 60 %, then ABA and the Verlet M⁻¹Δτ correction).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np
import pinocchio as pin

from granular_mpc.config import DropConfig, GuideRigConfig, SimConfig, load_robot, load_terrain
from granular_mpc.dynamics import Plant
from granular_mpc.dynamics.compiled import CompiledPlant
from granular_mpc.dynamics.fast_plant import FastPlant
from granular_mpc.robot import Biped
from granular_mpc.terrain import build_terrain
from granular_mpc.terrain.closed_form import FLOAT, FootShape, sagittal_forces
from granular_mpc.terrain.rft_numeric import sagittal_forces_numeric

DROP, RIG = DropConfig(), GuideRigConfig()
#: process CPU time per step [µs] of the last rate measurement, by terrain kind and path
CPU_US: dict[str, float] = {}


def settled(biped, terrain, seconds=0.8):
    """Plant data of the PD-held robot dropped on a guide rig and settled; rig removed."""
    plant = Plant(biped, terrain, SimConfig())
    q0 = biped.standing_configuration(DROP.height)
    d = plant.new_data(q0)
    p0 = q0[0:3].copy()

    def rig(q, v):
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        f = np.zeros(3)
        f[0:2] = -RIG.stiffness * (q[0:2] - p0[0:2]) - RIG.damping * (R @ v[0:3])[0:2]
        return np.concatenate([f, -RIG.rot_stiffness * pin.log3(R) - RIG.rot_damping * (R @ v[3:6])])

    d.base_wrench = rig
    q_hold = biped.actuated(q0)
    for _ in range(int(seconds / plant.dt)):
        plant.step(d, pd(biped, d, q_hold))
    d.base_wrench = None
    return plant, d, q_hold


def pd(biped, d, q_hold):
    return DROP.kp * (q_hold - d.q[biped.idx_q]) - DROP.kd * d.v[biped.idx_v]


def plant_rate(biped, terrain, steps=3000):
    """Steps per wall second with both feet in contact (checked before and after)."""
    plant, d, q_hold = settled(biped, terrain)
    assert d.foot_in_contact(0) and d.foot_in_contact(1), "a foot is off the ground"
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        plant.step(d, pd(biped, d, q_hold))
    wall = time.perf_counter() - t0
    CPU_US[terrain.kind] = (time.process_time() - c0) / steps * 1e6
    assert d.foot_in_contact(0) and d.foot_in_contact(1), "a foot left the ground"
    return steps / wall, plant.dt


def compiled_rates(biped, terrain, steps=20000):
    """(chunked PD-in-the-loop, per-step Python PD) steps/s of the compiled plant."""
    plant, d, q_hold = settled(biped, terrain)
    fast = CompiledPlant(plant)
    s = fast.state_from_data(d)
    kp, kd = np.full(6, DROP.kp), np.full(6, DROP.kd)
    t0, c0 = time.perf_counter(), time.process_time()
    s1 = fast.step(s, n_steps=steps, q_ref=q_hold, kp=kp, kd=kd)
    chunked = steps / (time.perf_counter() - t0)
    CPU_US[terrain.kind + "_compiled"] = (time.process_time() - c0) / steps * 1e6
    assert s1.foot_in_contact(0) and s1.foot_in_contact(1), "a foot left the ground"
    n = steps // 4
    d = fast.data_from_state(s)
    iq, iv = biped.idx_q, biped.idx_v
    t0 = time.perf_counter()
    for _ in range(n):
        d.tau[:] = kp * (q_hold - d.q[iq]) - kd * d.v[iv]
        fast.advance(d)
    per_step = n / (time.perf_counter() - t0)
    # the drop-in: Plant's interface (plant.step(d, tau)) on the compiled step
    drop_in = FastPlant(plant, fast)
    d = drop_in.new_data(s.q, s.v)
    drop_in.step(d, pd(biped, d, q_hold))
    t0 = time.perf_counter()
    for _ in range(n):
        drop_in.step(d, pd(biped, d, q_hold))
    drop_in_rate = n / (time.perf_counter() - t0)
    return chunked, per_step, drop_in_rate


def contact_call_us(terrain, calls=20000):
    """µs per call of one foot's contact function with a foot pressed into the terrain."""
    data = terrain.new_data(5e-4)
    foot = data.feet[0]
    foot.kin[0:3] = [0.0, 0.0, terrain.foot.radius - 0.012]
    foot.kin[3:12] = np.eye(3).ravel("F")
    foot.kin[12:18] = [0.01, 0.0, -0.05, 0.0, 0.1, 0.0]
    data.evaluate(0)
    data.commit()
    t0 = time.perf_counter()
    for _ in range(calls):
        data.evaluate(0)
    return (time.perf_counter() - t0) / calls * 1e6


def closed_form_speedup(shape):
    phi = math.radians(38.0)
    cases = [(0.012, 0.0, 0.0, -1.0), (0.025, -0.2, 0.7, -0.3), (0.008, 0.1, -0.5, 0.4)]
    reps = 300
    t0 = time.perf_counter()
    for _ in range(reps):
        for c in cases:
            sagittal_forces(FLOAT, shape, phi, *c, zeta=1.36)
    t_cf = (time.perf_counter() - t0) / (reps * len(cases))
    t0 = time.perf_counter()
    for c in cases:
        sagittal_forces_numeric(shape, phi, *c, zeta=1.36)
    t_num = (time.perf_counter() - t0) / len(cases)
    return t_num / t_cf, t_cf * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", metavar="PATH", help="also write the figures to PATH")
    args = parser.parse_args()

    robot = load_robot("yobogo10s")
    biped = Biped.from_config(robot, with_visuals=False)
    sand = build_terrain(load_terrain("dry_sand"), robot)
    rigid = build_terrain(load_terrain("rigid"), robot)
    old = os.environ.get("GRANULAR_MPC_JIT")
    os.environ["GRANULAR_MPC_JIT"] = "0"
    try:
        sand_vm = build_terrain(load_terrain("dry_sand"), robot)
    finally:
        if old is None:
            del os.environ["GRANULAR_MPC_JIT"]
        else:
            os.environ["GRANULAR_MPC_JIT"] = old

    figures: list[tuple[str, float, str]] = []
    rate_sand, dt = plant_rate(biped, sand)
    rate_rigid, _ = plant_rate(biped, rigid)
    fast_sand, fast_sand_py, fast_sand_drop_in = compiled_rates(biped, sand)
    fast_rigid, _, _ = compiled_rates(biped, rigid)
    figures += [("plant_steps_per_s_sand", rate_sand, "steps/s"),
                ("plant_steps_per_s_rigid", rate_rigid, "steps/s"),
                ("plant_realtime_factor_sand", rate_sand * dt, "x"),
                ("plant_steps_per_s_sand_compiled", fast_sand, "steps/s"),
                ("plant_steps_per_s_rigid_compiled", fast_rigid, "steps/s"),
                ("plant_steps_per_s_sand_compiled_per_step", fast_sand_py, "steps/s"),
                ("plant_steps_per_s_sand_fast_plant", fast_sand_drop_in, "steps/s"),
                ("plant_compiled_speedup_sand", fast_sand / rate_sand, "x"),
                ("plant_realtime_factor_sand_compiled", fast_sand * dt, "x"),
                ("plant_cpu_us_per_step_sand", CPU_US["granular"], "us"),
                ("plant_cpu_us_per_step_sand_compiled", CPU_US["granular_compiled"], "us")]
    jit_us, vm_us = contact_call_us(sand), contact_call_us(sand_vm, calls=4000)
    figures += [("contact_call_us_jit", jit_us, "us"), ("contact_call_us_vm", vm_us, "us"),
                ("contact_jit_speedup", vm_us / jit_us, "x")]
    speedup, cf_us = closed_form_speedup(FootShape.from_geometry(robot.foot))
    figures += [("closed_form_call_us", cf_us, "us"), ("closed_form_speedup", speedup, "x")]

    for name, value, unit in figures:
        print(f"{name}: {value:.4g} {unit}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump({name: value for name, value, _ in figures}, fh, indent=2)


if __name__ == "__main__":
    main()
