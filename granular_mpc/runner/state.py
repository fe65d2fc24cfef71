"""The changing state of one closed-loop run (:class:`LoopState`) and its fall event.

The immutable model of a run is :class:`granular_mpc.runner.build.Simulation`; everything
that changes while it runs lives here (model/data split, as in ``dynamics/plant.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class FallEvent:
    """When and why the closed loop counted as fallen.

    Attributes:
        time: simulated time of the fall [s].
        reason: which threshold was crossed, with the value (``|roll| 47.0 deg > 45 deg``).
    """

    time: float
    reason: str


@dataclass
class LoopState:
    """Changing state of one closed-loop run.

    Attributes:
        plant: plant data (time, q, v, contact state).
        controller: controller data (``None`` in drop mode).
        step: plant steps taken.
        fall: the first fall, if any.
        stop_reason: set (e.g. by a signal handler) to end the loop after the current plant
            call (at most one controller period later).
        end_reason: why the loop ended (``duration reached``, ``fell: …``, the stop reason).
        pushes_applied: push windows that have started.
        rng: the run's random generator (seeded with ``sim.seed``): anything random in a
            run draws from it, so a seed reproduces the run.
    """

    plant: Any
    controller: Any
    rng: np.random.Generator
    step: int = 0
    fall: FallEvent | None = None
    stop_reason: str | None = None
    end_reason: str = ""
    pushes_applied: list = field(default_factory=list)

    def request_stop(self, reason: str) -> None:
        """End the loop at the next plant step with ``end_reason = reason`` (first call wins)."""
        if self.stop_reason is None:
            self.stop_reason = reason


__all__ = ["FallEvent", "LoopState"]
