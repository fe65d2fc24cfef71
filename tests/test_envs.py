"""Gymnasium environments (granular_mpc.envs): registration, Gymnasium's checker,
determinism under a seed, documented spaces, termination and the vector env's autoreset."""
from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import granular_mpc.envs as envs  # noqa: E402


def test_registered_and_passes_the_checker():
    """Importing granular_mpc.envs registers the id; the env passes check_env."""
    assert envs.ENV_ID == "granular_mpc/BipedSand-v0" and envs.ENV_ID in gym.registry
    env = gym.make(envs.ENV_ID)
    assert env.spec.max_episode_steps == envs.MAX_EPISODE_STEPS
    assert env.observation_space.shape == (len(envs.OBS_NAMES),) == (28,)
    assert env.action_space.shape == (6,)
    check_env(env.unwrapped, skip_render_check=True)


def test_seeded_rollouts_are_reproducible_and_stand():
    """Same seed → same observations; holding the standing pose (action 0) for 0.5 s
    keeps the robot up, both feet on the sand bearing its weight, reward near maximum."""
    env = envs.BipedSandEnv()

    def rollout(seed):
        obs, _ = env.reset(seed=seed)
        total = 0.0
        for _ in range(50):
            obs, r, terminated, truncated, _ = env.step(np.zeros(6, np.float32))
            assert not terminated and not truncated
            total += r
        return obs, total

    (o1, r1), (o2, r2) = rollout(3), rollout(3)
    np.testing.assert_array_equal(o1, o2)
    assert r1 == r2
    names = list(envs.OBS_NAMES)
    assert o1[names.index("left_contact")] == 1.0 and o1[names.index("right_contact")] == 1.0
    support = o1[names.index("left_fz_over_weight")] + o1[names.index("right_fz_over_weight")]
    assert support == pytest.approx(1.0, abs=0.15)
    assert 0.35 < o1[names.index("base_z")] < 0.5
    assert r1 > 50 * 0.5                       # alive bonus every step, upright


def test_fall_terminates():
    """A robot that cannot stay above min_height is terminated (not truncated)."""
    env = envs.BipedSandEnv(min_height=0.6)
    env.reset(seed=0)
    _, _, terminated, truncated, _ = env.step(np.zeros(6, np.float32))
    assert terminated and not truncated


def test_vector_env_autoreset_and_theta_randomisation():
    """make_vec uses the batched plant; an ended episode restarts on the next step with
    reward 0; per-robot terrain parameters are drawn from theta_ranges."""
    venv = gym.make_vec(envs.ENV_ID, num_envs=3, vectorization_mode="vector_entry_point",
                        threads=2, theta_ranges={"zeta": (1.0, 1.7)}, max_episode_steps=2)
    assert isinstance(venv.unwrapped, envs.BipedSandVectorEnv)
    obs, _ = venv.reset(seed=4)
    assert obs.shape == (3, 28) and obs.dtype == np.float32
    names = list(venv.unwrapped.plant.plant.terrain.param_names)
    zeta = venv.unwrapped.terrain_params[:, names.index("zeta")]
    assert np.all((zeta >= 1.0) & (zeta <= 1.7)) and len(set(zeta.tolist())) == 3
    a = np.zeros((3, 6), np.float32)
    _, r1, te1, tr1, _ = venv.step(a)
    _, r2, te2, tr2, _ = venv.step(a)
    assert not te1.any() and not tr1.any() and tr2.all() and not te2.any()
    obs3, r3, te3, tr3, _ = venv.step(a)           # autoreset step
    np.testing.assert_array_equal(r3, 0.0)
    assert not te3.any() and not tr3.any()
    assert np.allclose(obs3[:, 0], obs[:, 0], atol=0.03)   # back at the start height
    venv.close()
