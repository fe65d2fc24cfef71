"""Paper-style plots: files are real PNGs and the plotted numbers are the right ones."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from matplotlib.image import imread

from granular_mpc.analysis import phase_bands, phase_grid, resample_by_phase, rmse_table
from granular_mpc.viz import (make_run_plots, plot_cot_vs_speed, plot_grf_bands,
                              plot_intrusion_bands, plot_joint_bands, plot_model_vs_measurement,
                              plot_residual_heatmap, plot_rmse_vs_speed, plot_rolling_cot,
                              plot_trajectories, trunk_rpy)
from granular_mpc.columns import BASE_QUATERNION
from granular_mpc.rotations import matrix_from_quat_wxyz, rot_x, rot_y, rot_z
from synthetic_log import MASS, G, interp_segment, make_log

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


#: Smallest PNG a drawn figure may be [bytes]. A PNG's size measures how much is drawn: a
#: blank Agg canvas of 800×600 to 1200×900 px compresses to 3.3–6.5 kB, the same canvas
#: with one empty set of axes to 9.2–12.5 kB (measured once, on figures that are not the
#: ones tested); the run plots measure 72–175 kB. 30 kB is 2.4× above an empty-axes figure
#: and 2.4× below the smallest run plot.
MIN_PNG_BYTES = 30_000
#: Grey-level spread (0–1) of a drawn figure: 0 for a blank canvas, 0.06–0.075 for empty
#: axes, 0.145–0.17 for the run plots (same measurement). 0.01 only rules out a blank one.
MIN_PNG_STD = 0.01


def _assert_png(path, min_bytes=MIN_PNG_BYTES):
    assert path.is_file()
    with open(path, "rb") as fh:
        assert fh.read(8) == PNG_MAGIC
    assert path.stat().st_size > min_bytes, path.stat().st_size
    img = imread(path)
    # the smallest figure size the plots use (figsize × dpi): ≥ 300 × 500 px
    assert img.ndim == 3 and img.shape[0] >= 300 and img.shape[1] >= 500
    assert img[..., :3].std() > MIN_PNG_STD          # not a blank canvas


@pytest.fixture(scope="module")
def synth():
    return make_log(6)


def _stack(L, column_of_side, grid, scale=1.0, mirror_right=False):
    """Stance-resampled signals; ``mirror_right`` flips right-foot stances (lateral axes
    are plotted positive outward)."""
    return np.vstack([scale * (-1.0 if mirror_right and s == "right" else 1.0)
                      * interp_segment(L.df, column_of_side(s), a, b, grid)
                      for s, a, b in L.segments])


def test_make_run_plots_writes_the_standard_set(synth, tmp_path):
    paths = make_run_plots(synth.df, tmp_path / "plots")
    assert len(paths) >= 4
    assert {p.name for p in paths} == {"joints.png", "grf.png", "intrusion.png",
                                       "rolling_cot.png", "trajectories.png"}
    for p in paths:
        _assert_png(p)


def test_make_run_plots_without_any_stance(tmp_path):
    df = make_log(3).df.copy()
    df["stance"] = "none"
    paths = make_run_plots(df, tmp_path)
    assert len(paths) == 5
    for p in paths:
        _assert_png(p, min_bytes=2_000)      # a file is written even with nothing to band


def test_joint_bands_equal_numpy(synth, tmp_path):
    out = plot_joint_bands(synth.df, tmp_path / "j.png")
    _assert_png(out.path)
    grid = phase_grid(101)
    other = {"left": "right", "right": "left"}
    for name in ("hip_abd", "hip_pitch", "knee"):
        st = np.vstack([interp_segment(synth.df, f"q_{s}_{name}", a, b, grid)
                        for s, a, b in synth.segments])
        sw = np.vstack([interp_segment(synth.df, f"q_{other[s]}_{name}", a, b, grid)
                        for s, a, b in synth.segments])
        bst = out.data[out.data.channel == f"q_stance_{name}"]
        bsw = out.data[out.data.channel == f"q_swing_{name}"]
        assert np.allclose(bst["mean"], st.mean(0)) and np.allclose(bst["sd"], st.std(0, ddof=1))
        assert np.allclose(bsw["mean"], sw.mean(0)) and np.allclose(bsw["sd"], sw.std(0, ddof=1))
    assert set(out.data.label.str[:2]) == {"q1", "q2", "q3", "q4", "q5", "q6"}
    assert (out.data.label[out.data.channel == "q_swing_hip_abd"] == "q1: swing hip abd").all()


def test_grf_and_intrusion_bands_equal_numpy(synth, tmp_path):
    grid = phase_grid(101)
    grf = plot_grf_bands(synth.df, tmp_path / "g.png")
    intr = plot_intrusion_bands(synth.df, tmp_path / "i.png")
    _assert_png(grf.path)
    _assert_png(intr.path)
    for ax in "xyz":
        lat = ax == "y"
        f = _stack(synth, lambda s: f"{s}_grf_{ax}", grid, mirror_right=lat)
        b = grf.data[grf.data.channel == f"grf_{ax}"]
        assert np.allclose(b["mean"], f.mean(0)) and np.allclose(b["sd"], f.std(0, ddof=1))
        z = _stack(synth, lambda s: f"{s}_intrusion_{ax}", grid, scale=1000.0, mirror_right=lat)
        b = intr.data[intr.data.channel == f"intrusion_{ax}"]
        assert np.allclose(b["mean"], z.mean(0)) and np.allclose(b["sd"], z.std(0, ddof=1))
    assert (intr.data.unit == "mm").all() and (grf.data.unit == "N").all()


def test_rolling_cot_bands_equal_numpy(synth, tmp_path):
    w = MASS * G
    out = plot_rolling_cot(synth.df, tmp_path / "r.png", weight=w)
    _assert_png(out.path)
    grid = phase_grid(101)
    d = _stack(synth, lambda s: f"{s}_pitch", grid)
    d = np.degrees(d - d[:, :1])
    b = out.data[out.data.channel == "dtheta_r"]
    assert np.allclose(b["mean"], d.mean(0)) and np.allclose(b["sd"], d.std(0, ddof=1))
    # independent cumulative CoT end value per stance: E/(W d) over the stance, E under the
    # default reading Σ_i |τ_i q̇_i| (docs/analysis.md §1)
    ends = []
    joints = [c[4:] for c in synth.df.columns if c.startswith("tau_")]
    for s, a, bb in synth.segments:
        part = synth.df.iloc[a:bb]
        p = sum(np.abs(part[f"tau_{j}"] * part[f"dq_{j}"]) for j in joints).to_numpy()
        t = part.time.to_numpy()
        e = np.sum(0.5 * (p[1:] + p[:-1]) * np.diff(t))
        dist = np.sum(0.5 * (part.com_vx.to_numpy()[1:] + part.com_vx.to_numpy()[:-1]) * np.diff(t))
        ends.append(e / (w * dist))
    c = out.data[out.data.channel == "cot_cum"]
    assert c["mean"].iloc[-1] == pytest.approx(np.mean(ends))
    assert c["sd"].iloc[-1] == pytest.approx(np.std(ends, ddof=1))
    assert out.data.attrs["weight_source"] == "given"
    # without a weight, W_r comes from the impulse balance and is stated
    est = plot_rolling_cot(synth.df, None, n_phase=21)
    assert est.path is None
    assert est.data.attrs["weight_N"] == pytest.approx(w, rel=1e-9)


def test_trajectories_report_the_true_trunk_angles(synth, tmp_path):
    out = plot_trajectories(synth.df, tmp_path / "t.png")
    _assert_png(out.path)
    true = np.degrees(synth.roll)
    assert np.allclose(out.data[["roll", "pitch", "yaw"]].to_numpy(), true, atol=1e-9)
    assert np.allclose(out.data.com_x, synth.df.com_x)


def test_trunk_rpy_rebuilds_the_rotation_and_ignores_quaternion_scale():
    rng = np.random.default_rng(3)
    quat = rng.normal(size=(200, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    rpy = trunk_rpy(pd.DataFrame(quat, columns=list(BASE_QUATERNION)))
    assert rpy.shape == (200, 3)
    for (roll, pitch, yaw), q in zip(rpy, quat):       # R_W_B = Rz(yaw) Ry(pitch) Rx(roll)
        assert np.allclose(rot_z(yaw) @ rot_y(pitch) @ rot_x(roll), matrix_from_quat_wxyz(q),
                           atol=1e-12)
    assert np.all(np.abs(rpy[:, 1]) <= np.pi / 2)
    scaled = quat * rng.uniform(0.5, 2.0, size=(200, 1)) * np.sign(rng.normal(size=(200, 1)))
    assert np.allclose(trunk_rpy(pd.DataFrame(scaled, columns=list(BASE_QUATERNION))), rpy,
                       atol=1e-12)


def test_cot_vs_speed_fits_and_ratio(tmp_path):
    h = 0.41
    rows = []
    for terrain, coef in (("rigid", (20.0, -8.0, 2.0)), ("dry_sand", (30.0, -10.0, 3.0))):
        for v in (0.1, 0.2, 0.3, 0.4, 0.5):
            x = v / np.sqrt(9.81 * h)
            for rep in range(3):
                noise = (-0.01, 0.0, 0.01)[rep]          # zero-mean: means are exact
                rows.append(dict(terrain=terrain, controller_terrain_model="rigid",
                                 commanded_speed_mps=v, mean_speed_mps=v,
                                 cot=np.polyval(coef, x) + noise, seed=rep))  # extra column
    sweep = pd.DataFrame(rows)
    out = plot_cot_vs_speed(sweep, tmp_path / "c.png", h_com=h)
    _assert_png(out.path)
    fits = out.data["fits"].set_index("series")
    assert np.allclose(fits.loc["rigid", "coefficients"], (20.0, -8.0, 2.0), atol=1e-8)
    assert np.allclose(fits.loc["dry_sand", "coefficients"], (30.0, -10.0, 3.0), atol=1e-8)
    ratio = out.data["ratio"].set_index("commanded_speed_mps")["cot_ratio"]
    for v in (0.1, 0.3, 0.5):
        x = v / np.sqrt(9.81 * h)
        assert ratio[v] == pytest.approx(np.polyval((30, -10, 3), x) / np.polyval((20, -8, 2), x))
    pts = out.data["points"]
    assert np.allclose(pts.cot_sd, 0.01) and (pts.n == 3).all()
    with pytest.raises(ValueError, match="h_com"):
        plot_cot_vs_speed(sweep, None)
    # per-row h_com column is used when no h_com argument is given
    alt = plot_cot_vs_speed(sweep.assign(h_com=h), None)
    assert np.allclose(alt.data["points"].v_dimless, pts.v_dimless)


def _validation_tables():
    L = make_log(6)
    df = L.df
    meas_rows, pred_rows = [], []
    for k, (side, a, b) in enumerate(L.segments):
        part = df.iloc[a:b]
        t = part.time.to_numpy()
        ph = 100 * (t - t[0]) / (t[-1] - t[0])
        base = pd.DataFrame({"trial": k, "commanded_speed_mps": 0.1 + 0.1 * (k % 3),
                             "stance_id": k, "phase_pct": ph, "grf_z": part.grf_z.to_numpy(),
                             "intrusion_z": part.intrusion_z.to_numpy()})
        meas_rows.append(base)
        pred_rows.append(base.assign(grf_z=base.grf_z + 5.0, intrusion_z=base.intrusion_z - 0.002))
    return pd.concat(meas_rows, ignore_index=True), pd.concat(pred_rows, ignore_index=True)


def test_validation_figures(tmp_path):
    meas, pred = _validation_tables()
    chans = ["grf_z", "intrusion_z"]
    src = []
    for name, frame in (("measurement", meas), ("granular", pred)):
        r = resample_by_phase(frame, chans, n_phase=51)
        src.append(phase_bands(r, chans).assign(source=name))
    bands = pd.concat(src, ignore_index=True)
    out = plot_model_vs_measurement(bands, tmp_path / "mv.png", units={"grf_z": "N", "intrusion_z": "m"})
    _assert_png(out.path)
    m = out.data[(out.data.source == "granular") & (out.data.channel == "grf_z")]["mean"].to_numpy()
    r = out.data[(out.data.source == "measurement") & (out.data.channel == "grf_z")]["mean"].to_numpy()
    assert np.allclose(m - r, 5.0)

    whole = []
    for model, shift in (("granular", 1.0), ("rigid", 3.0)):
        p = meas.assign(grf_z=meas.grf_z + shift * 5.0, intrusion_z=meas.intrusion_z + shift * 1e-3)
        whole.append(rmse_table(p, meas, chans, phase_bins=None, n_boot=100).assign(model=model))
    table = pd.concat(whole, ignore_index=True)
    out = plot_rmse_vs_speed(table, tmp_path / "rmse.png", units={"grf_z": "N"})
    _assert_png(out.path)
    g = out.data[(out.data.model == "rigid") & (out.data.channel == "grf_z")]
    assert np.allclose(g.rmse, 15.0) and len(g) == 3
    binned = rmse_table(pred, meas, chans, phase_bins=4, n_boot=50).assign(model="granular")
    with pytest.raises(ValueError, match="phase_bins=None"):
        plot_rmse_vs_speed(binned)

    one = rmse_table(pred, meas, chans, phase_bins=4, group_cols=(), n_boot=50)
    out = plot_residual_heatmap(one, tmp_path / "heat.png")
    _assert_png(out.path, min_bytes=5_000)    # a 2 × 4 heatmap: above a blank canvas (3.3 kB)
    assert out.data.shape == (2, 4)
    assert np.allclose(out.data.loc["grf_z"], 5.0)
    assert np.allclose(out.data.loc["intrusion_z"], 0.002)
    bias = plot_residual_heatmap(one, None, value="bias", normalise=None)
    assert np.allclose(bias.data.loc["intrusion_z"], -0.002)
    with pytest.raises(ValueError, match="filter"):
        plot_residual_heatmap(binned)
