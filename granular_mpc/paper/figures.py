"""The comparison's figures: CoT vs speed on both terrains, per-stance cumulative CoT, Δθ_r."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from .measures import PHASE, READING, StanceCurves

COLOURS = {"dry_sand": "tab:orange", "rigid": "tab:grey"}


def _save(fig: Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def plot_cot_speed(cots: Mapping[str, Sequence[float]], speeds: Sequence[float], path: Path) -> Path:
    """CoT (default reading) against commanded speed per terrain, with order-2 fits."""
    fig = Figure(figsize=(5, 3.6))
    ax = fig.add_subplot()
    for terrain, c in cots.items():
        v, y = np.asarray(speeds, float), np.asarray(c, float)
        ok = np.isfinite(y)
        ax.plot(v[ok], y[ok], "o", color=COLOURS.get(terrain), label=terrain)
        if ok.sum() >= 3:
            vv = np.linspace(v[ok].min(), v[ok].max(), 50)
            ax.plot(vv, np.polyval(np.polyfit(v[ok], y[ok], 2), vv), "-", color=COLOURS.get(terrain))
    ax.set_xlabel("commanded speed [m/s]")
    ax.set_ylabel(f"CoT ({READING}) [-]")
    ax.set_title("CoT vs speed (paper Fig. 6d)")
    ax.legend()
    return _save(fig, path)


def plot_stance_curves(curves: Mapping[str, StanceCurves], path: Path, *, what: str) -> Path:
    """Mean cumulative CoT (``what="cot"``) or Δθ_r (``"dtheta"``) over stance phase."""
    fig = Figure(figsize=(5, 3.6))
    ax = fig.add_subplot()
    seen: dict[str, int] = {}
    for label, c in curves.items():
        y = c.cot_cum if what == "cot" else c.dtheta_r_deg
        terrain = label.split(" ")[0]
        k = seen[terrain] = seen.get(terrain, -1) + 1        # 2nd curve of a terrain: dashed
        ax.plot(PHASE, y, color=COLOURS.get(terrain), linestyle=("-", "--", ":")[k % 3],
                label=f"{label} (n={c.n_stances})")
    ax.set_xlabel("stance [%] (touchdown to lift-off)")
    if what == "cot":
        ax.set_ylabel("cumulative CoT, E(t)/(W d_stance) [-]")
        ax.set_title("per-stance cumulative CoT (paper Fig. 6c)")
    else:
        ax.set_ylabel("Δθ_r [deg]")
        ax.set_title("foot rolling angle (paper Fig. 6a)")
    ax.legend()
    return _save(fig, path)


__all__ = ["plot_cot_speed", "plot_stance_curves"]
