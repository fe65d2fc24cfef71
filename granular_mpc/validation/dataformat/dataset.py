"""The loaded data set (:class:`Dataset`) and its stance phases (:func:`stance_phases`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Iterable, Literal, Mapping, NamedTuple

import numpy as np
import pandas as pd

from ...columns import STANCE, STANCE_LABELS, JointKind, joint_columns
from ...exceptions import DataFormatError, DataProblem
from .channels import ChannelGroup, ChannelSet
from .checks_columns import stance_problems
from .meta import DatasetMeta
from .stance_derive import StanceDerivation, StanceSource
from .write import write_dataset


class StancePhase(NamedTuple):
    """One maximal run of rows with the same ``stance`` label.

    Attributes:
        trial: trial name (``""`` when segmenting a bare DataFrame).
        row_start: positional index of the first row (0-based), ``df.iloc[row_start]``.
        row_stop: positional index one past the last row: ``df.iloc[row_start:row_stop]``.
        side: ``"left"``, ``"right"`` or ``"none"``.
        complete: False if the run touches the first or the last row of the trial, i.e.
            the recording may have cut it (its touchdown or lift-off was not observed).
    """

    trial: str
    row_start: int
    row_stop: int
    side: str
    complete: bool

    @property
    def first_row(self) -> int:
        """1-based data row number of the first row, as in the file and in error messages."""
        return self.row_start + 1

    @property
    def last_row(self) -> int:
        """1-based data row number of the last row."""
        return self.row_stop

    @property
    def n_rows(self) -> int:
        """Number of samples in the phase."""
        return self.row_stop - self.row_start


def stance_phases(df: pd.DataFrame, *, trial: str = "",
                  sides: Iterable[str] = STANCE_LABELS) -> list[StancePhase]:
    """Segment a trial into maximal runs of one stance label.

    Args:
        df: a trial with a ``stance`` column of ``left`` / ``right`` / ``none`` labels.
        trial: name stored in each phase.
        sides: labels to return (default: all three; ``("left", "right")`` for stance only).

    Returns:
        The phases in time order.

    Raises:
        DataFormatError: if ``stance`` is missing or holds another label.
    """
    wanted = set(sides)
    unknown = wanted - set(STANCE_LABELS)
    if unknown:
        raise ValueError(f"sides must be among {STANCE_LABELS}, got {sorted(unknown)}")
    where = trial or "<DataFrame>"
    if STANCE not in df.columns:
        raise DataFormatError([DataProblem(where, "required column is missing", STANCE)])
    labels = df[STANCE].astype(object).to_numpy()
    problems = stance_problems(labels, np.arange(1, len(labels) + 1), where)
    if problems:
        raise DataFormatError(problems)
    n = len(labels)
    if n == 0:
        return []
    change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    starts = np.r_[0, change]
    stops = np.r_[change, n]
    return [StancePhase(trial, int(a), int(b), str(labels[a]), bool(a > 0 and b < n))
            for a, b in zip(starts, stops) if labels[a] in wanted]


@dataclass(frozen=True, eq=False)
class Dataset:
    """A loaded, checked data set. Build with :func:`load_dataset`.

    Format columns are float64 (``stance``: strings); extra columns keep the type they
    were read with. The DataFrames are the loader's own; copy one before changing it.

    Attributes:
        path: the data set folder.
        meta: the validated ``meta.yaml``.
        trials: trial name → DataFrame, in ``meta.yaml`` order (read-only mapping).
        joint_names: actuated joints of ``meta.robot``, actuator order.
        channels: the measured channel groups (``meta.yaml`` ``channels``; all of them,
            undeclared, when the key is absent). Columns of other groups are absent.
        stance_source: ``"measured"`` (the files have ``stance``), ``"force"`` or
            ``"kinematics"`` (derived by the loader, :mod:`.stance_derive`).
        stance_derivations: trial → how its labels were derived (empty when measured).
    """

    path: Path
    meta: DatasetMeta
    trials: Mapping[str, pd.DataFrame]
    joint_names: tuple[str, ...]
    channels: ChannelSet = field(default_factory=ChannelSet.all)
    stance_source: StanceSource = "measured"
    stance_derivations: Mapping[str, StanceDerivation] = field(
        default_factory=lambda: MappingProxyType({}))

    def has(self, *groups: ChannelGroup | str) -> bool:
        """True if every one of the channel ``groups`` was measured."""
        return self.channels.has(*groups)

    def channel_report(self) -> str:
        """Measured and absent channel groups and the stance source, a few lines of text."""
        lines = [f"data set {self.path.name}: {len(self.trials)} trial(s), robot "
                 f"{self.meta.robot}, {self.meta.sample_rate_hz:g} Hz",
                 f"  measured: {self.channels}"
                 + ("" if self.channels.declared else " (no channels key: all groups)"),
                 f"  absent:   {', '.join(g.value for g in self.channels.missing) or '(none)'}",
                 f"  stance:   {self.stance_source}"]
        for name, d in self.stance_derivations.items():
            lines.append(f"    {name}: {d}")
        return "\n".join(lines)

    @property
    def trial_names(self) -> tuple[str, ...]:
        """Trial names in ``meta.yaml`` order."""
        return tuple(self.trials)

    def commanded_speed(self, trial: str) -> float:
        """Commanded walking speed of one trial [m/s]."""
        return self.meta.trials[trial].commanded_speed_mps

    def joint_columns(self, kind: JointKind = "q") -> list[str]:
        """``q_*`` / ``dq_*`` / ``tau_*`` column names in actuator order."""
        return joint_columns(self.joint_names, kind)

    def stance_phases(self, sides: Iterable[str] = STANCE_LABELS) -> list[StancePhase]:
        """:func:`stance_phases` of every trial, trials in ``meta.yaml`` order."""
        sides = tuple(sides)
        out: list[StancePhase] = []
        for name, df in self.trials.items():
            out += stance_phases(df, trial=name, sides=sides)
        return out

    def to_frame(self) -> pd.DataFrame:
        """All trials stacked in one new DataFrame (e.g. for trial-grouped cross-validation).

        Columns ``trial``, ``row`` (1-based data row in its file) and
        ``commanded_speed_mps`` come first, then the trial columns; columns absent from
        some trials are NaN there.

        Raises:
            ValueError: if a trial already has a column named ``trial``, ``row`` or
                ``commanded_speed_mps``.
        """
        frames = []
        for name, df in self.trials.items():
            clash = {"trial", "row", "commanded_speed_mps"} & set(df.columns)
            if clash:
                raise ValueError(f"trial {name!r} already has column(s) {sorted(clash)}")
            head = pd.DataFrame({"trial": name, "row": np.arange(1, len(df) + 1),
                                 "commanded_speed_mps": self.commanded_speed(name)},
                                index=df.index)
            frames.append(pd.concat([head, df], axis=1))
        return pd.concat(frames, ignore_index=True)

    def write(self, path: str | Path, format: Literal["csv", "parquet"] = "csv", *,
              overwrite: bool = False) -> Path:
        """Write this data set to another folder (e.g. CSV → Parquet); see :func:`write_dataset`.

        Derived stance labels are not written (the copy derives them again on loading).
        """
        trials = ({n: df.drop(columns=[STANCE]) if n in self.stance_derivations else df
                   for n, df in self.trials.items()} if self.stance_derivations else self.trials)
        return write_dataset(path, self.meta, trials, format, overwrite=overwrite)


__all__ = ["StancePhase", "stance_phases", "Dataset"]
