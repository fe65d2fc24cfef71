"""Velocity columns against the time derivative of their position columns.

A velocity in the wrong unit (mm/s, deg/s), sign or frame shows as a ratio far from 1, or
a negative correlation, between the column and the finite-difference derivative of the
matching position or angle column.
"""

from __future__ import annotations

import math

import numpy as np

from .tolerances import FormatTolerances
from .trial_check import RAD_PER_DEG, TrialCheck


def scale_hint(ratio: float, angular: bool) -> str:
    """Name the unit mistake suggested by ``ratio`` = velocity / time derivative of position."""
    if not (np.isfinite(ratio) and ratio > 0):
        return ""
    known = ([(1 / RAD_PER_DEG, "velocity in degrees per second"),
              (RAD_PER_DEG, "angle in degrees")]
             if angular else
             [(1e3, "velocity in mm/s"), (1e2, "velocity in cm/s"), (1e-3, "position in mm"),
              (1e-2, "position in cm")])
    for factor, text in known:
        if abs(math.log(ratio / factor)) < math.log(1.5):
            return f" — a factor of {factor:.4g}: {text}?"
    return ""


def rate_consistency(t: TrialCheck, vel_col: str, measured: np.ndarray, derived: np.ndarray,
                     source: str, angular: bool, tol: FormatTolerances) -> None:
    """Compare a velocity column with the time derivative of its position column.

    With m the measured velocity and d the finite-difference derivative (both at the
    mid-points of the samples), ratio = Σm² / Σmd (unbiased by noise in d) and
    corr = Σmd / √(Σm² Σd²). Only well-correlated channels are judged.
    """
    ok = np.isfinite(measured) & np.isfinite(derived)
    if ok.sum() < 10:
        return
    m, d = measured[ok], derived[ok]
    smm, sdd, smd = float(m @ m), float(d @ d), float(m @ d)
    if smm <= 0 or sdd <= 0 or math.sqrt(sdd / m.size) < 1e-6:
        return
    corr = smd / math.sqrt(smm * sdd)
    if corr <= -tol.rate_correlation:
        t.add(f"has the opposite sign of the time derivative of {source} (correlation "
              f"{corr:.2f}): sign convention or frame?", vel_col)
        t.flagged.add(vel_col)
    elif corr >= tol.rate_correlation:
        ratio = smm / smd
        if not 1 / tol.rate_ratio <= ratio <= tol.rate_ratio:
            t.add(f"is {ratio:.4g}× the time derivative of {source} (expected 1; correlation "
                  f"{corr:.2f}){scale_hint(ratio, angular)}", vel_col)
            t.flagged.add(vel_col)


def midpoints(v: np.ndarray) -> np.ndarray:
    """Mean of each pair of consecutive samples (n − 1 values)."""
    return 0.5 * (v[1:] + v[:-1])


__all__ = ["scale_hint", "rate_consistency", "midpoints"]
