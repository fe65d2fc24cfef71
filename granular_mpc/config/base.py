"""The base of every config object, and the constrained number types the schema uses."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field


class StrictModel(BaseModel):
    """Frozen config object; unknown keys are errors."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True,
                              arbitrary_types_allowed=False)


PositiveFloat = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
"""A finite number > 0."""
NonNegFloat = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
"""A finite number ≥ 0."""
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
"""A finite number (no NaN, no ±inf)."""

__all__ = ["StrictModel", "PositiveFloat", "NonNegFloat", "FiniteFloat"]
