"""Checks of the contact columns: ground force sign and magnitude, intrusion unit and
sign, and the direction of travel against the commanded speed."""

from __future__ import annotations

import math

import numpy as np

from ...columns import INTRUSION_COLUMNS
from .robot_facts import RobotFacts
from .tolerances import FormatTolerances
from .trial_check import TrialCheck


def check_contact(t: TrialCheck, labels: np.ndarray | None, facts: RobotFacts | None,
                  speed: float | None, time_ok: bool, tol: FormatTolerances) -> None:
    """GRF sign and magnitude, intrusion unit and sign, direction of travel."""
    for col in INTRUSION_COLUMNS:
        if col in t.values:
            v = t.values[col]
            big = np.isfinite(v) & (np.abs(v) > tol.max_intrusion)
            if big.any():
                peak = float(np.max(np.abs(v[big])))
                t.add_rows(col, f"|{col}| above {tol.max_intrusion:g} m (longer than the leg)",
                           big, f"; largest {peak:.4g} — millimetres or centimetres instead of "
                           "metres?")
                t.flagged.add(col)
    duration = None
    if time_ok:
        time = t.values["time"]
        duration = float(time[-1] - time[0])
    if labels is not None:
        stance = np.isin(labels, ("left", "right"))
        if not stance.any():
            t.add("stance is 'none' in every row: the trial has no stance phase", "stance")
        elif stance.sum() >= 10:
            if t.ok("grf_z"):
                fz = t.values["grf_z"]
                weight = facts.weight if facts is not None else None
                med = float(np.median(fz[stance]))
                if med < 0 and (weight is None or med < -0.1 * weight):
                    t.add(f"grf_z is negative during stance (median {med:.4g} N): format v1 wants "
                          "the force OF the ground ON the foot, positive up", "grf_z")
                    t.flagged.add("grf_z")
                elif weight is not None and duration is not None \
                        and duration >= tol.min_travel_duration:
                    ratio = float(np.sum(fz[stance]) / (len(fz) * weight))
                    if not 1 / tol.weight_ratio <= ratio <= tol.weight_ratio:
                        hint = ""
                        for factor, unit in ((1 / 9.81, "kgf"), (1e3, "mN"), (1e-3, "kN")):
                            if ratio > 0 and abs(math.log(ratio / factor)) < math.log(1.5):
                                hint = f" — in {unit} instead of N?"
                        t.add(f"the mean vertical ground force over the trial is {ratio:.3g}× the "
                              f"robot's weight {weight:.4g} N (expected about 1){hint}", "grf_z")
                        t.flagged.add("grf_z")
            if t.ok("intrusion_z"):
                z = t.values["intrusion_z"][stance]
                if np.median(z) < 0 and np.percentile(z, 10) < -tol.intrusion_sign \
                        and np.percentile(z, 90) < tol.intrusion_sign:
                    t.add(f"intrusion_z is negative during most of stance (10th percentile "
                          f"{np.percentile(z, 10):.4g} m): format v1 counts z positive DEEPER "
                          "(sinkage) — sign flipped?", "intrusion_z")
                    t.flagged.add("intrusion_z")
    if speed is not None and abs(speed) >= 0.05 and duration is not None \
            and duration >= tol.min_travel_duration and t.ok("base_x", "base_y"):
        dx = float(t.values["base_x"][-1] - t.values["base_x"][0])
        dy = float(t.values["base_y"][-1] - t.values["base_y"][0])
        travel = math.hypot(dx, dy)
        if travel >= 0.25 * abs(speed) * duration:
            cos = dx * math.copysign(1.0, speed) / travel
            if cos < math.cos(math.radians(45)):
                t.add(f"the trunk travelled (Δx, Δy) = ({dx:.3g}, {dy:.3g}) m in {duration:.3g} s "
                      f"at a commanded speed of {speed:g} m/s: world x must be the walking "
                      "direction (docs/notation.md)", "base_x,base_y")


__all__ = ["check_contact"]
