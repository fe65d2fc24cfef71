"""Workbench figures: model against measurement, RMSE against speed, residual heatmap.

Inputs are the tidy tables of :mod:`granular_mpc.analysis.metrics` (``phase_bands``,
``rmse_table``); every function draws one figure, saves it as PNG when ``out_path`` is
given and returns a :class:`~.figures.PlotOutput` holding the data as plotted (paper
Fig. 5 is :func:`plot_rmse_vs_speed`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ..analysis.metrics import PHASE_COL
from .figures import PALETTE, PHASE_LABEL, PlotOutput, draw_band, new_figure, save_figure


def plot_model_vs_measurement(bands: pd.DataFrame, out_path: str | Path | None = None, *,
                              source_col: str = "source", measurement: str = "measurement",
                              channels: Sequence[str] | None = None,
                              units: Mapping[str, str] | None = None,
                              ncols: int = 3) -> PlotOutput:
    """Model(s) against measurement over the stance: mean ± sd bands per channel.

    Args:
        bands: tidy bands from :func:`~granular_mpc.analysis.metrics.phase_bands` with
            ``by=[source_col]`` (one ``source`` per model, plus the measurement).
        measurement: the value of ``source_col`` naming the measurement (drawn in black).
        channels: channels to draw (default: all, in order of appearance).
        units: channel → unit for the axis labels.

    Returns:
        :class:`PlotOutput`; ``data`` = the rows of ``bands`` drawn.
    """
    for c in (source_col, "channel", PHASE_COL, "mean", "sd"):
        if c not in bands.columns:
            raise ValueError(f"plot_model_vs_measurement: bands lack column {c!r}")
    chans = list(dict.fromkeys(bands["channel"])) if channels is None else list(channels)
    units = dict(units or {})
    data = bands[bands["channel"].isin(chans)].reset_index(drop=True)
    sources = list(dict.fromkeys(data[source_col]))
    if measurement in sources:
        sources.remove(measurement)
        sources = [measurement] + sources
    nc = min(ncols, len(chans))
    nr = int(np.ceil(len(chans) / nc))
    fig, axes = new_figure(nr, nc, 3.8 * nc, 3.2 * nr)
    for i, ch in enumerate(chans):
        ax = axes[i // nc, i % nc]
        for k, src in enumerate(sources):
            b = data[(data["channel"] == ch) & (data[source_col] == src)]
            color = "k" if src == measurement else PALETTE[k % len(PALETTE)]
            m, sd = b["mean"].to_numpy(), b["sd"].fillna(0.0).to_numpy()
            draw_band(ax, b[PHASE_COL].to_numpy(), m, m - sd, m + sd, color=color,
                       label=str(src), ls="--" if src == measurement else "-")
        ax.set_title(ch)
        ax.set_xlabel(PHASE_LABEL)
        ax.set_ylabel(f"{ch} [{units[ch]}]" if ch in units else ch)
        ax.set_xlim(0, 100)
        ax.grid(True, alpha=0.3)
    for j in range(len(chans), nr * nc):
        axes[j // nc, j % nc].set_visible(False)
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle("Model vs measurement over the stance (mean ± sd)")
    return PlotOutput(save_figure(fig, out_path), data)


def plot_rmse_vs_speed(table: pd.DataFrame, out_path: str | Path | None = None, *,
                       model_col: str = "model", speed_col: str = "commanded_speed_mps",
                       channels: Sequence[str] | None = None,
                       units: Mapping[str, str] | None = None, ncols: int = 3) -> PlotOutput:
    """Whole-stance RMSE against commanded speed per model (paper Fig. 5), with the
    bootstrap intervals as error bars.

    Args:
        table: rows of :func:`~granular_mpc.analysis.metrics.rmse_table` (computed with
            ``phase_bins=None``) for several models, stacked with a ``model_col`` column.

    Raises:
        ValueError: if a (model, speed, channel) has more than one row (phase-binned input).
    """
    for c in (model_col, speed_col, "channel", "rmse"):
        if c not in table.columns:
            raise ValueError(f"plot_rmse_vs_speed: table lacks column {c!r}")
    chans = list(dict.fromkeys(table["channel"])) if channels is None else list(channels)
    data = table[table["channel"].isin(chans)].reset_index(drop=True)
    if data.duplicated([model_col, speed_col, "channel"]).any():
        raise ValueError("plot_rmse_vs_speed: several rows per (model, speed, channel); "
                         "use rmse_table(..., phase_bins=None)")
    units = dict(units or {})
    models = list(dict.fromkeys(data[model_col]))
    nc = min(ncols, len(chans))
    nr = int(np.ceil(len(chans) / nc))
    fig, axes = new_figure(nr, nc, 3.8 * nc, 3.2 * nr)
    markers = ("o", "s", "^", "D", "v")
    for i, ch in enumerate(chans):
        ax = axes[i // nc, i % nc]
        for k, mdl in enumerate(models):
            s = data[(data["channel"] == ch) & (data[model_col] == mdl)].sort_values(speed_col)
            y = s["rmse"].to_numpy()
            if {"ci_lo", "ci_hi"} <= set(s.columns):
                lo = np.nan_to_num(y - s["ci_lo"].to_numpy())
                hi = np.nan_to_num(s["ci_hi"].to_numpy() - y)
                yerr = np.vstack([np.maximum(lo, 0), np.maximum(hi, 0)])
            else:
                yerr = None
            ax.errorbar(s[speed_col], y, yerr=yerr, marker=markers[k % len(markers)],
                        capsize=3, color=PALETTE[k % len(PALETTE)], label=str(mdl))
        ax.set_title(ch)
        ax.set_xlabel("commanded speed [m/s]")
        ax.set_ylabel(f"RMSE [{units[ch]}]" if ch in units else "RMSE")
        ax.grid(True, alpha=0.3)
    for j in range(len(chans), nr * nc):
        axes[j // nc, j % nc].set_visible(False)
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle("One-stance RMSE against commanded speed (bars: bootstrap interval)")
    return PlotOutput(save_figure(fig, out_path), data)


def plot_residual_heatmap(table: pd.DataFrame, out_path: str | Path | None = None, *,
                          value: str = "rmse", normalise: str | None = "channel",
                          title: str | None = None) -> PlotOutput:
    """Heatmap of an error measure by channel (rows) × stance-phase bin (columns).

    Args:
        table: one row per (channel, phase bin), e.g. :func:`rmse_table` output filtered to
            one speed and one model (columns ``channel``, ``phase_lo``, ``phase_hi``,
            ``value``).
        value: the column to show (``rmse`` or ``bias``).
        normalise: ``"channel"`` colours each row by value / max |value| of that channel
            (channels have different units); None colours raw values. Cells are annotated
            with the raw values either way.

    Returns:
        :class:`PlotOutput`; ``data`` = the pivot of raw values (index channel, columns
        phase-bin start [%]).

    Raises:
        ValueError: if a (channel, bin) appears more than once (filter the other groups).
    """
    for c in ("channel", "phase_lo", "phase_hi", value):
        if c not in table.columns:
            raise ValueError(f"plot_residual_heatmap: table lacks column {c!r}")
    if table.duplicated(["channel", "phase_lo"]).any():
        raise ValueError("plot_residual_heatmap: several rows per (channel, phase bin); "
                         "filter to one speed / model first")
    order = list(dict.fromkeys(table["channel"]))
    piv = table.pivot(index="channel", columns="phase_lo", values=value).reindex(order)
    hi_edges = table.drop_duplicates("phase_lo").set_index("phase_lo")["phase_hi"]
    raw = piv.to_numpy(dtype=float)
    if normalise == "channel":
        scale = np.nanmax(np.abs(raw), axis=1, keepdims=True)
        scale[~(scale > 0)] = 1.0
        shown = raw / scale
        cbar_label = f"{value} / channel max"
    elif normalise is None:
        shown = raw
        cbar_label = value
    else:
        raise ValueError("normalise must be 'channel' or None")
    fig, axes = new_figure(1, 1, max(6.0, 0.8 * raw.shape[1] + 3), max(3.0, 0.45 * raw.shape[0] + 1.5))
    ax = axes[0, 0]
    cmap = "RdBu_r" if value == "bias" else "viridis"
    if value == "bias":
        lim = np.nanmax(np.abs(shown)) or 1.0
        im = ax.imshow(shown, aspect="auto", cmap=cmap, vmin=-lim, vmax=lim)
    else:
        im = ax.imshow(shown, aspect="auto", cmap=cmap)
    ax.set_yticks(range(len(order)), labels=order)
    ax.set_xticks(range(raw.shape[1]),
                  labels=[f"{lo:g}–{hi_edges[lo]:g}" for lo in piv.columns], rotation=45)
    for i in range(raw.shape[0]):
        for j in range(raw.shape[1]):
            if np.isfinite(raw[i, j]):
                ax.text(j, i, f"{raw[i, j]:.3g}", ha="center", va="center", fontsize=7,
                        color="w" if value != "bias" and shown[i, j] < 0.6 else "k")
    ax.set_xlabel(PHASE_LABEL)
    ax.set_ylabel("channel")
    fig.colorbar(im, ax=ax, label=cbar_label)
    ax.set_title(title or f"{value} by channel and stance phase")
    return PlotOutput(save_figure(fig, out_path), piv)


__all__ = ["plot_model_vs_measurement", "plot_rmse_vs_speed", "plot_residual_heatmap"]
