"""Compiled-function cache (granular_mpc.dynamics.codegen): same results as CasADi's VM,
one library per source, reused without rebuilding, and the no-compiler paths."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from granular_mpc.codegen import cache_dir, compile_functions, compiler
from granular_mpc.exceptions import ModelError


def _function(name="cg_probe", k=3.0):
    x = ca.SX.sym("x", 2)
    return ca.Function(name, [x], [ca.vertcat(ca.sin(x[0]) * k, ca.atan2(x[1], x[0]))])


@pytest.mark.skipif(compiler() is None, reason="no C compiler")
def test_compiled_equals_vm_and_is_cached(tmp_path, monkeypatch):
    """The library lands in $GRANULAR_MPC_CACHE, gives the VM's values, and a second build
    of the same function reuses the file; another function gets another library."""
    monkeypatch.setenv("GRANULAR_MPC_CACHE", str(tmp_path))
    assert cache_dir() == tmp_path
    f = _function()
    out = compile_functions("probe", [f])["cg_probe"]
    libs = sorted(tmp_path.glob("probe_*.so"))
    assert len(libs) == 1
    x = np.array([0.3, -1.2])
    np.testing.assert_allclose(np.array(out(x)).ravel(), np.array(f(x)).ravel(), rtol=1e-15)
    stamp = libs[0].stat().st_mtime_ns
    compile_functions("probe", [_function()])
    assert libs[0].stat().st_mtime_ns == stamp
    compile_functions("probe", [_function(k=4.0)])
    assert len(list(tmp_path.glob("probe_*.so"))) == 2


def test_without_compiler(monkeypatch, tmp_path):
    """No compiler: ModelError, or with fallback=True the functions themselves (VM)."""
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    assert compiler() is None
    with pytest.raises(ModelError, match="compiler"):
        compile_functions("probe", [_function()])
    f = _function()
    assert compile_functions("probe", [f], fallback=True)["cg_probe"] is f
