"""Effect parameters (granular_mpc.effects.params): defaults, overrides, unknown names with a
did-you-mean, out-of-range values with the allowed interval and unit."""
from __future__ import annotations

import pytest

from granular_mpc.effects import Param, resolve_params
from granular_mpc.exceptions import ConfigError

SPECS = {"suction": Param(3000.0, 0.0, 50000.0, "Pa", "suction"),
         "release": Param(0.003, 0.0005, 0.05, "m", "release")}


def test_defaults_overridden_by_given_values_in_spec_order():
    assert resolve_params("wet", SPECS, None) == {"suction": 3000.0, "release": 0.003}
    out = resolve_params("wet", SPECS, {"release": 0.01})
    assert out == {"suction": 3000.0, "release": 0.01} and list(out) == ["suction", "release"]
    assert isinstance(resolve_params("wet", SPECS, {"suction": 5})["suction"], float)


def test_unknown_parameter_gets_a_did_you_mean():
    with pytest.raises(ConfigError, match="has no parameter 'sucktion'; did you mean 'suction'") as err:
        resolve_params("wet", SPECS, {"sucktion": 1.0})
    assert err.value.key == "effects.wet.sucktion"
    assert err.value.allowed == "suction, release"


def test_out_of_range_names_key_value_and_interval_with_unit():
    with pytest.raises(ConfigError, match="out of range") as err:
        SPECS["suction"].check("wet", "suction", -5.0)
    assert err.value.key == "effects.wet.suction"
    assert err.value.value == -5.0
    assert err.value.allowed == "[0.0, 50000.0] Pa"
    assert SPECS["release"].check("wet", "release", 0.05) == 0.05        # bounds included
