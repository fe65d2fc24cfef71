"""Where, when and with what a residual is structured: the records of localisation.

:class:`Localization` is what :func:`.localise.localize` finds for one residual cube;
``diagnosis.json`` → ``localization.before`` / ``.after`` (same keys).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

from .records import OMIT_NONE, Record


@dataclass(frozen=True)
class Cell(Record):
    """One channel × stance-phase bin, over the stances of one side (or ``all``).

    Attributes:
        channel: format-v1 channel; side: ``all``, ``left`` or ``right``.
        phase_lo, phase_hi: the bin [% of stance].
        bias, sd, rms: mean, standard deviation across stances and RMS of the binned
            residual (channel units, ``unit``).
        t: bias / (sd / √n); n: stances.
        normalised_bias: bias / σ_c (the channel's stance-to-stance scatter).
        major: for a significant cell (|t| ≥ T_CELL), |normalised_bias| ≥ MAJOR_BIAS
            and |bias| ≥ ``practical_floor(σ_c, σ_meas)`` (PRACTICAL_BIAS × the error of
            one sample of a right model: replay scatter and sensor noise; see
            :func:`..localise.practical_floor`); None for the others.
    """

    channel: str
    side: str
    phase_lo: float
    phase_hi: float
    bias: float
    sd: float
    rms: float
    t: float
    n: int
    unit: str
    normalised_bias: float
    major: bool | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class ChannelStructure(Record):
    """Per channel: RMS of the residual and of its mean phase profile (the systematic
    part), and the systematic share of the mean square (None: no data)."""

    rms: float | None
    systematic_rms: float | None
    systematic_share: float | None
    unit: str


@dataclass(frozen=True)
class SpeedBias(Record):
    """Per commanded speed [m/s] and channel: mean and RMS of the binned residual."""

    speed_mps: float
    channel: str
    bias: float
    rms: float
    n_stances: int


@dataclass(frozen=True)
class Correlate(Record):
    """Rank correlation (and mutual information, when estimated) of a channel's binned,
    normalised residual with one binned measured feature."""

    feature: str
    spearman: float
    p_value: float
    mutual_information: float | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class Whiteness(Record):
    """Ljung–Box test of a channel's stance-to-stance sequence of mean residuals."""

    lags: int
    q: float
    p_value: float


@dataclass(frozen=True)
class Localization(Record):
    """Structure of one residual cube.

    Attributes:
        cells: every channel × phase × side cell.
        significant_cells: the strongest 40 cells with |t| ≥ T_CELL (major first).
        n_significant_cells, n_major_cells: counts over all cells.
        by_channel, by_speed: systematic share per channel; bias per speed and channel.
        correlates: per channel, features by decreasing |ρ|.
        whiteness_stance_sequence: per channel, Ljung–Box of the stance sequence.
    """

    cells: tuple[Cell, ...]
    significant_cells: tuple[Cell, ...]
    n_significant_cells: int
    n_major_cells: int
    by_channel: Mapping[str, ChannelStructure]
    by_speed: tuple[SpeedBias, ...]
    correlates: Mapping[str, tuple[Correlate, ...]]
    whiteness_stance_sequence: Mapping[str, Whiteness]


__all__ = ["Cell", "ChannelStructure", "SpeedBias", "Correlate", "Whiteness", "Localization"]
