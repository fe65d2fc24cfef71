"""Paper-style figures (matplotlib, headless) from run logs, sweep tables and RMSE tables.

Every ``plot_*`` function takes tidy inputs, draws one figure, saves it as PNG when
``out_path`` is given and returns a :class:`PlotOutput` holding the path and **the data
exactly as plotted** (values in the plotted unit, named in a ``unit`` column or the
docstring), so tests and users can check or re-plot the numbers.

Figures never touch pyplot's global state: they are :class:`matplotlib.figure.Figure`
objects rendered by the Agg canvas, so nothing is ever displayed and the caller's
backend is left alone.

Figures (paper numbering, ``../shared/paper``):

* :func:`plot_joint_bands` — Fig. 4a: joint angles over the stance, swing leg q1–3 and
  stance leg q4–6 (legs relabelled by role), mean ± sd across stances.
* :func:`plot_grf_bands` — Fig. 4b: ground reaction force of the stance foot.
* :func:`plot_intrusion_bands` — Fig. 4c: intrusion x_s, y_s, z_s.
* :func:`plot_rolling_cot` — Fig. 6a–c: Δθ_r, R_eff and cumulative CoT over the stance.
* :func:`plot_trajectories` — trunk and CoM paths (side and top views), trunk roll/pitch/yaw.
* :func:`plot_cot_vs_speed` — Fig. 6d: CoT against v/√(g h_CoM) per terrain, 2nd-order
  fits, and the CoT ratio to a reference terrain.
* :func:`plot_model_vs_measurement`, :func:`plot_rmse_vs_speed` (Fig. 5),
  :func:`plot_residual_heatmap` — validation.
* :func:`make_run_plots` — the standard set for one run.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ..analysis.cot import estimate_weight_from_grf, stance_cumulative_cot
from ..analysis.metrics import (ID_COL, PHASE_COL, leg_joint_roles, phase_bands,
                                resample_by_phase, resample_stances, segment_stances)
from ..analysis.rolling import DEFAULT_MIN_RATE, rolling_from_log
from ..exceptions import OutputError

DPI = 120
_PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
            "#17becf", "#7f7f7f", "#bcbd22")
_PHASE_LABEL = "stance phase [%]"


@dataclass(frozen=True)
class PlotOutput:
    """A drawn figure: where it was saved (None if not saved) and the plotted data."""

    path: Path | None
    data: pd.DataFrame | dict


# --------------------------------------------------------------------------- helpers
def _figure(nrows: int, ncols: int, width: float, height: float):
    fig = Figure(figsize=(width, height), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def _save(fig: Figure, out_path: str | Path | None) -> Path | None:
    if out_path is None:
        return None
    path = Path(out_path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=DPI, format="png")
    except OSError as exc:
        raise OutputError(f"cannot write the figure {path}: {exc.strerror}") from None
    return path


def _draw_band(ax, x, centre, lo, hi, *, color, label, ls="-"):
    ax.plot(x, centre, color=color, lw=1.8, ls=ls, label=label)
    ax.fill_between(x, lo, hi, color=color, alpha=0.25, lw=0)


def _band_panel(ax, bands: pd.DataFrame, channel: str, *, color, label, center="mean"):
    b = bands[bands["channel"] == channel]
    x = b[PHASE_COL].to_numpy()
    if center == "mean":
        m, sd = b["mean"].to_numpy(), b["sd"].fillna(0.0).to_numpy()
        _draw_band(ax, x, m, m - sd, m + sd, color=color, label=label)
    else:
        _draw_band(ax, x, b["median"].to_numpy(), b["q25"].to_numpy(), b["q75"].to_numpy(),
                   color=color, label=label)
    ax.set_xlim(0, 100)
    ax.grid(True, alpha=0.3)


def _segments_or_raise(log: pd.DataFrame, segments: pd.DataFrame | None) -> pd.DataFrame:
    segs = segment_stances(log) if segments is None else segments
    if len(segs) == 0:
        raise ValueError("no complete stance segment in the log (see segment_stances)")
    return segs


def _n_note(segs: pd.DataFrame) -> str:
    return f"mean ± sd over {len(segs)} stances"


# --------------------------------------------------------------------------- Fig. 4
def plot_joint_bands(log: pd.DataFrame, out_path: str | Path | None = None, *,
                     segments: pd.DataFrame | None = None, n_phase: int = 101) -> PlotOutput:
    """Joint angles over the stance by leg role (paper Fig. 4a), mean ± sd across stances.

    The leg on the ground is the *stance* leg (paper q4–6), the other the *swing* leg
    (q1–3); per stance, ``q_<side>_<joint>`` columns are relabelled accordingly.

    Returns:
        :class:`PlotOutput`; ``data`` = :func:`~granular_mpc.analysis.metrics.phase_bands`
        of the role channels (``q_swing_<joint>``, ``q_stance_<joint>``) [rad], plus
        ``label`` and ``unit`` columns.
    """
    segs = _segments_or_raise(log, segments)
    swing, stance = leg_joint_roles(log.columns, "q_")
    if not swing:
        raise ValueError("the log has no q_left_<joint>/q_right_<joint> columns")
    channels = swing + stance
    res = resample_stances(log, channels, segments=segs, n_phase=n_phase)
    bands = phase_bands(res, channels)
    labels = {}
    for i, c in enumerate(swing):
        labels[c] = f"q{i + 1}: swing {c[len('q_swing_'):].replace('_', ' ')}"
    for i, c in enumerate(stance):
        labels[c] = f"q{len(swing) + i + 1}: stance {c[len('q_stance_'):].replace('_', ' ')}"
    bands["label"] = bands["channel"].map(labels)
    bands["unit"] = "rad"
    ncol = len(swing)
    fig, axes = _figure(2, ncol, 3.6 * ncol, 6.0)
    for row, (group, color) in enumerate(((swing, _PALETTE[0]), (stance, _PALETTE[1]))):
        for j, ch in enumerate(group):
            ax = axes[row, j]
            _band_panel(ax, bands, ch, color=color, label=_n_note(segs))
            ax.set_title(labels[ch])
            ax.set_ylabel("joint angle [rad]")
            ax.set_xlabel(_PHASE_LABEL)
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle("Joint angles over one stance (swing leg q1–3, stance leg q4–6)")
    path = _save(fig, out_path)
    return PlotOutput(path, bands)


def _xyz_bands(log, out_path, segments, n_phase, prefix, scale, unit, title, symbols):
    segs = _segments_or_raise(log, segments)
    channels = [f"{prefix}_{a}" for a in "xyz"]
    res = resample_stances(log, channels, segments=segs, n_phase=n_phase)
    for c in channels:
        res[c] = res[c] * scale
    # left and right stances are mirror images laterally: averaging raw y would cancel
    # them, so y is taken positive outward (left foot as is, right foot mirrored)
    res.loc[res["side"] == "right", channels[1]] *= -1.0
    bands = phase_bands(res, channels)
    bands["unit"] = unit
    fig, axes = _figure(1, 3, 11.0, 3.6)
    for j, (ch, sym) in enumerate(zip(channels, symbols)):
        ax = axes[0, j]
        _band_panel(ax, bands, ch, color=_PALETTE[j], label=_n_note(segs))
        ax.set_title(sym + (" (+ outward)" if j == 1 else ""))
        ax.set_xlabel(_PHASE_LABEL)
        ax.set_ylabel(f"{sym} [{unit}]")
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle(title)
    return PlotOutput(_save(fig, out_path), bands)


def plot_grf_bands(log: pd.DataFrame, out_path: str | Path | None = None, *,
                   segments: pd.DataFrame | None = None, n_phase: int = 101) -> PlotOutput:
    """Ground reaction force on the stance foot (paper Fig. 4b), world frame [N].

    Uses the v1 columns ``grf_x, grf_y, grf_z`` (stance foot). The lateral component is
    shown positive outward (right-foot stances mirrored), so left and right stances add up
    instead of cancelling. ``data``: bands in N.
    """
    return _xyz_bands(log, out_path, segments, n_phase, "grf", 1.0, "N",
                      "Ground reaction force on the stance foot (world frame)",
                      ("F_x", "F_y", "F_z"))


def plot_intrusion_bands(log: pd.DataFrame, out_path: str | Path | None = None, *,
                         segments: pd.DataFrame | None = None, n_phase: int = 101) -> PlotOutput:
    """Stance-foot intrusion x_s, y_s, z_s (paper Fig. 4c), plotted in mm.

    Uses the v1 columns ``intrusion_x/y/z`` (contact point relative to touchdown, z_s
    positive deeper); y_s positive outward (right-foot stances mirrored). ``data``: bands
    in **mm** (log values × 1000).
    """
    return _xyz_bands(log, out_path, segments, n_phase, "intrusion", 1000.0, "mm",
                      "Stance-foot intrusion from touchdown (z_s positive deeper)",
                      ("x_s", "y_s", "z_s"))


# --------------------------------------------------------------------------- Fig. 6a–c
def plot_rolling_cot(log: pd.DataFrame, out_path: str | Path | None = None, *,
                     weight: float | None = None, biped=None,
                     segments: pd.DataFrame | None = None, n_phase: int = 101,
                     min_rate: float = DEFAULT_MIN_RATE, cot_mode: str = "abs",
                     cot_normalise: str = "running") -> PlotOutput:
    """Rolling angle Δθ_r, effective rolling radius and cumulative CoT over the stance
    (paper Fig. 6a–c).

    Δθ_r [deg] and the cumulative CoT [-] are drawn as mean ± sd across stances; R_eff [m]
    is heavy-tailed where θ̇_r is small (NaN below ``min_rate``), so it is drawn as median
    and inter-quartile range. W_r: ``weight`` [N], else ``biped.weight``, else estimated
    from the log's vertical impulse balance
    (:func:`~granular_mpc.analysis.cot.estimate_weight_from_grf`, stated in the figure).

    Returns:
        :class:`PlotOutput`; ``data`` = bands of channels ``dtheta_r`` [deg], ``r_eff`` [m],
        ``cot_cum`` [-] with a ``unit`` column; ``data.attrs["weight_N"]`` and
        ``data.attrs["weight_source"]`` record W_r.
    """
    segs = _segments_or_raise(log, segments)
    if weight is not None:
        w, w_src = float(weight), "given"
    elif biped is not None:
        w, w_src = float(biped.weight), "robot model"
    else:
        w, w_src = estimate_weight_from_grf(log), "estimated from ∫ΣF_z dt"
    roll = rolling_from_log(log, segments=segs, min_rate=min_rate)
    roll["dtheta_r"] = np.degrees(roll["dtheta_r"])
    cot = stance_cumulative_cot(log, weight=w, biped=biped, segments=segs, mode=cot_mode,
                                normalise=cot_normalise)
    # both frames hold the rows of the same segments in the same order
    if not np.array_equal(roll["time"].to_numpy(), cot["time"].to_numpy()):
        raise RuntimeError("rolling and CoT frames are not row-aligned")
    merged = roll[[ID_COL, PHASE_COL, "dtheta_r", "r_eff"]].copy()
    merged["cot_cum"] = cot["cot_cum"].to_numpy()
    res = resample_by_phase(merged, ["dtheta_r", "r_eff", "cot_cum"], n_phase=n_phase)
    bands = phase_bands(res, ["dtheta_r", "r_eff", "cot_cum"])
    bands["unit"] = bands["channel"].map({"dtheta_r": "deg", "r_eff": "m", "cot_cum": "-"})
    bands.attrs.update(weight_N=w, weight_source=w_src)

    fig, axes = _figure(1, 3, 12.0, 3.8)
    ax = axes[0, 0]
    _band_panel(ax, bands, "dtheta_r", color=_PALETTE[0], label=_n_note(segs))
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_title("(a) rolling angle Δθ_r")
    ax.set_ylabel("Δθ_r [deg] (negative: decreasing)")
    ax = axes[0, 1]
    _band_panel(ax, bands, "r_eff", color=_PALETTE[2], center="median",
                label=f"median, IQR (NaN where |θ̇_r| < {min_rate:g} rad/s)")
    ax.set_title("(b) effective rolling radius")
    ax.set_ylabel("R_eff [m]")
    ax = axes[0, 2]
    _band_panel(ax, bands, "cot_cum", color=_PALETTE[1], label=_n_note(segs))
    ax.set_title(f"(c) cumulative CoT ({cot_normalise}, {cot_mode} power)")
    ax.set_ylabel("CoT [-]")
    ax.text(0.02, 0.97, f"W_r = {w:.1f} N ({w_src})", transform=ax.transAxes, va="top",
            fontsize=8)
    for a in axes[0]:
        a.set_xlabel(_PHASE_LABEL)
        a.legend(loc="lower left", fontsize=7)
    fig.suptitle("Foot rolling and cost of transport over one stance")
    return PlotOutput(_save(fig, out_path), bands)


# --------------------------------------------------------------------------- trajectories
def trunk_rpy(log: pd.DataFrame) -> np.ndarray:
    """Trunk roll, pitch, yaw [rad] per row, R_W_B = Rz(yaw) Ry(pitch) Rx(roll).

    From the columns ``base_qw, base_qx, base_qy, base_qz``; shape (n, 3).
    """
    from scipy.spatial.transform import Rotation

    quat = log[["base_qx", "base_qy", "base_qz", "base_qw"]].to_numpy(dtype=float)
    ypr = Rotation.from_quat(quat).as_euler("ZYX")
    return ypr[:, ::-1].copy()


def plot_trajectories(log: pd.DataFrame, out_path: str | Path | None = None) -> PlotOutput:
    """Trunk and CoM paths: side view (x–z), top view (x–y), trunk roll/pitch/yaw and
    forward CoM speed against time.

    Returns:
        :class:`PlotOutput`; ``data``: ``time`` [s], ``base_x/y/z``, ``com_x/y/z`` [m],
        ``roll, pitch, yaw`` [deg], ``com_vx`` [m/s] — as plotted.
    """
    rpy = np.degrees(trunk_rpy(log))
    cols = ["time", "base_x", "base_y", "base_z", "com_x", "com_y", "com_z", "com_vx"]
    data = log[cols].astype(float).reset_index(drop=True)
    data["roll"], data["pitch"], data["yaw"] = rpy[:, 0], rpy[:, 1], rpy[:, 2]
    fig, axes = _figure(2, 2, 11.0, 7.0)
    ax = axes[0, 0]
    ax.plot(data.base_x, data.base_z, color=_PALETTE[0], label="trunk")
    ax.plot(data.com_x, data.com_z, color=_PALETTE[1], label="CoM")
    ax.set_title("side view")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax = axes[0, 1]
    ax.plot(data.base_x, data.base_y, color=_PALETTE[0], label="trunk")
    ax.plot(data.com_x, data.com_y, color=_PALETTE[1], label="CoM")
    for k, side in enumerate(("left", "right")):
        cx, cy, cc = f"{side}_px", f"{side}_py", f"{side}_contact"
        if {cx, cy, cc} <= set(log.columns):
            c = log[cc].to_numpy(dtype=float) > 0.5
            td = np.flatnonzero(c & ~np.concatenate(([False], c[:-1])))
            ax.plot(log[cx].to_numpy()[td], log[cy].to_numpy()[td], ls="none",
                    marker="s" if k == 0 else "o", ms=4, color=_PALETTE[2 + k],
                    label=f"{side} touchdowns")
    ax.set_title("top view")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax = axes[1, 0]
    for k, name in enumerate(("roll", "pitch", "yaw")):
        ax.plot(data.time, data[name], color=_PALETTE[k], label=name)
    ax.set_title("trunk orientation (Z-Y-X Euler)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("angle [deg]")
    ax = axes[1, 1]
    ax.plot(data.time, data.com_vx, color=_PALETTE[1], label="v_CoM,x")
    ax.set_title("forward CoM velocity")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("velocity [m/s]")
    for a in axes.ravel():
        a.grid(True, alpha=0.3)
        a.legend(loc="best", fontsize=8)
    fig.suptitle("Trunk and centre-of-mass trajectories")
    return PlotOutput(_save(fig, out_path), data)


# --------------------------------------------------------------------------- Fig. 6d
def _series_label(terrain: str, ctrl: str, multi_ctrl: bool) -> str:
    return f"{terrain} (controller: {ctrl})" if multi_ctrl else str(terrain)


def plot_cot_vs_speed(sweep: pd.DataFrame, out_path: str | Path | None = None, *,
                      h_com: float | None = None, g: float = 9.81,
                      speed_col: str = "mean_speed_mps", reference_terrain: str = "rigid",
                      fit_order: int = 2) -> PlotOutput:
    """CoT against dimensionless speed v/√(g h_CoM) per terrain (paper Fig. 6d).

    Points are mean ± sd of ``cot`` over the rows sharing (terrain, controller terrain
    model, commanded speed); x is the mean of ``speed_col`` [m/s] over those rows divided
    by √(g h_CoM). Each series gets a least-squares polynomial of order ``fit_order`` in x
    (when it has more distinct speeds than the order). The ratio panel divides each
    terrain's mean CoT by the reference terrain's at the same commanded speed, paired with
    the reference rows of the same controller terrain model when present, else with all
    reference rows.

    Args:
        sweep: table with ``terrain``, ``controller_terrain_model``,
            ``commanded_speed_mps``, ``speed_col`` and ``cot`` (and ``h_com`` [m] unless
            ``h_com`` is given).
        h_com: CoM height [m] used for every row (overrides the column).
        g: gravity [m/s²].

    Returns:
        :class:`PlotOutput`; ``data`` = {"points": DataFrame, "fits": DataFrame
        (series, coefficients highest power first, x range), "ratio": DataFrame}.
    """
    need = ["terrain", "controller_terrain_model", "commanded_speed_mps", speed_col, "cot"]
    missing = [c for c in need if c not in sweep.columns]
    if missing:
        raise ValueError(f"plot_cot_vs_speed: sweep table lacks {missing}")
    df = sweep.copy()
    if h_com is not None:
        df["h_com"] = float(h_com)
    elif "h_com" not in df.columns:
        raise ValueError("plot_cot_vs_speed: give h_com [m] or an h_com column")
    if not (df["h_com"].astype(float) > 0).all():
        raise ValueError("plot_cot_vs_speed: h_com must be positive")
    df["v_dimless"] = df[speed_col].astype(float) / np.sqrt(g * df["h_com"].astype(float))
    keys = ["terrain", "controller_terrain_model", "commanded_speed_mps"]
    agg = df.groupby(keys, sort=True).agg(v_dimless=("v_dimless", "mean"),
                                          cot_mean=("cot", "mean"), cot_sd=("cot", "std"),
                                          n=("cot", "count")).reset_index()
    multi_ctrl = agg.groupby("terrain")["controller_terrain_model"].nunique().max() > 1
    agg["series"] = [_series_label(t, c, multi_ctrl) for t, c in
                     zip(agg["terrain"], agg["controller_terrain_model"])]

    fits = []
    ratio_rows = []
    ref = agg[agg["terrain"] == reference_terrain]
    fig, axes = _figure(1, 2, 11.0, 4.2)
    ax = axes[0, 0]
    for k, (name, s) in enumerate(agg.groupby("series", sort=True)):
        color = _PALETTE[k % len(_PALETTE)]
        ax.errorbar(s["v_dimless"], s["cot_mean"], yerr=s["cot_sd"].fillna(0.0), ls="none",
                    marker="o", capsize=3, color=color, label=name)
        ok = np.isfinite(s["v_dimless"]) & np.isfinite(s["cot_mean"])
        if ok.sum() > fit_order:
            coef = np.polyfit(s["v_dimless"][ok], s["cot_mean"][ok], fit_order)
            xs = np.linspace(s["v_dimless"][ok].min(), s["v_dimless"][ok].max(), 100)
            ax.plot(xs, np.polyval(coef, xs), color=color, lw=1.5)
            fits.append({"series": name, "coefficients": tuple(float(c) for c in coef),
                         "x_min": float(xs[0]), "x_max": float(xs[-1])})
        terrain, ctrl = s["terrain"].iloc[0], s["controller_terrain_model"].iloc[0]
        if terrain == reference_terrain or ref.empty:
            continue
        r_same = ref[ref["controller_terrain_model"] == ctrl]
        r_use = r_same if not r_same.empty else ref
        r_mean = r_use.groupby("commanded_speed_mps")["cot_mean"].mean()
        for v, c in zip(s["commanded_speed_mps"], s["cot_mean"]):
            if v in r_mean.index:
                ratio_rows.append((name, terrain, ctrl, v, c / r_mean[v]))
    ax.set_xlabel("dimensionless speed v/√(g h_CoM) [-]")
    ax.set_ylabel("CoT [-]")
    ax.set_title(f"CoT vs speed (order-{fit_order} polynomial fits)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ratio = pd.DataFrame(ratio_rows, columns=["series", "terrain", "controller_terrain_model",
                                              "commanded_speed_mps", "cot_ratio"])
    ax = axes[0, 1]
    if ratio.empty:
        ax.text(0.5, 0.5, f"no '{reference_terrain}' rows to compare with", ha="center",
                va="center", transform=ax.transAxes)
    for k, (name, s) in enumerate(ratio.groupby("series", sort=True)):
        ax.plot(s["commanded_speed_mps"], s["cot_ratio"], marker="o",
                color=_PALETTE[(k + 1) % len(_PALETTE)], label=name)
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set_xlabel("commanded speed [m/s]")
    ax.set_ylabel(f"CoT / CoT_{reference_terrain} [-]")
    ax.set_title(f"CoT ratio to {reference_terrain} ground")
    ax.grid(True, alpha=0.3)
    if not ratio.empty:
        ax.legend(loc="best", fontsize=8)
    fig.suptitle("Cost of transport against speed")
    fits_df = pd.DataFrame(fits, columns=["series", "coefficients", "x_min", "x_max"])
    return PlotOutput(_save(fig, out_path), {"points": agg, "fits": fits_df, "ratio": ratio})


# --------------------------------------------------------------------------- validation
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
    fig, axes = _figure(nr, nc, 3.8 * nc, 3.2 * nr)
    for i, ch in enumerate(chans):
        ax = axes[i // nc, i % nc]
        for k, src in enumerate(sources):
            b = data[(data["channel"] == ch) & (data[source_col] == src)]
            color = "k" if src == measurement else _PALETTE[k % len(_PALETTE)]
            m, sd = b["mean"].to_numpy(), b["sd"].fillna(0.0).to_numpy()
            _draw_band(ax, b[PHASE_COL].to_numpy(), m, m - sd, m + sd, color=color,
                       label=str(src), ls="--" if src == measurement else "-")
        ax.set_title(ch)
        ax.set_xlabel(_PHASE_LABEL)
        ax.set_ylabel(f"{ch} [{units[ch]}]" if ch in units else ch)
        ax.set_xlim(0, 100)
        ax.grid(True, alpha=0.3)
    for j in range(len(chans), nr * nc):
        axes[j // nc, j % nc].set_visible(False)
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle("Model vs measurement over the stance (mean ± sd)")
    return PlotOutput(_save(fig, out_path), data)


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
    fig, axes = _figure(nr, nc, 3.8 * nc, 3.2 * nr)
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
                        capsize=3, color=_PALETTE[k % len(_PALETTE)], label=str(mdl))
        ax.set_title(ch)
        ax.set_xlabel("commanded speed [m/s]")
        ax.set_ylabel(f"RMSE [{units[ch]}]" if ch in units else "RMSE")
        ax.grid(True, alpha=0.3)
    for j in range(len(chans), nr * nc):
        axes[j // nc, j % nc].set_visible(False)
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle("One-stance RMSE against commanded speed (bars: bootstrap interval)")
    return PlotOutput(_save(fig, out_path), data)


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
    fig, axes = _figure(1, 1, max(6.0, 0.8 * raw.shape[1] + 3), max(3.0, 0.45 * raw.shape[0] + 1.5))
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
    ax.set_xlabel(_PHASE_LABEL)
    ax.set_ylabel("channel")
    fig.colorbar(im, ax=ax, label=cbar_label)
    ax.set_title(title or f"{value} by channel and stance phase")
    return PlotOutput(_save(fig, out_path), piv)


# --------------------------------------------------------------------------- run set
def _placeholder(out_path: Path, title: str, message: str) -> Path:
    fig, axes = _figure(1, 1, 6.0, 3.0)
    ax = axes[0, 0]
    ax.axis("off")
    ax.text(0.5, 0.5, message, ha="center", va="center", wrap=True, transform=ax.transAxes)
    fig.suptitle(title)
    return _save(fig, out_path)


def make_run_plots(log_df: pd.DataFrame, out_dir: str | Path, biped=None, *,
                   weight: float | None = None) -> list[Path]:
    """Write the standard figures of one run into ``out_dir``; return their paths.

    Files: ``joints.png`` (Fig. 4a), ``grf.png`` (4b), ``intrusion.png`` (4c),
    ``rolling_cot.png`` (6a–c), ``trajectories.png``. If the log holds no complete stance
    (e.g. the robot fell at once) the four stance figures say so instead of plotting.

    Args:
        log_df: run log DataFrame (:func:`granular_mpc.runlog.read_log`).
        out_dir: output folder (created).
        biped: robot model, for W_r in the CoT; without it (and ``weight`` [N]) W_r is
            estimated from the log (stated in the figure).
    """
    out = Path(out_dir)
    segs = segment_stances(log_df)
    paths = []
    stance_figs = (("joints.png", "Joint angles", lambda p: plot_joint_bands(log_df, p, segments=segs)),
                   ("grf.png", "Ground reaction force", lambda p: plot_grf_bands(log_df, p, segments=segs)),
                   ("intrusion.png", "Intrusion", lambda p: plot_intrusion_bands(log_df, p, segments=segs)),
                   ("rolling_cot.png", "Rolling and CoT",
                    lambda p: plot_rolling_cot(log_df, p, weight=weight, biped=biped, segments=segs)))
    for name, title, fn in stance_figs:
        if len(segs) == 0:
            paths.append(_placeholder(out / name, title,
                                      "no complete stance in this log: nothing to average"))
        else:
            paths.append(fn(out / name).path)
    paths.append(plot_trajectories(log_df, out / "trajectories.png").path)
    return paths


__all__ = [
    "PlotOutput", "plot_joint_bands", "plot_grf_bands", "plot_intrusion_bands",
    "plot_rolling_cot", "trunk_rpy", "plot_trajectories", "plot_cot_vs_speed",
    "plot_model_vs_measurement", "plot_rmse_vs_speed", "plot_residual_heatmap",
    "make_run_plots",
]
