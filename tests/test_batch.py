"""The batched plant (granular_mpc.dynamics.batch): every robot of a batch equals the same
robot stepped alone by the compiled plant (itself checked against the reference in
tests/test_compiled.py), with per-robot states, commands, terrain parameters and resets."""
from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.config import SimConfig
from granular_mpc.dynamics import Plant
from granular_mpc.dynamics.batch import BatchPlant
from granular_mpc.dynamics.compiled import CompiledPlant
from granular_mpc.exceptions import ConfigError


@pytest.fixture(scope="module")
def fast(biped, sand):
    return CompiledPlant(Plant(biped, sand, SimConfig()))


def _starts(biped, rng, n):
    q0 = np.tile(biped.standing_configuration(0.005), (n, 1))
    q0[:, 2] += rng.uniform(-0.006, 0.004, n)
    return q0, rng.normal(0.0, 0.05, (n, biped.model.nv))


@pytest.mark.parametrize("parallelization", ["thread", "serial"])
def test_batch_rows_equal_single_robots(fast, biped, parallelization):
    """5 robots, different starts, torques, PD targets and terrain ζ: each row after 13
    steps equals the single compiled robot bit for bit (same compiled code)."""
    rng = np.random.default_rng(31)
    n = 5
    batch = BatchPlant(fast, n, parallelization=parallelization, threads=2)
    q0, v0 = _starts(biped, rng, n)
    tau = rng.normal(0.0, 1.0, (n, 6))
    q_ref = biped.actuated(q0[0]) + rng.normal(0.0, 0.05, (n, 6))
    theta = np.tile(fast.theta, (n, 1))
    theta[:, list(fast.plant.terrain.param_names).index("zeta")] *= rng.uniform(0.7, 1.3, n)
    s = batch.step(batch.initial_state(q0, v0), tau, 13, q_ref=q_ref, kp=150.0, kd=3.0,
                   theta=theta)
    assert s.x.shape == (n, fast.layout.nx) and not s.diverged.any()
    assert np.all(s.steps == 13) and np.allclose(s.t, 13 * fast.dt)
    for i in range(n):
        one = fast.step(fast.initial_state(q0[i], v0[i]), tau[i], 13, q_ref=q_ref[i],
                        kp=150.0, kd=3.0, theta=theta[i])
        np.testing.assert_allclose(s.x[i], one.x, rtol=1e-13, atol=1e-13)
    assert len({round(float(z), 9) for z in s.q[:, 2]}) == n     # the robots differ


def test_batch_reset_and_divergence_flags(fast, biped):
    """A robot thrown beyond the velocity bound is flagged (others go on); reset restarts it."""
    rng = np.random.default_rng(32)
    batch = BatchPlant(fast, 3, threads=2)
    q0, v0 = _starts(biped, rng, 3)
    v0[1, 0] = 2.0 * fast.plant.sim.max_speed
    s = batch.step(batch.initial_state(q0, v0), n_steps=4, q_ref=biped.actuated(q0[0]),
                   kp=150.0, kd=3.0)
    assert s.diverged.tolist() == [False, True, False]
    s = batch.reset(s, s.diverged, q0, np.zeros_like(v0))
    assert not s.diverged.any() and s.steps.tolist() == [4, 0, 4]
    np.testing.assert_allclose(s.q[1], q0[1])


def test_batch_rejects_bad_arguments(fast):
    with pytest.raises(ConfigError):
        BatchPlant(fast, 0)
    with pytest.raises(ConfigError, match="parallelization"):
        BatchPlant(fast, 2, parallelization="gpu")
    with pytest.raises(ConfigError, match="q0"):
        BatchPlant(fast, 2).initial_state(np.zeros(5))
