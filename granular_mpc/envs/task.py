"""The walking task shared by the single and the vector environment (row-wise NumPy).

:class:`WalkTask` turns batched plant states (:class:`~granular_mpc.dynamics.batch.BatchState`)
into observations, rewards and termination flags, and makes reset states; the definitions
are documented on :class:`~granular_mpc.envs.biped_sand.BipedSandEnv`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..config import DropConfig, SimConfig, load_robot, load_terrain
from ..dynamics.batch import BatchState
from ..dynamics.compiled import CompiledPlant
from ..dynamics.plant import Plant
from ..exceptions import ConfigError
from ..robot import Biped
from ..rotations import quat_mul_rows_wxyz, rpy_rows_from_quat_wxyz, wxyz_from_xyzw
from ..terrain import build_terrain

#: observation entries, in order (units in BipedSandEnv's docstring)
OBS_NAMES = (("base_z",) + tuple(f"base_q{c}" for c in "xyzw")
             + tuple(f"base_v{c}_B" for c in "xyz") + tuple(f"base_w{c}_B" for c in "xyz")
             + tuple(f"q_{i}" for i in range(6)) + tuple(f"dq_{i}" for i in range(6))
             + ("left_contact", "right_contact", "left_fz_over_weight", "right_fz_over_weight",
                "target_speed"))


@dataclass(frozen=True)
class WalkTask:
    """Task constants: control, reward weights, termination bounds, reset noise (SI units).

    Attributes:
        robot, terrain: robot and terrain names (``models/``).
        frame_skip: plant steps per environment step (dt = 0.5 ms → 10 ms at 20).
        target_speed: commanded forward speed [m/s] (world x).
        action_scale: joint-target offset per unit action [rad].
        kp, kd: joint PD gains [N·m/rad, N·m·s/rad] of the PD law run at the plant rate.
        min_height: trunk height below which the robot has fallen [m].
        max_tilt: roll or pitch beyond which it has fallen [rad].
        reset_noise: joint-angle / velocity noise at reset [rad, rad/s, m/s].
        theta_ranges: optional terrain-parameter randomisation per episode,
            ``{param name: (low, high)}`` (``terrain.param_names``).
        w_speed, w_alive, w_action_rate, w_tilt: reward weights.
    """

    robot: str = "yobogo10s"
    terrain: str = "dry_sand"
    frame_skip: int = 20
    target_speed: float = 0.2
    action_scale: float = 0.3
    kp: float = field(default_factory=lambda: DropConfig().kp)
    kd: float = field(default_factory=lambda: DropConfig().kd)
    min_height: float = 0.25
    max_tilt: float = 0.8
    reset_noise: float = 0.02
    theta_ranges: tuple = ()
    w_speed: float = 1.0
    w_alive: float = 0.5
    w_action_rate: float = 0.01
    w_tilt: float = 0.5

    def build(self) -> CompiledPlant:
        """The compiled plant of this task's robot and terrain (compiled once, cached)."""
        if self.frame_skip < 1:
            raise ConfigError("frame_skip must be ≥ 1", key="frame_skip", value=self.frame_skip)
        robot = load_robot(self.robot)
        biped = Biped.from_config(robot, with_visuals=False)
        terrain = build_terrain(load_terrain(self.terrain), robot)
        names = terrain.param_names
        for name, _ in self.theta_ranges:
            if name not in names:
                raise ConfigError(f"unknown terrain parameter {name!r}", key="theta_ranges",
                                  allowed=", ".join(names))
        return CompiledPlant(Plant(biped, terrain, SimConfig()))

    # ------------------------------------------------------------------ rows
    def reset_rows(self, plant: CompiledPlant, rng: np.random.Generator, n: int):
        """(q0 (n, nq), v0 (n, nv), θ (n, nθ)) for ``n`` fresh episodes."""
        biped = plant.plant.biped
        q_stand = biped.standing_configuration(0.005)
        q0 = np.tile(q_stand, (n, 1))
        q0[:, biped.idx_q] += rng.uniform(-self.reset_noise, self.reset_noise, (n, 6))
        v0 = rng.uniform(-self.reset_noise, self.reset_noise, (n, biped.model.nv))
        theta = np.tile(plant.theta, (n, 1))
        names = list(plant.plant.terrain.param_names)
        for name, (lo, hi) in self.theta_ranges:
            theta[:, names.index(name)] = rng.uniform(lo, hi, n)
        return q0, v0, theta

    def q_ref(self, q_stand: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Joint targets [rad] (n, 6): ``q_stand`` (actuator order) + ``action_scale`` ×
        the action clipped to [-1, 1]."""
        return q_stand + self.action_scale * np.clip(actions, -1.0, 1.0)

    @staticmethod
    def standing_joints(plant: CompiledPlant) -> np.ndarray:
        """Joint angles of the standing pose [rad] (actuator order)."""
        biped = plant.plant.biped
        return biped.actuated(biped.standing_configuration())

    def observe(self, plant: CompiledPlant, s: BatchState) -> np.ndarray:
        """Observations (n, len(OBS_NAMES)) float32 (see :data:`OBS_NAMES`)."""
        biped = plant.plant.biped
        q, v = s.q, s.v
        fz = np.column_stack([s.foot_force(0)[:, 2], s.foot_force(1)[:, 2]]) / biped.weight
        contact = np.column_stack([s.foot_in_contact(0), s.foot_in_contact(1)])
        obs = np.hstack([q[:, 2:3], q[:, 3:7], v[:, 0:6], q[:, biped.idx_q], v[:, biped.idx_v],
                         contact, fz, np.full((len(q), 1), self.target_speed)])
        return obs.astype(np.float32)

    def forward_speed(self, s: BatchState) -> np.ndarray:
        """Trunk velocity along world x [m/s] (n,): R_W_B v_B."""
        quat = wxyz_from_xyzw(s.q[:, 3:7])
        conj = quat * np.array([1.0, -1.0, -1.0, -1.0])
        v_b = np.column_stack([np.zeros(len(quat)), s.v[:, 0:3]])
        return quat_mul_rows_wxyz(quat_mul_rows_wxyz(quat, v_b), conj)[:, 1]

    def tilt(self, s: BatchState) -> np.ndarray:
        """max(|roll|, |pitch|) of the trunk [rad] (n,)."""
        rpy = rpy_rows_from_quat_wxyz(wxyz_from_xyzw(s.q[:, 3:7]))
        return np.abs(rpy[:, 0:2]).max(axis=1)

    def reward(self, s: BatchState, actions: np.ndarray, prev_actions: np.ndarray) -> np.ndarray:
        """Reward per robot (n,): see BipedSandEnv's docstring."""
        err = (self.forward_speed(s) - self.target_speed) / 0.1
        rate = np.sum((np.clip(actions, -1, 1) - np.clip(prev_actions, -1, 1)) ** 2, axis=1)
        return (self.w_speed * np.exp(-err * err) + self.w_alive
                - self.w_action_rate * rate - self.w_tilt * self.tilt(s) ** 2)

    def terminated(self, s: BatchState) -> np.ndarray:
        """Fallen (trunk low or tilted) or diverged, per robot (n,) bool."""
        bad = s.diverged | ~np.isfinite(s.x).all(axis=1)
        return bad | (np.nan_to_num(s.q[:, 2], nan=0.0) < self.min_height) \
            | (np.nan_to_num(self.tilt(s), nan=np.inf) > self.max_tilt)


__all__ = ["OBS_NAMES", "WalkTask"]
