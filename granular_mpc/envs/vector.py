"""The vector version of ``granular_mpc/BipedSand-v0`` on the batched compiled plant."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..dynamics.batch import BatchPlant
from .task import OBS_NAMES, WalkTask


class BipedSandVectorEnv(VectorEnv):
    """``num_envs`` bipeds on sand stepped together by one :class:`BatchPlant` call.

    Same observation, action, reward, termination and reset as
    :class:`~granular_mpc.envs.biped_sand.BipedSandEnv` (see there), row per robot;
    the robots are spread over the cores (``parallelization``, ``threads`` of
    :class:`~granular_mpc.dynamics.batch.BatchPlant`). Episodes that end are reset on the
    next :meth:`step` (Gymnasium's ``NEXT_STEP`` autoreset: that step ignores their action
    and returns their first observation with reward 0). Truncation after
    ``max_episode_steps`` steps.

    Args:
        num_envs: number of robots.
        max_episode_steps: truncation length (default 1000 steps = 10 s).
        parallelization, threads: passed to :class:`BatchPlant`.
        **task: fields of :class:`~granular_mpc.envs.task.WalkTask`.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 8, *, max_episode_steps: int = 1000,
                 parallelization: str = "thread", threads: int | None = None,
                 render_mode: str | None = None, **task) -> None:
        if render_mode is not None:
            raise ValueError(f"render_mode {render_mode!r} is not supported")
        if isinstance(task.get("theta_ranges"), dict):
            task["theta_ranges"] = tuple(task["theta_ranges"].items())
        self.task = dataclasses.replace(WalkTask(), **task)
        self.plant = self.task.build()
        self.num_envs = int(num_envs)
        self.max_episode_steps = int(max_episode_steps)
        self.batch = BatchPlant(self.plant, self.num_envs, parallelization=parallelization,
                                threads=threads)
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, (6,), np.float32)
        self.single_observation_space = gym.spaces.Box(-np.inf, np.inf, (len(OBS_NAMES),),
                                                       np.float32)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.render_mode = None
        self._q_stand = self.task.standing_joints(self.plant)
        self._rng = np.random.default_rng()
        self._state = None
        self._theta = None
        self._prev = np.zeros((self.num_envs, 6))
        self._elapsed = np.zeros(self.num_envs, int)
        self._autoreset = np.zeros(self.num_envs, bool)

    @property
    def terrain_params(self) -> np.ndarray:
        """Terrain parameters θ of each robot's current episode (num_envs, nθ), a copy."""
        return np.array(self._theta)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        q0, v0, self._theta = self.task.reset_rows(self.plant, self._rng, self.num_envs)
        self._state = self.batch.initial_state(q0, v0)
        self._prev[:] = 0.0
        self._elapsed[:] = 0
        self._autoreset[:] = False
        return self.task.observe(self.plant, self._state), {}

    def step(self, actions):
        a = np.asarray(actions, dtype=float).reshape(self.num_envs, 6)
        restart = self._autoreset.copy()
        if restart.any():
            n = int(restart.sum())
            q0, v0, theta = self.task.reset_rows(self.plant, self._rng, n)
            q_all = np.array(self._state.q)
            v_all = np.array(self._state.v)
            q_all[restart], v_all[restart] = q0, v0
            self._theta = np.array(self._theta)
            self._theta[restart] = theta
            self._state = self.batch.reset(self._state, restart, q_all, v_all)
            self._prev[restart] = 0.0
            self._elapsed[restart] = 0
        q_ref = self.task.q_ref(self._q_stand, a)
        stepped = self.batch.step(self._state, None, self.task.frame_skip, q_ref=q_ref,
                                  kp=self.task.kp, kd=self.task.kd, theta=self._theta)
        # robots being reset this call keep their fresh state (the action is ignored)
        self._state = self.batch.reset(stepped, restart, self._state.q, self._state.v) \
            if restart.any() else stepped
        s = self._state
        self._elapsed[~restart] += 1
        reward = np.nan_to_num(self.task.reward(s, a, self._prev), nan=0.0)
        terminated = self.task.terminated(s) & ~restart
        truncated = (self._elapsed >= self.max_episode_steps) & ~terminated & ~restart
        reward[restart] = 0.0
        self._prev = np.where(restart[:, None], 0.0, a)
        self._autoreset = terminated | truncated
        obs = np.nan_to_num(self.task.observe(self.plant, s), nan=0.0, posinf=0.0, neginf=0.0)
        info = {"forward_speed": self.task.forward_speed(s)}
        return obs, reward, terminated, truncated, info


__all__ = ["BipedSandVectorEnv"]
