"""Tracing a terrain force symbolically (granular_mpc.effects.tracing): one clear error
naming the effect, its file and ``o.if_else`` for Python control flow on the patch state,
one short warning for NumPy calls, NaN from ``math`` refused."""
from __future__ import annotations

import functools
import math
import warnings

import casadi as ca
import numpy as np
import pytest

from granular_mpc.cli import BAD_INPUT_ERRORS
from granular_mpc.effects import EffectInfo, PatchState, Param
from granular_mpc.effects.tracing import SYMBOLIC_ADVICE, effect_source, trace_terrain_force
from granular_mpc.exceptions import ConfigError, EffectError
from granular_mpc.terrain.closed_form import casadi_ops


def _symbolic_state() -> PatchState:
    x = ca.SX.sym("x", 12)
    v = tuple(x[i] for i in range(12))
    return PatchState(depth=v[0], in_contact=v[1], p_c=v[2:5], v_c=v[5:8], a_c=(0.0,) * 3,
                      intrusion=(0.0,) * 3, heading=(1.0, 0.0, 0.0), lateral=(0.0, 1.0, 0.0),
                      f_terrain=(v[8], v[9], v[10]), f_yield_z=0.0, area_h=0.0, width=0.02,
                      density=1500.0, dt=5e-4, foot=v[11], depth_rate=-v[7])


def _info(name, fn) -> EffectInfo:
    return EffectInfo(name=name, kind="terrain_force",
                      params={"a": Param(0.3, 0.0, 1.0, "-", "gain")}, fn=fn)


def if_foot(o, s, p):
    if s.foot < 0.5:
        return (-p["a"] * s.f_terrain[0], 0.0, 0.0)
    return (0.0, 0.0, 0.0)


def min_depth(o, s, p):
    return (0.0, 0.0, p["a"] * min(s.depth, 0.01))


def numpy_force(o, s, p):
    r = np.maximum(s.depth_rate, 0.0)
    return (0.0, 0.0, p["a"] * r * r * s.in_contact)


def math_force(o, s, p):
    return (0.0, 0.0, p["a"] * math.sqrt(s.depth))


def good_force(o, s, p):
    return (0.0, 0.0, p["a"] * o.if_else(s.foot > 0.5, s.depth, 0.0) * s.in_contact)


@pytest.mark.parametrize("fn", [if_foot, min_depth])
def test_python_control_flow_is_one_clear_bad_input_error(fn):
    with pytest.raises(EffectError) as err:
        trace_terrain_force(_info("user_term", fn), casadi_ops(), _symbolic_state(), {"a": 0.3})
    exc = err.value
    text = str(exc)
    assert exc.effect == "user_term" and "'user_term'" in text
    assert exc.source == __file__ and text.startswith(__file__)
    assert "o.if_else(cond, a, b)" in text and SYMBOLIC_ADVICE in text
    assert isinstance(exc, ConfigError) and isinstance(exc, BAD_INPUT_ERRORS)


def test_numpy_call_is_one_short_warning_naming_the_effect():
    info = _info("numpy_term_once", numpy_force)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(3):
            f = trace_terrain_force(info, casadi_ops(), _symbolic_state(), {"a": 0.3})
    assert isinstance(f[2], ca.SX) and "fmax" in str(f[2])
    assert not [w for w in caught if issubclass(w.category, FutureWarning)]
    mine = [str(w.message) for w in caught if "numpy_term_once" in str(w.message)]
    assert len(mine) == 1 and "o.fmax" in mine[0] and __file__ in mine[0]


def test_math_on_a_symbol_is_refused_instead_of_a_nan_force():
    with pytest.raises(EffectError, match="NaN"):
        trace_terrain_force(_info("math_term", math_force), casadi_ops(), _symbolic_state(),
                            {"a": 0.3})


def test_a_symbolic_force_traces_unchanged_without_warning():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        f = trace_terrain_force(_info("good_term", good_force), casadi_ops(),
                                _symbolic_state(), {"a": 0.3})
    assert not caught
    assert f[0] == 0.0 and f[1] == 0.0
    assert isinstance(f[2], ca.SX) and "?" in str(f[2])      # CasADi prints if_else as c?a:b


def test_effect_source_follows_wrappers_to_the_user_file():
    @functools.wraps(if_foot)
    def wrapper(o, s, p):
        return if_foot(o, s, p)

    assert effect_source(wrapper) == __file__
    assert effect_source(len) == ""
