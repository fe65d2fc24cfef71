"""Paper-style figures (matplotlib, headless) from run logs, sweep tables and RMSE tables.

Every ``plot_*`` function takes tidy inputs, draws one figure, saves it as PNG when
``out_path`` is given and returns a :class:`PlotOutput` holding the path and **the data
exactly as plotted** (values in the plotted unit, named in a ``unit`` column or the
docstring), so tests and users can check or re-plot the numbers.

Figures never touch pyplot's global state (:mod:`.figures`): nothing is ever displayed
and the caller's backend is left alone.

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
  :func:`plot_residual_heatmap` — validation; defined in :mod:`.validation_plots`,
  re-exported here.
* :func:`make_run_plots` — the standard set for one run.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis.attitude import trunk_rpy
from ..analysis.cot import (DEFAULT_COT_READING, estimate_weight_from_grf, reading_mode,
                            stance_cumulative_cot)
from ..analysis.metrics import (ID_COL, PHASE_COL, leg_joint_roles, phase_bands,
                                resample_by_phase, resample_stances, contact_segments)
from ..analysis.rolling import DEFAULT_MIN_RATE, rolling_from_log
from ..columns import (BASE_POSITION, COM_POSITION, COM_VELOCITY,
                       FOOT_CONTACT, FOOT_POINT, FOOT_SIDES, TIME, foot_column)
from .figures import DPI, PALETTE, PHASE_LABEL, PlotOutput, draw_band, new_figure, save_figure
from .validation_plots import (plot_model_vs_measurement, plot_residual_heatmap,
                               plot_rmse_vs_speed)


# --------------------------------------------------------------------------- helpers
def _band_panel(ax, bands: pd.DataFrame, channel: str, *, color, label, center="mean"):
    b = bands[bands["channel"] == channel]
    x = b[PHASE_COL].to_numpy()
    if center == "mean":
        m, sd = b["mean"].to_numpy(), b["sd"].fillna(0.0).to_numpy()
        draw_band(ax, x, m, m - sd, m + sd, color=color, label=label)
    else:
        draw_band(ax, x, b["median"].to_numpy(), b["q25"].to_numpy(), b["q75"].to_numpy(),
                   color=color, label=label)
    ax.set_xlim(0, 100)
    ax.grid(True, alpha=0.3)


def _segments_or_raise(log: pd.DataFrame, segments: pd.DataFrame | None) -> pd.DataFrame:
    segs = contact_segments(log) if segments is None else segments
    if len(segs) == 0:
        raise ValueError("no complete stance segment in the log (see granular_mpc.analysis.contact_segments)")
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
    fig, axes = new_figure(2, ncol, 3.6 * ncol, 6.0)
    for row, (group, color) in enumerate(((swing, PALETTE[0]), (stance, PALETTE[1]))):
        for j, ch in enumerate(group):
            ax = axes[row, j]
            _band_panel(ax, bands, ch, color=color, label=_n_note(segs))
            ax.set_title(labels[ch])
            ax.set_ylabel("joint angle [rad]")
            ax.set_xlabel(PHASE_LABEL)
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle("Joint angles over one stance (swing leg q1–3, stance leg q4–6)")
    path = save_figure(fig, out_path)
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
    fig, axes = new_figure(1, 3, 11.0, 3.6)
    for j, (ch, sym) in enumerate(zip(channels, symbols)):
        ax = axes[0, j]
        _band_panel(ax, bands, ch, color=PALETTE[j], label=_n_note(segs))
        ax.set_title(sym + (" (+ outward)" if j == 1 else ""))
        ax.set_xlabel(PHASE_LABEL)
        ax.set_ylabel(f"{sym} [{unit}]")
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle(title)
    return PlotOutput(save_figure(fig, out_path), bands)


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
                     min_rate: float = DEFAULT_MIN_RATE,
                     cot_mode: str = reading_mode(DEFAULT_COT_READING),
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

    fig, axes = new_figure(1, 3, 12.0, 3.8)
    ax = axes[0, 0]
    _band_panel(ax, bands, "dtheta_r", color=PALETTE[0], label=_n_note(segs))
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_title("(a) rolling angle Δθ_r")
    ax.set_ylabel("Δθ_r [deg] (negative: decreasing)")
    ax = axes[0, 1]
    _band_panel(ax, bands, "r_eff", color=PALETTE[2], center="median",
                label=f"median, IQR (NaN where |θ̇_r| < {min_rate:g} rad/s)")
    ax.set_title("(b) effective rolling radius")
    ax.set_ylabel("R_eff [m]")
    ax = axes[0, 2]
    _band_panel(ax, bands, "cot_cum", color=PALETTE[1], label=_n_note(segs))
    ax.set_title(f"(c) cumulative CoT ({cot_normalise}, {cot_mode} power)")
    ax.set_ylabel("CoT [-]")
    ax.text(0.02, 0.97, f"W_r = {w:.1f} N ({w_src})", transform=ax.transAxes, va="top",
            fontsize=8)
    for a in axes[0]:
        a.set_xlabel(PHASE_LABEL)
        a.legend(loc="lower left", fontsize=7)
    fig.suptitle("Foot rolling and cost of transport over one stance")
    return PlotOutput(save_figure(fig, out_path), bands)


# --------------------------------------------------------------------------- trajectories
def plot_trajectories(log: pd.DataFrame, out_path: str | Path | None = None) -> PlotOutput:
    """Trunk and CoM paths: side view (x–z), top view (x–y), trunk roll/pitch/yaw and
    forward CoM speed against time.

    Returns:
        :class:`PlotOutput`; ``data``: ``time`` [s], ``base_x/y/z``, ``com_x/y/z`` [m],
        ``roll, pitch, yaw`` [deg], ``com_vx`` [m/s] — as plotted.
    """
    rpy = np.degrees(trunk_rpy(log))
    bx, by, bz = BASE_POSITION
    cx, cy, cz = COM_POSITION
    cvx = COM_VELOCITY[0]
    data = log[[TIME, bx, by, bz, cx, cy, cz, cvx]].astype(float).reset_index(drop=True)
    data["roll"], data["pitch"], data["yaw"] = rpy[:, 0], rpy[:, 1], rpy[:, 2]
    fig, axes = new_figure(2, 2, 11.0, 7.0)
    ax = axes[0, 0]
    ax.plot(data[bx], data[bz], color=PALETTE[0], label="trunk")
    ax.plot(data[cx], data[cz], color=PALETTE[1], label="CoM")
    ax.set_title("side view")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax = axes[0, 1]
    ax.plot(data[bx], data[by], color=PALETTE[0], label="trunk")
    ax.plot(data[cx], data[cy], color=PALETTE[1], label="CoM")
    for k, side in enumerate(FOOT_SIDES):
        px, py = (foot_column(side, key) for key in FOOT_POINT[:2])
        contact = foot_column(side, FOOT_CONTACT)
        if {px, py, contact} <= set(log.columns):
            c = log[contact].to_numpy(dtype=float) > 0.5
            td = np.flatnonzero(c & ~np.concatenate(([False], c[:-1])))
            ax.plot(log[px].to_numpy()[td], log[py].to_numpy()[td], ls="none",
                    marker="s" if k == 0 else "o", ms=4, color=PALETTE[2 + k],
                    label=f"{side} touchdowns")
    ax.set_title("top view")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax = axes[1, 0]
    for k, name in enumerate(("roll", "pitch", "yaw")):
        ax.plot(data[TIME], data[name], color=PALETTE[k], label=name)
    ax.set_title("trunk orientation (Z-Y-X Euler)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("angle [deg]")
    ax = axes[1, 1]
    ax.plot(data[TIME], data[cvx], color=PALETTE[1], label="v_CoM,x")
    ax.set_title("forward CoM velocity")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("velocity [m/s]")
    for a in axes.ravel():
        a.grid(True, alpha=0.3)
        a.legend(loc="best", fontsize=8)
    fig.suptitle("Trunk and centre-of-mass trajectories")
    return PlotOutput(save_figure(fig, out_path), data)


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
    fig, axes = new_figure(1, 2, 11.0, 4.2)
    ax = axes[0, 0]
    for k, (name, s) in enumerate(agg.groupby("series", sort=True)):
        color = PALETTE[k % len(PALETTE)]
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
                color=PALETTE[(k + 1) % len(PALETTE)], label=name)
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set_xlabel("commanded speed [m/s]")
    ax.set_ylabel(f"CoT / CoT_{reference_terrain} [-]")
    ax.set_title(f"CoT ratio to {reference_terrain} ground")
    ax.grid(True, alpha=0.3)
    if not ratio.empty:
        ax.legend(loc="best", fontsize=8)
    fig.suptitle("Cost of transport against speed")
    fits_df = pd.DataFrame(fits, columns=["series", "coefficients", "x_min", "x_max"])
    return PlotOutput(save_figure(fig, out_path), {"points": agg, "fits": fits_df, "ratio": ratio})


# --------------------------------------------------------------------------- run set
def _placeholder(out_path: Path, title: str, message: str) -> Path:
    fig, axes = new_figure(1, 1, 6.0, 3.0)
    ax = axes[0, 0]
    ax.axis("off")
    ax.text(0.5, 0.5, message, ha="center", va="center", wrap=True, transform=ax.transAxes)
    fig.suptitle(title)
    return save_figure(fig, out_path)


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
    segs = contact_segments(log_df)
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
    "DPI", "PlotOutput", "plot_joint_bands", "plot_grf_bands", "plot_intrusion_bands",
    "plot_rolling_cot", "trunk_rpy", "plot_trajectories", "plot_cot_vs_speed",
    "plot_model_vs_measurement", "plot_rmse_vs_speed", "plot_residual_heatmap",
    "make_run_plots",
]
