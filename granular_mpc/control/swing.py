"""Swing-foot trajectory: a cycloid with a fixed apex, as in the paper's gait.

With phase s ∈ [0, 1] and φ = 2πs, the horizontal progress is the cycloid
``c(s) = (φ − sin φ)/(2π)`` (zero velocity and acceleration at both ends) and the height
``z = z0 + (z1 − z0)·c(s) + h·(1 − cos φ)/2``, so the foot lifts and lands vertically at rest.
"""

from __future__ import annotations

import math

import numpy as np


def cycloid_components(p0: tuple, p1: tuple, height: float, phase: float,
                       duration: float) -> tuple[tuple, tuple, tuple]:
    """:func:`cycloid` on Python floats: ``p0``, ``p1`` as (x, y, z) sequences of floats
    [m, W]; returns position, velocity and acceleration as (x, y, z) tuples [m, m/s, m/s²]
    (the same numbers)."""
    s = min(max(phase, 0.0), 1.0)
    phi = 2.0 * math.pi * s
    w = 2.0 * math.pi / duration          # dφ/dt
    sin_phi, cos_phi = math.sin(phi), math.cos(phi)
    c = (phi - sin_phi) / (2.0 * math.pi)
    dc = (1.0 - cos_phi) / (2.0 * math.pi) * w
    ddc = sin_phi / (2.0 * math.pi) * w * w
    # per component on Python floats: the IEEE operations of the array form
    # (p0 + Δ·c, Δ·ċ, Δ·c̈, then the height terms added to z) without NumPy's per-call cost
    (x0, y0, z0), (x1, y1, z1) = p0, p1
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    return ((x0 + dx * c, y0 + dy * c, (z0 + dz * c) + height * (1.0 - cos_phi) / 2.0),
            (dx * dc, dy * dc, dz * dc + height * sin_phi / 2.0 * w),
            (dx * ddc, dy * ddc, dz * ddc + height * cos_phi / 2.0 * w * w))


def cycloid(p0: np.ndarray, p1: np.ndarray, height: float, phase: float,
            duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position [m], velocity [m/s] and acceleration [m/s²] of the swing foot in W.

    Args:
        p0: lift-off point; p1: touchdown target (both in W) [m].
        height: apex above the straight line p0 → p1 [m].
        phase: swing progress in [0, 1]; duration: swing duration [s].
    """
    pos, vel, acc = cycloid_components(np.asarray(p0, dtype=float).tolist(),
                                       np.asarray(p1, dtype=float).tolist(),
                                       height, phase, duration)
    return np.array(pos), np.array(vel), np.array(acc)


__all__ = ["cycloid", "cycloid_components"]
