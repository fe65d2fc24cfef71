"""Effect specs: one optional physical effect by registered name, with parameter values.

The effects themselves (what a name means) live in :mod:`granular_mpc.terrain.effects`
and :mod:`granular_mpc.terrain.effects_library`; a spec only names one.
"""

from __future__ import annotations

from typing import Any

from pydantic import Field, model_validator

from ..exceptions import ConfigError
from .base import StrictModel


class EffectSpec(StrictModel):
    """One optional physical effect, by registered name, with parameter values.

    Accepts the compact string form ``"name:param=value,param=value"`` too.
    """

    name: str
    params: dict[str, float] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _from_string(cls, value: Any) -> Any:
        if isinstance(value, str):
            return parse_effect_string(value)
        return value


def parse_effect_string(text: str) -> dict[str, Any]:
    """``"inertial_drag:c_d=1.2"`` → ``{"name": "inertial_drag", "params": {"c_d": 1.2}}``.

    Raises:
        ConfigError: a parameter is not ``name=value`` or its value is not a number.
    """
    name, _, rest = text.partition(":")
    params: dict[str, float] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, val = item.partition("=")
        if not eq:
            raise ConfigError(f"effect parameter {item!r} must look like name=value",
                              key="effect", value=text)
        try:
            params[key.strip()] = float(val)
        except ValueError:
            raise ConfigError(f"effect parameter {key.strip()!r} must be a number, got {val!r}",
                              key="effect", value=text) from None
    return {"name": name.strip(), "params": params}


__all__ = ["EffectSpec", "parse_effect_string"]
