"""Measured and missing channels of a data set, and per candidate effect whether it can be
assessed with them: the records ``validate`` and ``diagnose`` report
(:mod:`.diagnosis.coverage` decides the candidates; ``docs/import.md``)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Mapping

from .dataformat import Dataset
from .dataformat.channels import ChannelGroup
from .scored_channels import SCORED_GROUPS, channel_names

#: a candidate moving no measured channel × phase mean by this many σ at its nominal
#: magnitude cannot be assessed when channel groups are missing
#: (:mod:`granular_mpc.validation.diagnosis.coverage`); the practical-size threshold of
#: the diagnosis (``diagnosis.thresholds.MIN_EFFECT_SIZE``)
MIN_ASSESSABLE_SIZE = 1.0


@dataclass(frozen=True)
class EffectCoverage:
    """Whether one candidate can be assessed with the measured channels.

    Attributes:
        name: the effect; kind: its kind.
        assessable: False: taken out of the ranking.
        size: detectable size at its nominal magnitude [σ] (NaN: not computed).
        channel: the measured channel where ``size`` is reached (``""``: none).
        reason: in words.
        identifiable_size: the part of ``size`` the nuisance columns do not explain, and
            no other candidate either (the smallest over them) [σ] (NaN: not computed;
            :mod:`.diagnosis.identifiability`).
        indistinguishable_from: the candidates that explain its signature on the measured
            channels within less than the threshold.
    """

    name: str
    kind: str
    assessable: bool
    size: float
    channel: str
    reason: str
    identifiable_size: float = float("nan")
    indistinguishable_from: tuple[str, ...] = ()


@dataclass(frozen=True)
class Coverage:
    """Measured and missing channels of a data set and what can be assessed with them.

    Attributes:
        measured, missing: channel group names.
        declared: the data set lists its groups (False: no ``channels`` key, all measured).
        scored: scored channels (measured).
        not_scored: channels the replay predicts that were not measured.
        trunk_state: where the trunk position / velocity come from (``measured``,
            ``velocity from position``, ``leg odometry``).
        stance_source: ``measured``, ``force`` or ``kinematics``.
        touchdowns: where the replay windows' touchdowns (and, without foot force, the
            trailing foot's initial load) come from (:func:`touchdown_source`).
        calibration: how ζ was set (equation error, or kept and why).
        effects: per candidate (diagnosis only).
        threshold: :data:`MIN_ASSESSABLE_SIZE` [σ].
    """

    measured: tuple[str, ...]
    missing: tuple[str, ...]
    declared: bool
    scored: tuple[str, ...]
    not_scored: tuple[str, ...]
    trunk_state: str
    stance_source: str
    touchdowns: str = ""
    calibration: str = ""
    effects: tuple[EffectCoverage, ...] = ()
    threshold: float = MIN_ASSESSABLE_SIZE

    @property
    def not_assessable(self) -> tuple[str, ...]:
        """Candidates that cannot be assessed without the missing channels."""
        return tuple(e.name for e in self.effects if not e.assessable)

    @property
    def assessable(self) -> tuple[str, ...]:
        """Candidates that can."""
        return tuple(e.name for e in self.effects if e.assessable)

    @property
    def indistinguishable(self) -> tuple[tuple[str, str], ...]:
        """(candidate that cannot be assessed, the candidate that explains its signature
        on the measured channels): an addition of the second one is ambiguous."""
        return tuple((e.name, b) for e in self.effects for b in e.indistinguishable_from)

    @property
    def warnings(self) -> tuple[str, ...]:
        """One line per candidate that cannot be assessed."""
        miss = ", ".join(self.missing)
        return tuple(f"candidate '{e.name}' cannot be assessed without {miss}: {e.reason}"
                     for e in self.effects if not e.assessable)

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        return {"measured": list(self.measured), "missing": list(self.missing),
                "declared": self.declared, "scored_channels": list(self.scored),
                "not_scored_channels": list(self.not_scored), "trunk_state": self.trunk_state,
                "stance_source": self.stance_source, "touchdowns": self.touchdowns,
                "calibration": self.calibration,
                "threshold_sigma": self.threshold,
                "not_assessable": list(self.not_assessable),
                "effects": [asdict(e) for e in self.effects]}

    @classmethod
    def from_dict(cls, d: Mapping) -> "Coverage":
        """Inverse of :meth:`to_dict`."""
        return cls(tuple(d["measured"]), tuple(d["missing"]), bool(d["declared"]),
                   tuple(d["scored_channels"]), tuple(d["not_scored_channels"]),
                   str(d["trunk_state"]), str(d["stance_source"]), str(d.get("touchdowns", "")),
                   str(d.get("calibration", "")),
                   tuple(_effect_from_dict(e) for e in d.get("effects", ())),
                   float(d.get("threshold_sigma", MIN_ASSESSABLE_SIZE)))

    def markdown(self) -> list[str]:
        """The report section (markdown lines)."""
        lines = ["## Channels", "",
                 f"* measured: {', '.join(self.measured)}"
                 + ("" if self.declared else " (no `channels` key: all groups)"),
                 f"* **not measured:** {', '.join(self.missing) or 'none'}",
                 f"* scored channels: {', '.join(self.scored)}",
                 f"* not scored (not measured): {', '.join(self.not_scored) or 'none'}",
                 f"* trunk position / velocity: {self.trunk_state}; stance labels: "
                 f"{self.stance_source}"]
        if self.touchdowns:
            lines.append(f"* touchdowns: {self.touchdowns}")
        if self.calibration:
            lines.append(f"* calibration: {self.calibration}")
        if self.effects:
            bad = [e for e in self.effects if not e.assessable]
            lines += ["", f"Candidates that **cannot be assessed** without "
                          f"{', '.join(self.missing) or '-'} (rules: at its nominal magnitude "
                          f"it moves no measured channel × phase mean by ≥ {self.threshold:g} σ; "
                          f"or less than {self.threshold:g} σ of that signature (per trial "
                          "and side) is left once the calibration's free parameters, or "
                          "they and any one other candidate, are fitted; or it reads an "
                          "unmeasured column): "
                      + (", ".join(f"`{e.name}`" for e in bad) or "none"), ""]
            for a, b in self.indistinguishable:
                lines.append(f"* **indistinguishable with the measured channels: {a}, {b}** "
                             f"— an addition of {b} may be {a}'s doing (ambiguous)")
            lines += ["", "| candidate | kind | size at nominal magnitude | on | identifiable "
                          "part | assessable |", "|---|---|---|---|---|---|"]
            for e in self.effects:
                size = "–" if not math.isfinite(e.size) else f"{e.size:.2f} σ"
                ident = ("–" if not math.isfinite(e.identifiable_size)
                         else f"{e.identifiable_size:.2f} σ")
                lines.append(f"| {e.name} | {e.kind} | {size} | {e.channel or '–'} | {ident} | "
                             f"{'yes' if e.assessable else 'no: ' + e.reason} |")
        return lines + [""]


def _effect_from_dict(e: Mapping) -> EffectCoverage:
    """One :class:`EffectCoverage` from its JSON form (None → NaN, lists → tuples)."""
    def num(v):
        return float("nan") if v is None else float(v)
    return EffectCoverage(str(e["name"]), str(e["kind"]), bool(e["assessable"]),
                          num(e["size"]), str(e["channel"]), str(e["reason"]),
                          num(e.get("identifiable_size")),
                          tuple(e.get("indistinguishable_from", ())))


def trunk_state_source(ds: Dataset) -> str:
    """Where the replays' trunk position and velocity come from (see :mod:`..prepare`)."""
    if ds.has(ChannelGroup.TRUNK_POSITION):
        return ("measured" if ds.has(ChannelGroup.TRUNK_LINEAR_VELOCITY)
                else "velocity from position")
    return "leg odometry (stance foot + IMU)"


def touchdown_source(ds: Dataset) -> str:
    """Where the replay windows' touchdowns and, without measured foot force, the
    trailing foot's initial load come from (see :mod:`..prepare`)."""
    est = "foot force ESTIMATED from the joint torques (leg dynamics; not a measured channel)"
    out = (f"stance labels ({ds.stance_source})" if ds.stance_source != "kinematics"
           else f"{est}, else where the leg kinematics say the foot stops")
    if not ds.has(ChannelGroup.FOOT_FORCE):
        out += "; trailing foot's initial load: " + (
            "the same estimate" if ds.stance_source == "kinematics" else est)
    return out


def channel_coverage(ds: Dataset) -> Coverage:
    """Measured / missing groups and scored / not-scored channels of ``ds``."""
    J = list(ds.joint_names)
    scored = channel_names(J, ds.channels)
    every = [c for g in SCORED_GROUPS for c in g.columns(J)]
    return Coverage(tuple(g.value for g in ds.channels),
                    tuple(g.value for g in ds.channels.missing), ds.channels.declared,
                    tuple(scored), tuple(c for c in every if c not in scored),
                    trunk_state_source(ds), str(ds.stance_source), touchdown_source(ds))




__all__ = ["Coverage", "EffectCoverage", "channel_coverage", "trunk_state_source",
           "touchdown_source",
           "MIN_ASSESSABLE_SIZE"]
