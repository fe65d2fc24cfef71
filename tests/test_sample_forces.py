"""A terrain-force effect on the sinking samples (``validation.diagnosis.sample_forces``):
the sole's submerged area against the circle, library effects at the measured state
against their laws evaluated by hand, and the one-parameter force function against the
same effect traced at fixed parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest

from granular_mpc.config import load_robot
from granular_mpc.effects import effect_info
from granular_mpc.validation.diagnosis.sample_forces import (force_function, sinking_states,
                                                             submerged_area)
from sinking import sinking_columns

RHO = 1660.0


def _foot():
    return load_robot("yobogo10s").foot


def test_submerged_area_is_the_chord_of_the_sole_arc_at_that_depth():
    foot = _foot()
    R, c, h, w = foot.radius, foot.chord, foot.height, foot.width
    d = np.array([0.0, 1e-3, 5e-3, h, 2 * h])
    area = submerged_area(d, R, c, w)
    # the circle of radius R whose lowest point is at depth d: half-chord √(R² − (R − d)²)
    expected = [min(2.0 * math.sqrt(max(R * R - (R - x) ** 2, 0.0)), c) * w for x in d]
    assert area == pytest.approx(expected, rel=1e-12, abs=1e-15)
    assert area[0] == 0.0 and area[3] == pytest.approx(c * w) and area[4] == area[3]


def test_library_effects_at_the_measured_state_match_their_laws_evaluated_by_hand():
    """inertial_drag and cohesion on the patch state the module builds, summed over the
    foot's patches, against their formulas written out here (numbers, not the tracer)."""
    foot = _foot()
    n_sl = int(foot.slices)
    c = sinking_columns()
    law_h, law_z = np.full(c["depth"].size, 20.0), np.full(c["depth"].size, 150.0)
    fx = [(effect_info("inertial_drag"), {"c_d": 4.0}),
          (effect_info("cohesion"), {"suction": 3000.0, "release": 0.003})]
    states = sinking_states(c, law_h, law_z, n_slices=n_sl, radius=foot.radius,
                            chord=foot.chord, width=foot.width, density=RHO, dt=0.002)
    out = {info.name: force_function(states, info, values)(None) for info, values in fx}
    area = submerged_area(c["depth"], foot.radius, foot.chord, foot.width / n_sl)
    speed = np.sqrt(c["v_h"] ** 2 + c["v_l"] ** 2 + c["v_z"] ** 2 + 1e-12)
    k = -0.5 * 4.0 * RHO * area * speed * n_sl
    assert out["inertial_drag"]["h"] == pytest.approx(k * c["v_h"], rel=1e-9)
    assert out["inertial_drag"]["z"] == pytest.approx(k * c["v_z"], rel=1e-9)
    pull = -3000.0 * area * (1.0 - np.exp(-c["rise"] / 0.003)) * n_sl
    assert out["cohesion"]["z"] == pytest.approx(pull, rel=1e-9, abs=1e-12)
    assert np.all(out["cohesion"]["h"] == 0.0)
    assert np.all(pull[c["rise"] == 0.0] == 0.0) and np.any(pull < 0.0)


def test_the_force_function_of_one_parameter_is_the_effect_at_that_value():
    """force_function(…, free="c_d")(v) — c_d a CasADi input — equals the effect traced
    at c_d = v as a number, for every v (inertial drag is linear in c_d: twice the
    coefficient, twice the force)."""
    foot = _foot()
    n_sl = int(foot.slices)
    c = sinking_columns(30, seed=5)
    law_h, law_z = np.full(30, 15.0), np.full(30, 120.0)
    info = effect_info("inertial_drag")
    states = sinking_states(c, law_h, law_z, n_slices=n_sl, radius=foot.radius,
                            chord=foot.chord, width=foot.width, density=RHO, dt=0.002)
    fn = force_function(states, info, {"c_d": 1.0}, free="c_d")
    for v in (0.5, 2.0, 7.0):
        ref = force_function(states, info, {"c_d": v})(None)
        got = fn(v)
        assert got["z"] == pytest.approx(ref["z"], rel=1e-12)
        assert got["h"] == pytest.approx(ref["h"], rel=1e-12)
    assert fn(4.0)["z"] == pytest.approx(2.0 * fn(2.0)["z"], rel=1e-12)
    assert np.all(fn(2.0)["z"] > 0.0)             # the drag opposes the sinking (v_z < 0)
