"""The controller's ground model (:mod:`granular_mpc.control.contact_model`): the scalar
interpolation of the tick (:func:`interp_scalar`) is ``np.interp``'s numbers, the batched
capacity look-up (:meth:`GroundModel.capacities`) is the scalar one element by element, and
the sinkage Z(F) inverts the capacity, on sand and on rigid ground."""

import math

import numpy as np
import pytest

from granular_mpc.config import MPCConfig
from granular_mpc.control.contact_model import ground_model, interp_scalar


def test_interp_scalar_is_numpys_interp_bit_for_bit():
    rng = np.random.default_rng(7)
    for _ in range(20):
        xp = np.cumsum(rng.uniform(1e-3, 1.0, 50))
        fp = rng.normal(0.0, 10.0, 50)
        xs = np.concatenate([rng.uniform(xp[0] - 1.0, xp[-1] + 1.0, 200), xp,
                             [xp[0], xp[-1], -np.inf, np.inf]])
        lx, lf = xp.tolist(), fp.tolist()
        for x in xs.tolist():
            assert interp_scalar(x, lx, lf) == float(np.interp(x, xp, fp)), x
    assert math.isnan(interp_scalar(float("nan"), [0.0, 1.0], [0.0, 2.0]))


@pytest.mark.parametrize("terrain_name", ["sand", "rigid"])
def test_batched_capacities_equal_the_scalar_ones_and_sinkage_inverts_them(terrain_name, sand,
                                                                          rigid):
    ground = ground_model(sand if terrain_name == "sand" else rigid, MPCConfig())
    rng = np.random.default_rng(11)
    f_max = ground.polytope.f_max
    forces = np.concatenate([rng.uniform(-50.0, 1.5 * f_max, (4, 25)).ravel(),
                             [0.0, -1.0, f_max, 2.0 * f_max]])
    z = np.array([ground.sinkage(f) for f in forces.tolist()])
    depths = np.concatenate([rng.uniform(-0.01, 0.1, 100), [0.0, -0.0, 1.0]])
    assert ground.capacities(depths).tolist() == [ground.capacity(d) for d in depths.tolist()]
    if terrain_name == "rigid":
        assert not z.any()
        return
    # Z(F) inverts the capacity between the surface's and f_max: F_cap(Z(F)) = F (up to
    # round-off); below the capacity just under the surface the foot does not sink
    surface_cap = ground.capacity(1e-9)
    inside = forces[(forces > surface_cap) & (forces < 0.99 * f_max)]
    assert inside.size > 20
    for f in inside.tolist():
        assert ground.capacity(ground.sinkage(f)) == pytest.approx(f, rel=1e-9)
    assert (z[forces <= 0.0] == 0.0).all() and (z[forces > surface_cap] > 0.0).all()
