"""Gymnasium environments on the compiled, batched plant (optional extra ``gym``).

Importing this package registers ``granular_mpc/BipedSand-v0``::

    import gymnasium as gym
    import granular_mpc.envs  # noqa: F401  (registers the environments)

    env = gym.make("granular_mpc/BipedSand-v0")                      # one robot
    envs = gym.make_vec("granular_mpc/BipedSand-v0", num_envs=64,
                        vectorization_mode="vector_entry_point")      # one batched plant

Observation, action, reward and termination: :class:`BipedSandEnv`.
"""
from __future__ import annotations

try:
    import gymnasium as gym
except ImportError as exc:  # pragma: no cover - depends on the installed extras
    raise ImportError("granular_mpc.envs needs Gymnasium: pip install 'granular_mpc[gym]'") from exc

from .biped_sand import BipedSandEnv
from .task import OBS_NAMES, WalkTask
from .vector import BipedSandVectorEnv

ENV_ID = "granular_mpc/BipedSand-v0"
#: environment steps before truncation (10 s at the default 100 Hz)
MAX_EPISODE_STEPS = 1000

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="granular_mpc.envs.biped_sand:BipedSandEnv",
                 vector_entry_point="granular_mpc.envs.vector:BipedSandVectorEnv",
                 max_episode_steps=MAX_EPISODE_STEPS)

__all__ = ["ENV_ID", "MAX_EPISODE_STEPS", "BipedSandEnv", "BipedSandVectorEnv", "OBS_NAMES",
           "WalkTask"]
