"""Which plant steps a run or a replay: the compiled one where it models everything asked
for, else the reference :class:`~.plant.Plant`, with the reason.

    plant, choice = select_plant(Plant(biped, terrain, sim), "compiled")
    choice.resolved          # "compiled" or "reference"
    choice.note              # one line: why the reference plant steps (empty otherwise)

``requested`` is ``"compiled"`` (the default: :class:`~.fast_plant.FastPlant` on
:class:`~.compiled.CompiledPlant`, the same physics ≈ 18× faster, checked against the
reference in ``tests/test_compiled.py``, ``test_fast_plant.py``, ``test_fast_path.py``) or
``"reference"`` (Pinocchio + Python). The environment variable ``GRANULAR_MPC_PLANT``
changes the default of every run and replay that does not choose (``sim.plant`` of a
scenario chooses for its run). The compiled plant does not model (falls back, named):
a ``track`` terrain (one contact law per segment), ``sim.actuators`` (joint friction,
motor envelope, rotor inertia) and joint effects that cannot be traced with CasADi.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from ..codegen import compiler
from ..exceptions import ConfigError
from .compiled import CompiledPlant
from .fast_plant import FastPlant
from .plant import Plant

#: the plants a run or a replay can step
PLANT_CHOICES = ("compiled", "reference")
#: environment variable overriding the default choice
PLANT_ENV = "GRANULAR_MPC_PLANT"


def default_plant_choice() -> str:
    """``$GRANULAR_MPC_PLANT`` if set (``compiled`` or ``reference``), else ``compiled``.

    Raises:
        ConfigError: the variable holds another value.
    """
    value = os.environ.get(PLANT_ENV, "compiled").strip() or "compiled"
    if value not in PLANT_CHOICES:
        raise ConfigError(f"{PLANT_ENV}={value!r} is not a plant", key=PLANT_ENV,
                          value=value, allowed=", ".join(PLANT_CHOICES))
    return value


@dataclass(frozen=True)
class PlantChoice:
    """The plant asked for and the one that steps.

    Attributes:
        requested: ``compiled`` or ``reference``.
        resolved: the plant that steps.
        reason: why ``resolved`` differs from ``requested`` (empty if it does not).
    """

    requested: str
    resolved: str
    reason: str = ""

    @property
    def note(self) -> str:
        """One line for the console: empty unless the reference plant replaces the compiled."""
        if not self.reason:
            return ""
        return f"plant: reference (compiled not used: {self.reason})"


def compiled_unsupported(plant: Plant) -> str:
    """Why the compiled plant cannot step ``plant`` (empty if it can), without building it."""
    if getattr(plant.terrain, "kind", None) == "track":
        return "the track terrain has one contact law per segment"
    if plant.actuators.active:
        return "sim.actuators (joint friction, motor envelope, rotor inertia) is not compiled"
    if compiler() is None or os.environ.get("GRANULAR_MPC_JIT", "1") == "0":
        # CasADi's interpreter would evaluate the step, several times slower than Pinocchio
        return "no C compiler found (install gcc or set CC)"
    return ""


def select_plant(plant: Plant, requested: str | None = None, **compiled_kw
                 ) -> tuple[Plant | FastPlant, PlantChoice]:
    """The plant that steps ``plant``'s model, and the record of the choice.

    Args:
        plant: the reference plant (model).
        requested: ``compiled``, ``reference`` or None (:func:`default_plant_choice`).
        **compiled_kw: passed to :class:`CompiledPlant` (``chunk``, ``per_foot_theta``,
            ``joint_params``).

    Returns:
        ``(plant to step, PlantChoice)``: a :class:`FastPlant` or ``plant`` itself.
    """
    requested = default_plant_choice() if requested is None else requested
    if requested not in PLANT_CHOICES:
        raise ConfigError(f"unknown plant {requested!r}", key="sim.plant", value=requested,
                          allowed=", ".join(PLANT_CHOICES))
    if requested == "reference":
        return plant, PlantChoice(requested, "reference")
    reason = compiled_unsupported(plant)
    if not reason:
        try:
            return FastPlant(plant, CompiledPlant(plant, **compiled_kw)), \
                PlantChoice(requested, "compiled")
        except ConfigError as exc:           # e.g. a joint effect CasADi cannot trace
            reason = str(exc)
    return plant, PlantChoice(requested, "reference", reason)


__all__ = ["PLANT_CHOICES", "PLANT_ENV", "PlantChoice", "default_plant_choice",
           "compiled_unsupported", "select_plant"]
