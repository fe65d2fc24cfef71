"""The diagnosis problem: a data set as replayable stance windows, with the robot, the
model's terrain and the scored channels (the input of every stage)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...config import SimConfig
from ...exceptions import GranularMpcError
from ...robot.model import Biped, load_biped
from ..dataformat import load_dataset
from ..prepare import StanceWindow, channel_names, stance_windows
from ..replay.model import ReplayModel, build_replay_model, model_terrain
from .joint_proposal import JointSamples

#: fewest complete stance phases a diagnosis works with
MIN_WINDOWS = 4


@dataclass(frozen=True, eq=False)
class Problem:
    """A data set ready to diagnose.

    Attributes:
        data_dir: the data set's folder.
        biped: the robot of the data set.
        terrain_cfg: the model's terrain config before calibration.
        sim: plant settings of the replays.
        sample_rate_hz: the data set's sample rate [Hz].
        replay_model: the model without candidates (its contact stiffness set the windows).
        windows: every complete stance phase.
        joint_names: actuated joints (actuator order).
        channels: scored channels (format-v1 names).
        edges: stance-phase bin edges [%].
        joint_rows: the joint-torque equation-error rows (:func:`.joint_proposal.equation_rows`;
            None when the data set does not measure the joint torques and the trunk motion,
            or has not been given them): the evidence a joint term's torque is judged on
            (:mod:`.torque_evidence`).
    """

    data_dir: Path
    biped: Biped
    terrain_cfg: Any
    sim: SimConfig | None
    sample_rate_hz: float
    replay_model: ReplayModel
    windows: tuple[StanceWindow, ...]
    joint_names: tuple[str, ...]
    channels: tuple[str, ...]
    edges: np.ndarray
    joint_rows: JointSamples | None = None

    @property
    def trials(self) -> np.ndarray:
        """Trial of each window."""
        return np.array([w.trial for w in self.windows])

    @property
    def n_trials(self) -> int:
        return int(np.unique(self.trials).size)


def load_problem(data_dir: str | Path, *, terrain: Any = "dry_sand", sim: SimConfig | None = None,
                 phase_bins: int = 10, dataset=None, segments: int = 1) -> Problem:
    """Load the data set (or use ``dataset``), cut it into stance windows and set up the
    channels and phase bins; ``segments``: replay segments per stance
    (:mod:`~granular_mpc.validation.restarts`).

    Raises:
        GranularMpcError: fewer than :data:`MIN_WINDOWS` complete stance phases.
    """
    ds = load_dataset(data_dir) if dataset is None else dataset
    biped = load_biped(ds.meta.robot, with_visuals=False)
    cfg0 = model_terrain(terrain)
    # its terrain and contact stiffness are what the stages use: no compiled plant
    rm0 = build_replay_model(biped, cfg0, sample_rate_hz=ds.meta.sample_rate_hz, sim=sim,
                             compile_plant=False)
    windows = stance_windows(ds, biped, contact_stiffness=rm0.contact_stiffness,
                             segments=segments)
    if len(windows) < MIN_WINDOWS:
        raise GranularMpcError(f"{data_dir}: {len(windows)} complete stance phases; the "
                               f"diagnosis needs at least {MIN_WINDOWS}")
    J = tuple(ds.joint_names)
    return Problem(Path(data_dir), biped, cfg0, sim, ds.meta.sample_rate_hz, rm0,
                   tuple(windows), J, tuple(channel_names(list(J))),
                   np.linspace(0.0, 100.0, phase_bins + 1))


__all__ = ["Problem", "load_problem", "MIN_WINDOWS"]
