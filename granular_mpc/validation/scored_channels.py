"""Which channels a replay needs and which it scores (format-v1 names, by channel group).

Used by :mod:`.prepare` (stance windows), :mod:`.channel_coverage` (the reports) and the
replay scoring; ``docs/import.md`` §"Validate and diagnose with the channels you have".
"""

from __future__ import annotations

from typing import Sequence

from ..exceptions import DataFormatError, DataProblem
from .dataformat import Dataset
from .dataformat.channels import ChannelGroup, ChannelSet

#: the channel groups a replay cannot do without (initial state and inputs)
REPLAY_REQUIRED = (ChannelGroup.JOINT_ANGLES, ChannelGroup.JOINT_TORQUES,
                   ChannelGroup.TRUNK_ORIENTATION, ChannelGroup.TRUNK_ANGULAR_VELOCITY)

#: scored channel groups (the replay predicts them), in channel order
SCORED_GROUPS = (ChannelGroup.JOINT_ANGLES, ChannelGroup.FOOT_FORCE, ChannelGroup.INTRUSION)


def channel_names(joint_names: Sequence[str], channels: ChannelSet | None = None) -> list[str]:
    """Scored channels (format-v1 names): each joint angle, GRF x/y/z, intrusion x/y/z —
    those of the measured groups of ``channels`` (default: all)."""
    ch = ChannelSet.all() if channels is None else channels
    out: list[str] = []
    for g in SCORED_GROUPS:
        if ch.has(g):
            out += list(g.columns(joint_names))
    return out


def check_replayable(ds: Dataset) -> None:
    """Raise if ``ds`` lacks a group a replay needs (:data:`REPLAY_REQUIRED`).

    Raises:
        DataFormatError: naming the missing groups and their columns.
    """
    missing = [g for g in REPLAY_REQUIRED if not ds.has(g)]
    if missing:
        raise DataFormatError([DataProblem(
            str(ds.path / "meta.yaml"), f"a replay needs the channel group '{g.value}' "
            f"({', '.join(g.columns(ds.joint_names))}), which this data set does not declare",
            "channels") for g in missing])


CHANNEL_UNITS = {"q": "rad", "grf": "N", "intrusion": "m"}


def channel_unit(ch: str) -> str:
    """Unit of a scored channel (``rad``, ``N`` or ``m``; ``""`` if unknown)."""
    return CHANNEL_UNITS.get(ch.split("_")[0], "")


__all__ = ["REPLAY_REQUIRED", "SCORED_GROUPS", "CHANNEL_UNITS", "channel_names",
           "check_replayable", "channel_unit"]
