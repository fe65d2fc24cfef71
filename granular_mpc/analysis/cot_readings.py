"""Every cost-of-transport reading of a run log in one call: whole-body and decoupled.

The readings of the paper's E = ∫‖τ_aᵀ q̇_a‖ dt (``abs_per_joint``, the default; ``abs_net``,
the literal one; ``positive``) are defined in :mod:`granular_mpc.analysis.cot`; the
decoupled sagittal + frontal form in :mod:`granular_mpc.analysis.cot_decoupled`. This
module reads both from a log window and names the results for ``summary.json``
(:meth:`RunCot.summary_items`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pandas as pd

from .attitude import trunk_rpy
from .cot import (COT_READINGS, DEFAULT_COT_READING, STANDARD_GRAVITY, CotReadings,
                  cot_readings_from_arrays, log_joints, log_window, resolve_weight)
from .cot_decoupled import DecoupledCotReadings, cot_decoupled_readings
from .stances import planned_column

N_ACTUATORS = 6


@dataclass(frozen=True)
class RunCot:
    """All CoT readings of one log window.

    Attributes:
        full: whole-body CoT under each reading.
        decoupled: sagittal + frontal CoT under each reading (same W_r and d as ``full``);
            None if not computed (``decoupled=False``, or not six actuated joints).
        default_reading: the reading named the default (:data:`DEFAULT_COT_READING`).
    """

    full: CotReadings
    decoupled: DecoupledCotReadings | None
    default_reading: str = DEFAULT_COT_READING

    @property
    def cot(self) -> float:
        """Whole-body CoT under the default reading [-]."""
        return self.full.get(self.default_reading).cot

    def summary_items(self) -> dict[str, float | str | None]:
        """Keys for ``summary.json``: ``cot_<reading>`` and ``cot_decoupled_<reading>`` for
        every reading (None when not computed), ``energy_J_<reading>`` [J],
        ``net_work_J`` [J] and ``cot_default_reading``."""
        out: dict[str, float | str | None] = {}
        for r in COT_READINGS:
            out[f"cot_{r}"] = self.full.get(r).cot
        for r in COT_READINGS:
            out[f"cot_decoupled_{r}"] = None if self.decoupled is None else self.decoupled.get(r)
        for r in COT_READINGS:
            out[f"energy_J_{r}"] = self.full.get(r).energy_J
        out["net_work_J"] = self.full.net_work_J
        out["cot_default_reading"] = self.default_reading
        return out


def trunk_pitch_roll(log: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Trunk pitch (about +y) and roll (about +x) [rad] per row, R_W_B = Rz Ry Rx, from
    ``base_qw, base_qx, base_qy, base_qz``."""
    rpy = trunk_rpy(log)
    return rpy[:, 1], rpy[:, 0]


def cot_readings_report(log: pd.DataFrame, *, weight: float | None = None,
                        mass: float | None = None, biped=None,
                        joints: Sequence[str] | None = None, t_start: float | None = None,
                        t_end: float | None = None, distance: float | None = None,
                        decoupled: bool = True, actuation: str = "exact") -> RunCot:
    """Whole-body and decoupled CoT of a log window under every reading.

    Args:
        log: run log (``time``, ``tau_*``, ``dq_*``, ``com_vx``; for the decoupled form
            also ``q_*``, the ``base_q*`` quaternion and ``stance``/``planned_stance``).
        weight: W_r = m g [N]; default ``mass`` × :data:`~.cot.STANDARD_GRAVITY`, else
            ``biped.weight``.
        mass: robot mass m [kg] (used when ``weight`` is None).
        biped: robot model (joint names in actuator order, weight, joint-axis signs).
        joints: actuated joint names in actuator order (left abd, pitch, knee, right abd,
            pitch, knee); default: the biped's, else the log's ``tau_*`` order.
        t_start, t_end: the window [s] (inclusive), e.g. the summary's averaging window.
        distance: d [m]; default ∫ com_vx dt over the window.
        decoupled: also compute the decoupled form (needs six actuated joints).
        actuation: decoupled B matrices, ``"exact"`` (default) or ``"paper"``.

    Returns:
        :class:`RunCot`.
    """
    if weight is None and mass is not None:
        weight = float(mass) * STANDARD_GRAVITY
    w = resolve_weight(weight, biped)
    part = log_window(log, t_start, t_end)
    js = log_joints(part, biped, joints)
    t = part["time"].to_numpy(dtype=float)
    tau = part[[f"tau_{j}" for j in js]].to_numpy(dtype=float)
    dq = part[[f"dq_{j}" for j in js]].to_numpy(dtype=float)
    full = cot_readings_from_arrays(t, tau, dq, part["com_vx"].to_numpy(dtype=float), w,
                                    distance=distance)
    dec = None
    if decoupled and len(js) == N_ACTUATORS:
        pitch, roll = trunk_pitch_roll(part)
        dec = cot_decoupled_readings(
            t, part[[f"q_{j}" for j in js]].to_numpy(dtype=float), dq, tau, pitch, roll,
            part[planned_column(part)].astype(str).to_numpy(), w,
            full.abs_net.distance_m, biped=biped, actuation=actuation)
    return RunCot(full, dec)


__all__ = ["RunCot", "cot_readings_report", "trunk_pitch_roll"]
