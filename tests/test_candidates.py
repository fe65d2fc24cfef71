"""The candidate set's bookkeeping (``diagnosis.candidates``): a candidate dropped after its
sensitivities were computed must not take regression rows from the others."""

import numpy as np

from granular_mpc.validation.diagnosis.candidates import build_candidates, kept_sensitivities
from granular_mpc.validation.diagnosis.design import Design
from granular_mpc.validation.diagnosis.regression import Rows


def _cube(nan_share: float = 0.0, seed: int = 0) -> np.ndarray:
    """A (W=8, C=3, B=5) sensitivity cube with ``nan_share`` of its cells undefined."""
    rng = np.random.default_rng(seed)
    S = rng.normal(size=(8, 3, 5))
    S.ravel()[: int(nan_share * S.size)] = np.nan
    return S


def test_dropped_candidates_columns_leave_the_sensitivities():
    computed = build_candidates(["cohesion", "joint_friction", "inertial_drag"])
    kept = computed.without(["cohesion"])
    sens = {k: _cube() for keys in computed.keys.values() for k in keys}
    sens["calibration.zeta"] = _cube()                  # nuisance: no candidate's
    out = kept_sensitivities(sens, computed, kept)
    gone = set(computed.keys["cohesion"])
    assert gone and not gone & set(out)
    expected = {k for n in ("joint_friction", "inertial_drag") for k in computed.keys[n]}
    assert set(out) == expected | {"calibration.zeta"}
    assert all(out[k] is sens[k] for k in out)          # the cubes themselves unchanged
    assert gone <= set(sens)                            # the input mapping is not mutated
    # nothing dropped: every cube kept
    assert set(kept_sensitivities(sens, computed, computed)) == set(sens)


def test_a_dropped_candidates_undefined_rows_no_longer_cut_the_design():
    """The mechanism of the jf+encoder-offset pair (``docs/validation.md`` §5.3): a
    diverged candidate's NaN cells removed every other candidate's rows."""
    computed = build_candidates(["cohesion", "joint_friction"])
    kept = computed.without(["cohesion"])
    sens = {k: _cube() for k in computed.keys["joint_friction"]}
    sens |= {k: _cube(nan_share=0.75, seed=1) for k in computed.keys["cohesion"]}

    def n_rows(s) -> int:
        X = {k: v.ravel() for k, v in s.items()}
        n = 8 * 3 * 5
        d = Design(np.ones(n), X, np.zeros(n), np.zeros(n, int), np.full(n, "c"),
                   np.zeros(n, int), {"c": 1.0}, 1.0)
        return int(Rows.of(d).ok.sum())

    assert n_rows(sens) == 30                           # 25 % of 120 rows left
    assert n_rows(kept_sensitivities(sens, computed, kept)) == 120
