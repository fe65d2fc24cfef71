"""Roll out a PD balance policy on ``granular_mpc/BipedSand-v0`` (vector env), headless.

The Gymnasium environment steps a batch of bipeds on dry sand with one call of the
compiled, batched plant per environment step (``granular_mpc.envs``, optional extra
``gym``). The policy is a hand-written PD on the trunk attitude read from the observation
(hip pitch targets follow the trunk pitch, hip abduction targets its roll, knees held at
the standing pose): a baseline, not a walker — on its rolling semi-cylindrical soles the
robot cannot stand still, so episodes end in a fall after ≈ 1.4 s and restart
(Gymnasium's autoreset); learning to step is what the environment is for.

    python examples/gym_rollout.py [--num-envs 16] [--steps 200]

Prints the episodes' mean return and length and, last, the throughput:
``env_steps_per_s`` (robot-steps of the policy, 100 Hz each) and ``plant_steps_per_s``
(robot-steps of the 0.5 ms plant). ``GRANULAR_MPC_EXAMPLE_SECONDS`` (simulated seconds
per robot) overrides ``--steps``.
"""

import argparse
import os
import time

import gymnasium as gym
import numpy as np

import granular_mpc.envs as envs

NAMES = list(envs.OBS_NAMES)
I_QUAT = [NAMES.index(f"base_q{c}") for c in "xyzw"]
I_W = [NAMES.index(f"base_w{c}_B") for c in "xyz"]


def pd_policy(obs: np.ndarray) -> np.ndarray:
    """Actions (n, 6) in [-1, 1] from observations (n, 28): attitude PD on the hips."""
    x, y, z, w = (obs[:, i] for i in I_QUAT)
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
    wx, wy = obs[:, I_W[0]], obs[:, I_W[1]]
    hip_pitch = 0.5 * pitch + 0.05 * wy
    hip_abd = 0.5 * roll + 0.05 * wx
    a = np.zeros((len(obs), 6))
    a[:, 0], a[:, 3] = hip_abd, hip_abd          # left / right hip abduction
    a[:, 1], a[:, 4] = hip_pitch, hip_pitch      # left / right hip pitch
    return np.clip(a, -1.0, 1.0).astype(np.float32)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--num-envs", type=int, default=16)
    ap.add_argument("--steps", type=int, default=200, help="environment steps per robot")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    seconds = os.environ.get("GRANULAR_MPC_EXAMPLE_SECONDS")
    venv = gym.make_vec(envs.ENV_ID, num_envs=args.num_envs,
                        vectorization_mode="vector_entry_point")
    frame_skip = venv.unwrapped.task.frame_skip
    dt = venv.unwrapped.plant.dt
    steps = int(round(float(seconds) / (frame_skip * dt))) if seconds else args.steps
    obs, _ = venv.reset(seed=args.seed)
    returns, lengths = [], []
    ret = np.zeros(args.num_envs)
    length = np.zeros(args.num_envs, int)
    t0 = time.perf_counter()
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = venv.step(pd_policy(obs))
        ret += reward
        length += 1
        for i in np.flatnonzero(terminated | truncated):
            returns.append(ret[i])
            lengths.append(length[i])
            ret[i], length[i] = 0.0, -1          # the next step is the autoreset step
    wall = time.perf_counter() - t0
    venv.close()
    returns += [r for r, n in zip(ret, length) if n > 0]
    lengths += [n for n in length if n > 0]
    env_steps = steps * args.num_envs
    print(f"episodes: {len(returns)}")
    print(f"mean_return: {np.mean(returns):.2f}")
    print(f"mean_length_steps: {np.mean(lengths):.1f}")
    print(f"env_steps_per_s: {env_steps / wall:.4g}")
    print(f"plant_steps_per_s: {env_steps * frame_skip / wall:.4g}")


if __name__ == "__main__":
    main()
