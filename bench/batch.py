"""Batched plant throughput: one `name: value unit` line per figure.

    python bench/batch.py [--robots 64] [--seconds 0.2] [--threads N] [--json PATH]

Figures (measured in this process, side by side, all robots on dry sand, both feet in
contact: the robots start standing 5 mm above the sand with small per-robot offsets and
are stepped 0.1 s first; PD law to the standing pose in the loop, 150 N·m/rad, 3 N·m·s/rad):

* batch_env_steps_per_s — robot-steps of the 0.5 ms plant per wall second,
  :class:`granular_mpc.dynamics.batch.BatchPlant` with ``parallelization="thread"`` over
  ``--threads`` (default: all CPUs) — the figure of issue 12 (target ≥ 200 k on 2 cores);
* batch_env_steps_per_s_serial — the same batch, one thread;
* batch_thread_speedup — their ratio (how well the cores are used; on a machine loaded
  by other processes it says little);
* batch_cpu_us_per_env_step / _serial — process CPU time per robot-step [µs], threaded and
  serial: what a robot-step costs a core, much less sensitive to the machine's load than
  wall-clock rates (an idle machine with C cores approaches C / this per µs);
* single_compiled_steps_per_s — one robot, :class:`CompiledPlant`, chunked calls;
* gym_vector_env_steps_per_s / gym_vector_plant_steps_per_s — the Gymnasium vector env
  (``granular_mpc/BipedSand-v0``, same robots, zero action) in policy steps (100 Hz) and
  plant steps, including its observation/reward work (skipped without gymnasium).

Each figure is the median of 3 repetitions. The machine is shared: report ``uptime``'s load.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
from _report import emit

from granular_mpc.config import DropConfig, SimConfig, load_robot, load_terrain
from granular_mpc.dynamics import Plant
from granular_mpc.dynamics.batch import BatchPlant
from granular_mpc.dynamics.compiled import CompiledPlant
from granular_mpc.robot import Biped
from granular_mpc.terrain import build_terrain

DROP = DropConfig()


def batch_rate(fast, biped, robots, steps, parallelization, threads, reps=3):
    """(median robot-steps per wall second, median process CPU µs per robot-step) of
    ``robots`` robots stepped ``steps`` steps per repetition."""
    batch = BatchPlant(fast, robots, parallelization=parallelization, threads=threads)
    rng = np.random.default_rng(0)
    q0 = np.tile(biped.standing_configuration(0.005), (robots, 1))
    q0[:, 2] += rng.uniform(-0.002, 0.002, robots)
    q_hold = biped.actuated(q0[0])
    gains = dict(q_ref=q_hold, kp=DROP.kp, kd=DROP.kd)
    s = batch.step(batch.initial_state(q0), n_steps=200, **gains)
    rates, cpu = [], []
    for _ in range(reps):
        t0, c0 = time.perf_counter(), time.process_time()
        s = batch.step(s, n_steps=steps, **gains)
        rates.append(robots * steps / (time.perf_counter() - t0))
        cpu.append((time.process_time() - c0) / (robots * steps) * 1e6)
    assert not s.diverged.any()
    assert s.foot_in_contact(0).all() and s.foot_in_contact(1).all(), "a foot left the sand"
    return statistics.median(rates), statistics.median(cpu)


def single_rate(fast, biped, steps, reps=3):
    s = fast.initial_state(biped.standing_configuration(0.005))
    q_hold = biped.actuated(s.q)
    s = fast.step(s, n_steps=200, q_ref=q_hold, kp=DROP.kp, kd=DROP.kd)
    rates = []
    for _ in range(reps):
        t0 = time.perf_counter()
        s = fast.step(s, n_steps=steps, q_ref=q_hold, kp=DROP.kp, kd=DROP.kd)
        rates.append(steps / (time.perf_counter() - t0))
    return statistics.median(rates)


def gym_rate(robots, env_steps, threads, reps=3):
    try:
        import gymnasium as gym

        import granular_mpc.envs as envs
    except ImportError:
        return None, None
    venv = gym.make_vec(envs.ENV_ID, num_envs=robots, vectorization_mode="vector_entry_point",
                        threads=threads)
    venv.reset(seed=0)
    action = np.zeros((robots, 6), np.float32)
    rates = []
    for _ in range(reps):
        t0 = time.perf_counter()
        for _ in range(env_steps):
            venv.step(action)
        rates.append(robots * env_steps / (time.perf_counter() - t0))
    skip = venv.unwrapped.task.frame_skip
    venv.close()
    rate = statistics.median(rates)
    return rate, rate * skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=64)
    ap.add_argument("--seconds", type=float, default=0.2, help="simulated seconds per rep")
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--json", metavar="PATH", help="also write the figures to PATH")
    args = ap.parse_args()
    threads = args.threads or os.cpu_count() or 1

    robot = load_robot("yobogo10s")
    biped = Biped.from_config(robot, with_visuals=False)
    fast = CompiledPlant(Plant(biped, build_terrain(load_terrain("dry_sand"), robot), SimConfig()))
    steps = max(fast.chunk, int(round(args.seconds / fast.dt)))
    threaded, cpu_threaded = batch_rate(fast, biped, args.robots, steps, "thread", threads)
    serial, cpu_serial = batch_rate(fast, biped, args.robots, steps, "serial", 1)
    figures = {"batch_env_steps_per_s": threaded,
               "batch_env_steps_per_s_serial": serial,
               "batch_thread_speedup": threaded / serial,
               "batch_cpu_us_per_env_step": cpu_threaded,
               "batch_cpu_us_per_env_step_serial": cpu_serial,
               "batch_robots": args.robots,
               "batch_threads": threads,
               "single_compiled_steps_per_s": single_rate(fast, biped, steps * 4)}
    env_rate, env_plant_rate = gym_rate(args.robots, max(2, steps // 20), threads)
    if env_rate is not None:
        figures["gym_vector_env_steps_per_s"] = env_rate
        figures["gym_vector_plant_steps_per_s"] = env_plant_rate
    emit(figures, args.json, units={"_per_s": "steps/s", "_per_s_serial": "steps/s",
                                    "speedup": "x", "_env_step": "us", "_step_serial": "us"})


if __name__ == "__main__":
    main()
