"""One exception hierarchy for the whole package.

Every error raised on purpose by ``granular_mpc`` derives from :class:`GranularMpcError`.
Leaves carry the data needed to debug them (the offending key, file, row, time, state),
so callers can inspect them rather than parse messages.

    GranularMpcError
    ├── ConfigError            bad YAML, unknown key, wrong type, value out of range
    │   └── ModelFileError     a robot / terrain / scenario file is missing or unreadable
    ├── ModelError             a model cannot be built (robot description, geometry)
    ├── SimulationError
    │   └── PlantDivergedError non-finite or exploding plant state
    ├── SolverError            a QP could not be set up (bad dimensions, non-finite data)
    ├── DataFormatError        a measurement data set breaks format v1 (all problems listed)
    ├── OutputError            an output folder cannot be written
    └── ViewerError            the Meshcat viewer or its server cannot be used
"""

from __future__ import annotations

import signal
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np


class GranularMpcError(Exception):
    """Root of every error raised on purpose by granular_mpc."""


class ConfigError(GranularMpcError, ValueError):
    """A configuration value is missing, unknown, of the wrong type or out of range.

    Attributes:
        key: dotted path of the offending key (``terrain.zeta``), or ``""``.
        value: the offending value, if any.
        allowed: what would have been accepted.
        source: the file the value came from, if known.
    """

    def __init__(self, message: str, *, key: str = "", value: Any = None,
                 allowed: str = "", source: str = "") -> None:
        self.key = key
        self.value = value
        self.allowed = allowed
        self.source = source
        parts = []
        if source:
            parts.append(f"{source}: ")
        if key:
            parts.append(f"{key}: ")
        parts.append(message)
        if allowed:
            parts.append(f" (allowed: {allowed})")
        super().__init__("".join(parts))


class ModelFileError(ConfigError, FileNotFoundError):
    """A robot, terrain or scenario file named in a configuration cannot be found or read."""


class ModelError(GranularMpcError):
    """A physical model cannot be built from its description."""


class SimulationError(GranularMpcError):
    """The closed loop or the plant cannot continue."""


class PlantDivergedError(SimulationError, FloatingPointError):
    """The plant state became non-finite or exploded.

    Attributes:
        time: simulation time [s] at which divergence was detected.
        q: configuration at that time (may contain NaN).
        v: generalised velocity at that time.
        q_names, v_names: the coordinates' names (``base_x`` …, ``q_<joint>``; ``base_vx_B`` …
            in the trunk frame B, ``dq_<joint>``), empty when unknown.
        reason: short machine-readable reason (``"non-finite"``, ``"velocity-bound"``).
    """

    def __init__(self, time: float, q: Sequence[float], v: Sequence[float], reason: str, *,
                 q_names: Sequence[str] = (), v_names: Sequence[str] = ()) -> None:
        self.time = float(time)
        self.q = np.array(q, dtype=float)
        self.v = np.array(v, dtype=float)
        self.reason = reason
        self.q_names = tuple(q_names)
        self.v_names = tuple(v_names)
        super().__init__(
            f"plant diverged at t = {self.time:.4f} s ({reason}); "
            f"q = {_labelled(self.q, self.q_names)}, v = {_labelled(self.v, self.v_names)}. "
            "Reduce sim.dt or check the terrain stiffness / controller gains.")


def _labelled(values: np.ndarray, names: Sequence[str]) -> str:
    """``[name=value, …]`` when every entry has a name, else the plain vector."""
    if len(names) != len(values):
        with np.printoptions(precision=4, suppress=True, linewidth=160):
            return str(values)
    return "[" + ", ".join(f"{n}={x:.4g}" for n, x in zip(names, values)) + "]"


class SolverError(GranularMpcError):
    """A QP could not be set up or solved for a reason other than infeasibility."""


@dataclass
class DataProblem:
    """One problem found in a measurement data set."""

    file: str
    message: str
    column: str = ""
    row: int | None = None

    def __str__(self) -> str:
        where = self.file
        if self.column:
            where += f", column '{self.column}'"
        if self.row is not None:
            where += f", row {self.row}"
        return f"{where}: {self.message}"


class DataFormatError(GranularMpcError, ValueError):
    """A measurement data set does not follow data format v1.

    All problems are collected and reported at once in :attr:`problems`.
    """

    def __init__(self, problems: Sequence[DataProblem], root: str = "") -> None:
        self.problems = list(problems)
        self.root = root
        head = f"{len(self.problems)} problem(s) in data set {root}".rstrip()
        body = "\n".join(f"  - {p}" for p in self.problems[:200])
        more = "" if len(self.problems) <= 200 else f"\n  … and {len(self.problems) - 200} more"
        super().__init__(f"{head}:\n{body}{more}")


class OutputError(GranularMpcError, OSError):
    """An output folder or file cannot be written."""


class ViewerError(GranularMpcError, RuntimeError):
    """The Meshcat server could not be started or stopped answering.

    Attributes:
        detail: what failed (server output, timeout …).
    """

    def __init__(self, message: str, *, detail: str = "") -> None:
        self.detail = detail
        super().__init__(message + (f": {detail}" if detail else ""))


__all__ = [
    "GranularMpcError", "ConfigError", "ModelFileError", "ModelError", "SimulationError",
    "PlantDivergedError", "SolverError", "DataProblem", "DataFormatError", "OutputError",
    "ViewerError",
]


class Interrupted(KeyboardInterrupt):
    """SIGINT (Ctrl-C) or SIGTERM stopped a command. Not an error: the command line exits
    with ``128 + signum`` (130 for SIGINT, 143 for SIGTERM).

    A :class:`KeyboardInterrupt`, so code that handles Ctrl-C handles SIGTERM alike.

    Attributes:
        signum: the signal number.
        signame: its name (``"SIGINT"``, ``"SIGTERM"``).
    """

    def __init__(self, signum: int = 2, detail: str = "") -> None:
        self.signum = int(signum)
        try:
            self.signame = signal.Signals(self.signum).name
        except ValueError:
            self.signame = f"signal {self.signum}"
        super().__init__(f"interrupted by {self.signame}" + (f" {detail}" if detail else ""))

    @property
    def exit_code(self) -> int:
        """``128 + signum``: 130 for SIGINT, 143 for SIGTERM."""
        return 128 + self.signum


__all__ += ["Interrupted"]


class EffectError(ConfigError):
    """An effect's function cannot be used as written: a terrain force with Python control
    flow (``if``/``and``/``min`` …) on its symbolic patch state, or one that traces to NaN.

    A :class:`ConfigError` (the effect file is the user's input: the command line exits 2).

    Attributes:
        effect: the effect's registered name.
        source: the file defining the effect's function, if known.
    """

    def __init__(self, message: str, *, effect: str, source: str = "") -> None:
        self.effect = effect
        super().__init__(message, key="effects", value=effect, source=source)


__all__ += ["EffectError"]
