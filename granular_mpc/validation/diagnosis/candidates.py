"""Candidate effects and their regression columns (``docs/validation.md`` §3.2).

A candidate is a registered effect (any kind: terrain force, joint, sensor, geometry) with
parameters that switch it off (``EffectInfo.neutral``); each such *magnitude* parameter
is one regression :class:`Column`. The calibration's own parameters are columns too
(``candidate="calibration"``, nuisance, see :mod:`.calibration`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from ...effects import EffectInfo, all_effects, effect_info
from ...exceptions import ConfigError
from ..prepare import StanceWindow
from ..replay.measurement import changes_replay, check_sensor_inversion, check_sensor_specs
from ..replay.model import Variant, effect_variant

#: the candidate name of the calibration's (nuisance) columns
CALIBRATION = "calibration"


@dataclass(frozen=True)
class Column:
    """One regression column: a magnitude parameter of a candidate (or a nuisance θ).

    Attributes:
        candidate: effect name, or ``"calibration"``.
        param: parameter (θ name for nuisance).
        neutral: value that switches it off (nuisance: the calibrated value).
        step: finite-difference step of the sensitivity.
        lower, upper: bounds of the parameter value.
        unit: the parameter's unit.
    """

    candidate: str
    param: str
    neutral: float
    step: float
    lower: float
    upper: float
    unit: str = ""

    @property
    def key(self) -> str:
        """``<candidate>.<param>``: the column's name in designs and regressions."""
        return f"{self.candidate}.{self.param}"

    @property
    def bounds(self) -> tuple[float, float]:
        """Bounds of the column's coefficient (the change from ``neutral``)."""
        return (self.lower - self.neutral, self.upper - self.neutral)


def candidate_columns(info: EffectInfo) -> list[Column]:
    """Columns of one candidate: its parameters that switch it off (``neutral``)."""
    cols = []
    for p, neutral in info.neutral.items():
        spec = info.params[p]
        step = spec.default - neutral
        if abs(step) < 1e-12:
            step = 0.1 * (spec.upper - spec.lower)
            if neutral + step > spec.upper:
                step = -step
        cols.append(Column(info.name, p, float(neutral), float(step), spec.lower, spec.upper,
                           spec.unit))
    return cols


def variant_for(info: EffectInfo, values: Mapping[str, float], base: Variant) -> Variant:
    """``base`` with the effect ``info`` on at its neutral parameters updated by ``values``."""
    p = info.neutral_params()
    p.update(values)
    return effect_variant([(info, p)], base)


@dataclass(frozen=True)
class CandidateSet:
    """The candidates of a diagnosis and their columns.

    Attributes:
        infos: effect name → its registry entry (only effects that can be switched off).
        columns: effect name → its magnitude columns.
        sensor_outputs: sensor effect → the data columns it changes at its default
            parameters, tried once on one stance window (:func:`check_sensor_candidates`
            sets them; empty before).
    """

    infos: Mapping[str, EffectInfo]
    columns: Mapping[str, tuple[Column, ...]]
    sensor_outputs: Mapping[str, frozenset[str]] = field(default_factory=dict)

    @property
    def replayed_sensors(self) -> frozenset[str]:
        """The sensor effects that change what a replay reads (``q_*``, ``dq_*``,
        ``tau_*``, ``base_*``): their sensitivities need replays, like the other kinds."""
        return frozenset(n for n, cols in self.sensor_outputs.items() if changes_replay(cols))

    def sensors_changing(self, prefix: str | tuple[str, ...]) -> frozenset[str]:
        """The sensor effects that change some column named ``prefix…`` (``"tau_"``: the
        measured joint torques; a tuple: any of those prefixes)."""
        return frozenset(n for n, cols in self.sensor_outputs.items()
                         if any(c.startswith(prefix) for c in cols))

    def needs_replay(self, name: str) -> bool:
        """Whether the candidate's sensitivity needs replays (every kind but a sensor
        effect acting on the outputs only)."""
        return self.kind(name) != "sensor" or name in self.replayed_sensors

    def without(self, names: Sequence[str]) -> "CandidateSet":
        """The set without the candidates ``names``."""
        drop = set(names)
        return replace(self, infos={n: i for n, i in self.infos.items() if n not in drop},
                       columns={n: c for n, c in self.columns.items() if n not in drop},
                       sensor_outputs={n: c for n, c in self.sensor_outputs.items()
                                       if n not in drop})

    @property
    def keys(self) -> dict[str, list[str]]:
        """Effect name → its column keys."""
        return {n: [c.key for c in cols] for n, cols in self.columns.items()}

    @property
    def terrain_force_names(self) -> list[str]:
        """The terrain-force candidates (compiled into the replayed terrain)."""
        return [n for n, i in self.infos.items() if i.kind == "terrain_force"]

    def kind(self, name: str) -> str:
        """The effect's kind."""
        return self.infos[name].kind

    def params_at(self, name: str, values: Mapping[str, float]) -> dict[str, float]:
        """The effect's neutral parameters with its columns set from ``values``
        (column key → value)."""
        p = self.infos[name].neutral_params()
        for c in self.columns[name]:
            p[c.param] = values[c.key]
        return p


def build_candidates(names: Sequence[str] | None = None) -> CandidateSet:
    """The candidates ``names`` (default: every registered effect of any kind), those
    that can be switched off, with their columns."""
    names = sorted(all_effects()) if names is None else list(dict.fromkeys(names))
    infos = {n: effect_info(n) for n in names}
    infos = {n: i for n, i in infos.items() if i.neutral}      # needs a way to switch off
    return CandidateSet(infos, {n: tuple(candidate_columns(i)) for n, i in infos.items()})


def check_sensor_candidates(candidates: CandidateSet, window: StanceWindow,
                            joint_names: Sequence[str]) -> CandidateSet:
    """Try every sensor candidate on one window's columns (every column of the data
    format) before any replay, and keep the columns each changes
    (:attr:`CandidateSet.sensor_outputs`: which change a replay's inputs, which the
    measured torques).

    Raises:
        ConfigError: a sensor effect reads a column the data do not have (the error names
            the effect and the column) or returns one that is not a format column.
    """
    specs = [(i, i.resolve_params({})) for i in candidates.infos.values() if i.kind == "sensor"]
    changed = check_sensor_specs(specs, window, joint_names)
    return replace(candidates, sensor_outputs={n: frozenset(c) for n, c in changed.items()})


def drop_uninvertible_sensor_candidates(candidates: CandidateSet, window: StanceWindow,
                                        joint_names: Sequence[str]
                                        ) -> tuple[CandidateSet, tuple[str, ...]]:
    """The sensor candidates that change a replay's inputs, inverted on one window's
    torques at each of their probe values (the values the screening replays); one that
    cannot be inverted (a map mixing samples without an ``inverse``) is dropped with a
    warning naming it instead of replaying as diverged.

    Returns:
        The set without them, and one warning per dropped candidate.
    """
    drop, warns = [], []
    for n in sorted(candidates.replayed_sensors):
        info = candidates.infos[n]
        for col in candidates.columns[n]:
            p = info.neutral_params()
            p[col.param] = col.neutral + col.step
            try:
                check_sensor_inversion([(info, p)], window, joint_names)
            except ConfigError as exc:
                drop.append(n)
                warns.append(f"candidate '{n}' (sensor) was not ranked: {exc}")
                break
    return candidates.without(drop), tuple(warns)


def dead_candidates(candidates: CandidateSet, sens: Mapping[str, np.ndarray],
                    channels: Sequence[str]) -> dict[str, str]:
    """Candidates whose every column has a zero (or undefined) sensitivity on the scored
    channels: they cannot explain anything in these data (e.g. a sensor effect on a
    column nobody scores, or one that skips columns it does not find). Name → warning."""
    out = {}
    for n, cols in candidates.columns.items():
        peak = 0.0
        for c in cols:
            S = sens.get(c.key)
            if S is not None and np.isfinite(S).any():
                peak = max(peak, float(np.nanmax(np.abs(S))))
        if not peak > 0.0:
            out[n] = (f"candidate '{n}' ({candidates.kind(n)}) changes none of the scored "
                      f"channels ({', '.join(channels[:3])} …) in these data: its regression "
                      "column is all zero, so it was not ranked")
    return out


def drop_dead_candidates(candidates: CandidateSet, sens: Mapping[str, np.ndarray],
                         channels: Sequence[str]) -> tuple[CandidateSet, tuple[str, ...]]:
    """:func:`dead_candidates` removed from the set, each with a ``UserWarning``."""
    dead = dead_candidates(candidates, sens, channels)
    for msg in dead.values():
        warnings.warn(msg, UserWarning, stacklevel=2)
    return candidates.without(list(dead)), tuple(dead.values())


#: A candidate whose sensitivity is undefined (its replays diverged or jumped) in more than
#: this share of the cells where the residual is defined is not ranked. The regression
#: keeps only the rows where every column is defined, so such a candidate would take those
#: rows from every other candidate (measured, issue 11: a fed-back proposal whose replays
#: diverged cut the systematic rows from 744 to 96 and joint_friction's inclusion from 38 %
#: to 0). A design choice, not fitted to data: losing one row in ten for all is the most
#: one candidate may cost the others.
MAX_DIVERGED_SHARE = 0.1


def diverged_candidates(candidates: CandidateSet, sens: Mapping[str, np.ndarray],
                        R: np.ndarray) -> dict[str, str]:
    """Candidates whose sensitivity is undefined in more than :data:`MAX_DIVERGED_SHARE` of
    the cells (window × channel × phase bin) where the residual ``R`` is defined.
    Name → warning."""
    defined = np.isfinite(R)
    n = int(defined.sum())
    out = {}
    for name, cols in candidates.columns.items():
        lost = np.zeros_like(defined)
        worst, worst_k = None, 0
        for c in cols:
            S = sens.get(c.key)
            if S is not None:
                lost_c = defined & ~np.isfinite(S)
                lost |= lost_c
                if int(lost_c.sum()) > worst_k:
                    worst, worst_k = c, int(lost_c.sum())
        k = int(lost.sum())
        if n and k > MAX_DIVERGED_SHARE * n:
            probe = (f"; the worst, the replays with {worst.param} alone at "
                     f"{worst.neutral + worst.step:.4g}"
                     f"{' ' + worst.unit if worst.unit not in ('', '-') else ''}"
                     f" (each magnitude parameter is probed alone at its default, the others "
                     f"neutral), diverged in {100 * worst_k / n:.0f} %" if worst else "")
            out[name] = (f"candidate '{name}' ({candidates.kind(name)}): its replays diverged "
                         f"in {100 * k / n:.0f} % of the residual's cells ({k} of {n}){probe}. "
                         "The regression keeps only rows every candidate defines, so it would "
                         "take them from all the others: not ranked. A term that is stable only "
                         "beside the others (a negative depth² beside a positive depth term), or "
                         "a default far beyond the data, does this: give it a smaller default, "
                         "bound it, or put the terms under one common scale parameter")
    return out


def drop_diverged_candidates(candidates: CandidateSet, sens: Mapping[str, np.ndarray],
                             R: np.ndarray) -> tuple[CandidateSet, tuple[str, ...]]:
    """:func:`diverged_candidates` removed from the set, each with a ``UserWarning``."""
    bad = diverged_candidates(candidates, sens, R)
    for msg in bad.values():
        warnings.warn(msg, UserWarning, stacklevel=2)
    return candidates.without(list(bad)), tuple(bad.values())


def kept_sensitivities(sens: Mapping[str, np.ndarray], computed: CandidateSet,
                       kept: CandidateSet) -> dict[str, np.ndarray]:
    """The sensitivity cubes without the columns of the candidates dropped after they were
    computed (in ``computed``, not in ``kept``: dead, diverged, unassessable).

    Every regression keeps only the rows on which *all* its columns are finite
    (:class:`.regression.Rows`), so a dropped candidate's cube left in ``sens`` would still
    take its undefined rows from every other candidate: a user term whose replays diverged
    in 81 % of the cells, dropped with a warning, cut the rows from 744 to 168 and undid
    another effect's addition (``docs/validation.md`` §5.3). Nuisance and strength columns
    (no candidate's) are kept.

    Args:
        sens: column key → sensitivity cube (W, C, B).
        computed: the candidate set the cubes were computed for.
        kept: the candidates still ranked.

    Returns:
        A new mapping without the dropped candidates' column keys.
    """
    gone = {c.key for n, cols in computed.columns.items() if n not in kept.columns for c in cols}
    return {k: v for k, v in sens.items() if k not in gone}


__all__ = ["CALIBRATION", "Column", "candidate_columns", "variant_for", "CandidateSet",
           "drop_uninvertible_sensor_candidates",
           "build_candidates", "check_sensor_candidates", "dead_candidates",
           "drop_dead_candidates", "diverged_candidates", "drop_diverged_candidates",
           "kept_sensitivities", "MAX_DIVERGED_SHARE"]
