"""The closed loop (granular_mpc/runner/loop.py): the plant steps between events (controller
ticks, log rows, push edges, the end) are taken in one ``step_n`` call of the compiled
plant; the rows are the same, bit for bit, as the loop stepping one plant step per
iteration (the plant seen through a wrapper without ``step_n``). Pushes start and end
between controller ticks (odd times) and the log rate (400 Hz: a row every 5 plant steps)
is not a multiple of the WBC's (500 Hz: every 4), so every kind of event falls inside a
would-be chunk."""
from __future__ import annotations

import dataclasses
import math

import pytest

from granular_mpc.runner import build_simulation, closed_loop
from granular_mpc.scenario import load_scenario

OVERRIDES = ["sim.duration=1.2", "output.log_rate_hz=400",
             "pushes=[{time: 0.7013, force: [0, 40, 0], duration: 0.0517}, "
             "{time: 0.95, force: [15, 0, 0], duration: 0.1}]"]


class _OneStepPlant:
    """The plant without ``step_n``: the loop steps it one step per iteration."""

    def __init__(self, plant) -> None:
        self._plant = plant

    def __getattr__(self, name):
        if name == "step_n":
            raise AttributeError(name)
        return getattr(self._plant, name)


def _rows(sim):
    return list(closed_loop(sim, sim.new_state()))


@pytest.fixture(scope="module")
def sim():
    s = build_simulation(load_scenario("sand_walk", OVERRIDES))
    assert hasattr(s.plant, "step_n")            # the compiled plant
    return s


def test_chunked_steps_give_the_same_rows(sim):
    chunked = _rows(sim)
    single = _rows(dataclasses.replace(sim, plant=_OneStepPlant(sim.plant)))
    assert len(chunked) == len(single) == 1.2 * 400 + 1
    pushed = 0
    for a, b in zip(chunked, single):
        assert list(a) == list(b)
        for k in a:
            if k.endswith("_ms"):                  # wall-clock solve times
                continue
            assert a[k] == b[k] or (isinstance(a[k], float) and math.isnan(a[k])
                                    and math.isnan(b[k])), (a["time"], k)
        pushed += a["push_fy"] != 0.0 or a["push_fx"] != 0.0
    # both pushes were applied, over their durations (± one row)
    assert abs(pushed - round((0.0517 + 0.1) * 400)) <= 2
