"""``granular_mpc/BipedSand-v0``: the biped walking on dry sand, as a Gymnasium environment."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np

from ..dynamics.batch import BatchPlant
from .task import OBS_NAMES, WalkTask


class BipedSandEnv(gym.Env):
    """The YoboGo-10S-class biped on dry sand (compiled plant, terrain law of the paper).

    Each :meth:`step` holds the action for ``frame_skip`` plant steps of 0.5 ms (default 20:
    a 100 Hz policy); the plant is the compiled :class:`~granular_mpc.dynamics.compiled.
    CompiledPlant` (rigid-body dynamics, both feet's sand law with sinkage and slip, joint
    end stops), identical to the reference plant of the simulator.

    **Action** (Box(−1, 1, (6,)), float32): joint-target offsets, actuator order (left hip
    abduction, hip pitch, knee, right …). The joint PD law runs at the plant rate:
    ``τ = k_p (q_ref − q_a) − k_d q̇_a`` with ``q_ref = q_stand + action_scale · action``
    (``action_scale`` 0.3 rad, ``k_p`` 150 N·m/rad, ``k_d`` 3 N·m·s/rad).

    **Observation** (Box(−∞, ∞, (28,)), float32), :data:`~granular_mpc.envs.task.OBS_NAMES`:
    trunk height z [m]; trunk quaternion (x, y, z, w); trunk linear [m/s] and angular
    [rad/s] velocity in the trunk frame; joint angles [rad] and rates [rad/s] (actuator
    order); per foot (left, right) the contact flag (0/1) and the vertical ground force
    divided by the robot's weight; the target speed [m/s].

    **Reward** per step: ``w_speed · exp(−((v_x − v_target)/0.1)²) + w_alive
    − w_action_rate · ‖a − a_prev‖² − w_tilt · max(|roll|, |pitch|)²`` with v_x the trunk
    velocity along world x [m/s] and the weights 1.0, 0.5, 0.01, 0.5 (:class:`WalkTask`).

    **Termination**: the trunk below 0.25 m, roll or pitch beyond 0.8 rad, or the plant
    diverged. **Truncation**: after ``max_episode_steps`` (1000 = 10 s when registered).

    **Reset**: standing pose, soles 5 mm above the sand, joint angles and velocities with
    uniform noise ±0.02; optional terrain-parameter randomisation (``theta_ranges``).

    Args:
        render_mode: only None (use ``granular_mpc.viz`` on logged states to watch).
        **task: fields of :class:`~granular_mpc.envs.task.WalkTask` (``terrain="rigid"``,
            ``frame_skip``, ``target_speed``, ``theta_ranges={"zeta": (1.0, 1.7)}`` …).
    """

    metadata = {"render_modes": []}

    def __init__(self, render_mode: str | None = None, **task) -> None:
        if render_mode is not None:
            raise ValueError(f"render_mode {render_mode!r} is not supported")
        if isinstance(task.get("theta_ranges"), dict):
            task["theta_ranges"] = tuple(task["theta_ranges"].items())
        self.task = dataclasses.replace(WalkTask(), **task)
        self.plant = self.task.build()
        self.batch = BatchPlant(self.plant, 1, parallelization="serial")
        self.action_space = gym.spaces.Box(-1.0, 1.0, (6,), np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (len(OBS_NAMES),), np.float32)
        self.render_mode = None
        self._q_stand = self.task.standing_joints(self.plant)
        self._state = None
        self._theta = None
        self._prev = np.zeros((1, 6))

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        q0, v0, self._theta = self.task.reset_rows(self.plant, self.np_random, 1)
        self._state = self.batch.initial_state(q0, v0)
        self._prev = np.zeros((1, 6))
        return self.task.observe(self.plant, self._state)[0], {}

    def step(self, action):
        a = np.asarray(action, dtype=float).reshape(1, 6)
        q_ref = self.task.q_ref(self._q_stand, a)
        self._state = self.batch.step(self._state, None, self.task.frame_skip, q_ref=q_ref,
                                      kp=self.task.kp, kd=self.task.kd, theta=self._theta)
        s = self._state
        reward = float(np.nan_to_num(self.task.reward(s, a, self._prev)[0], nan=0.0))
        self._prev = a
        terminated = bool(self.task.terminated(s)[0])
        obs = np.nan_to_num(self.task.observe(self.plant, s)[0], nan=0.0, posinf=0.0,
                            neginf=0.0)
        info = {"forward_speed": float(self.task.forward_speed(s)[0]),
                "diverged": bool(s.diverged[0])}
        return obs, reward, terminated, False, info


__all__ = ["BipedSandEnv"]
