"""Why our figures differ from the paper's: one-knob ablations of the paper sweep (issue 10).

    GRANULAR_MPC_PROXSUITE=generic python bench/paper_gaps.py [--out runs/paper_gaps]
        [--json PATH] [--cases base actuators ...] [--seconds 12] [--quick]
        [--dataset DIR/dataset] [--fx] [--replay-only] [--planar-only]

Each *knob* changes one thing of the paper comparison's sweep protocol
(``sim/paper_sweep.yaml``: rigid-ground controller, the paper's gait + 39 ms touchdown
double support, 0.2 m/s, 12 s) and is run closed loop on the terrains it concerns (dry sand
and/or rigid ground), one run at a time, through the public API (``load_scenario``
overrides, ``run_scenario``). The figures of each run are the ones the paper comparison
reports (:mod:`granular_mpc.paper.measures`, the same functions): CoT under its three
readings, the sand − rigid cumulative-CoT opening phase, the late-stance share, the Δθ_r
plateau onset and coverage. A knob run on sand only is paired with the base rigid run (and
vice versa) for the ratio and the opening.

Two knobs need no new run (*readings* of the base runs): the stance segmentation
(contact / force / planned, :func:`granular_mpc.analysis.contact_segments`) and an
electrical CoT reading (mechanical power plus the copper loss R_w (τ/(k_t N))² of the
default motor model, ``sim.actuators.motor``; no regeneration). A third reading checks the
plateau detector: its relative threshold doubled (0.1 → 0.2 of the stance's mean |θ̇_r|).

The 0.5 m/s sand run of the paper sweep falls; ``fall_*`` cases re-run it and record the
first failing signals (the thresholds of ``bench/paper_ablation.py``) and one ablation of
the cause.

With ``--dataset`` (the comparison's data set, ``DIR/dataset``) two replay ablations run
too: the rigid model's low F_z (how the stance foot is held, the impact, Newton's
balance) and the planar model's intrusion error (the frontal-plane state its terrain law
sees); with ``--fx`` the knobs of ``bench/paper_fx.py`` (the mid-stance F_x swing of the
default sand run). ``--replay-only`` runs only those and merges them into an existing
``--json``. ``--planar-only`` (with ``--dataset``) runs only the planar model's under-load
ablation of ``bench/paper_planar.py`` (reading ``planar_load``) and merges it likewise.

Writes ``OUT/runs/<case>_<terrain>/`` (run folders) and, with ``--json``, every figure as
JSON (the paper comparison's claims cite these numbers: docs/paper-experiment-notes.md §7).
``--quick`` runs two knobs for 3 s (a test of the script, not a result).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

os.environ.setdefault("GRANULAR_MPC_PROXSUITE", "generic")   # bit-reproducible runs

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from paper_ablation import failing_signals as ablation_signals  # noqa: E402
from paper_fx import main as fx_main  # noqa: E402
from paper_planar import run as planar_load_run  # noqa: E402

from granular_mpc.analysis import plateau_by_stance, rolling_from_log  # noqa: E402
from granular_mpc.columns import joint_columns  # noqa: E402
from granular_mpc.config.scenario import MotorConfig  # noqa: E402
from granular_mpc.paper.measures import (late_share, opening_phase, read_summary,  # noqa: E402
                                         run_weight, stance_curves, steady_segments)
from granular_mpc.robot.model import load_biped  # noqa: E402
from granular_mpc.runlog import read_log  # noqa: E402
from granular_mpc.runner import run_scenario  # noqa: E402
from granular_mpc.scenario import load_scenario  # noqa: E402
from granular_mpc.validation.dataformat import load_dataset  # noqa: E402
from granular_mpc.validation.prepare import stance_windows, windows_frame  # noqa: E402
from granular_mpc.validation.replay import (Variant, build_replay_model,  # noqa: E402
                                            model_terrain, replay_granular, replay_planar,
                                            replay_rigid)
from granular_mpc.validation.replay.rigid import measured_configurations  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "sim" / "paper_sweep.yaml"
SAND, RIGID = "dry_sand", "rigid"
BOTH, SAND_ONLY, RIGID_ONLY = (SAND, RIGID), (SAND,), (RIGID,)
ACTUATORS = ("sim.actuators.friction.enabled=true", "sim.actuators.motor.enabled=true")


@dataclass(frozen=True)
class Knob:
    """One ablation: one change of the paper sweep's protocol.

    Attributes:
        name: short name (table row, run folder prefix).
        what: one line on what changes.
        terrains: terrains it is run on.
        overrides: scenario overrides on top of ``sim/paper_sweep.yaml``.
        speed: commanded speed [m/s].
        rows: the comparison rows (claim keys) it tests.
    """

    name: str
    what: str
    terrains: tuple[str, ...]
    overrides: tuple[str, ...] = ()
    speed: float = 0.2
    rows: tuple[str, ...] = ()


COT_ROWS = ("cot_sand", "cot_rigid", "cot_ratio_02", "cot_ratio_range")
STANCE_ROWS = ("cost_opening", "pullout_jump", "plateau_sand", "plateau_rigid")
KNOBS: tuple[Knob, ...] = (
    Knob("base", "the paper sweep's protocol (reference)", BOTH, (), 0.2,
         COT_ROWS + STANCE_ROWS),
    Knob("actuators", "sim.actuators on: joint friction + motor model (docs/model.md §3.1)",
         BOTH, ACTUATORS, 0.2, COT_ROWS + STANCE_ROWS),
    Knob("zeta_half", "sand half as strong: ζ 1.36 → 0.68", SAND_ONLY, ("terrain.zeta=0.68",),
         0.2, COT_ROWS + STANCE_ROWS),
    Knob("zeta_double", "sand twice as strong: ζ 1.36 → 2.72", SAND_ONLY, ("terrain.zeta=2.72",),
         0.2, COT_ROWS + STANCE_ROWS),
    Knob("phi_30", "weaker solidified zone: φ_s 38° → 30°", SAND_ONLY, ("terrain.phi_s_deg=30",),
         0.2, COT_ROWS + STANCE_ROWS),
    Knob("transfer_0", "no touchdown double support (the paper's gait exactly; rigid ground "
         "only: on sand it falls, notes §1)", RIGID_ONLY, ("controller.gait.load_transfer=0",),
         0.2, COT_ROWS + ("cost_opening",)),
    Knob("transfer_78", "touchdown double support 39 → 78 ms", BOTH,
         ("controller.gait.load_transfer=0.078",), 0.2, COT_ROWS + STANCE_ROWS),
    Knob("swing_5cm", "swing apex 10 → 5 cm", BOTH, ("controller.swing.height=0.05",), 0.2,
         COT_ROWS),
    Knob("base_v01", "the reference at 0.1 m/s (the end of the ratio range furthest from "
         "the paper's)", BOTH, (), 0.1, ("cot_ratio_range",)),
    Knob("actuators_v01", "sim.actuators on, 0.1 m/s", BOTH, ACTUATORS, 0.1,
         ("cot_ratio_range",)),
    Knob("zeta_half_v01", "ζ 1.36 → 0.68, 0.1 m/s", SAND_ONLY, ("terrain.zeta=0.68",), 0.1,
         ("cot_ratio_range",)),
    Knob("base_v04", "the reference at 0.4 m/s (plateau against speed)", SAND_ONLY, (), 0.4,
         ("plateau_fades",)),
    Knob("fall_v05", "the sand run at 0.5 m/s that falls (first failing signals)", SAND_ONLY,
         (), 0.5, ("fall_05",)),
    Knob("fall_v05_noint", "0.5 m/s without the foothold's integral speed correction "
         "(controller.foothold.k_speed_integral 0.5 → 0)", SAND_ONLY,
         ("controller.foothold.k_speed_integral=0",), 0.5, ("fall_05",)),
)
QUICK_KNOBS = ("base", "actuators")

#: failing-signal thresholds (as bench/paper_ablation.py)


@dataclass(frozen=True)
class RunFigures:
    """The comparison's figures of one run.

    Attributes:
        knob, terrain, speed: which run.
        run_dir: its folder.
        fell, fall_time_s, fall_reason: from ``summary.json``.
        cot, cot_abs_net, cot_positive: the three CoT readings (NaN if it fell).
        cot_electrical: mechanical + copper loss of the default motor, no regeneration.
        mean_speed_mps, sinkage_mm, slip_mm: from ``summary.json``.
        n_stances: steady contact stances.
        plateau_onset_pct, plateau_share, plateau_fraction: Δθ_r plateaus (contact stances).
        late_share: share of the stance cost in its last 10 %.
        first_signals: first failing signals ``(name, t [s])``, earliest first.
        wall_s: wall time of the run [s].
    """

    knob: str
    terrain: str
    speed: float
    run_dir: str
    fell: bool
    fall_time_s: float
    fall_reason: str
    cot: float
    cot_abs_net: float
    cot_positive: float
    cot_electrical: float
    mean_speed_mps: float
    sinkage_mm: float
    slip_mm: float
    n_stances: int
    plateau_onset_pct: float
    plateau_share: float
    plateau_fraction: float
    late_share: float
    first_signals: tuple
    wall_s: float


def _num(x) -> float:
    return float("nan") if x is None else float(x)


def electrical_cot(run_dir: Path, summary: dict, motor: MotorConfig | None = None) -> float:
    """CoT of the electrical energy over the summary window: Σ_i max(τ_i q̇_i +
    R_w (τ_i / (k_t N_i))², 0) integrated, over (W d) — the default motor's copper loss
    added to the mechanical power, no regeneration."""
    motor = motor or MotorConfig()
    log = read_log(run_dir)
    a, b = summary["window_s"]
    log = log[(log["time"] >= a) & (log["time"] <= b)]
    names = [c[len("tau_"):] for c in log.columns if c.startswith("tau_")]
    tau = log[joint_columns(names, "tau")].to_numpy(dtype=float)
    dq = log[joint_columns(names, "dq")].to_numpy(dtype=float)
    n = np.resize(np.asarray(motor.gear_ratio, dtype=float), len(names))
    kt = float(np.atleast_1d(motor.torque_constant)[0])
    rw = float(np.atleast_1d(motor.winding_resistance)[0])
    p = np.maximum(tau * dq + rw * (tau / (kt * n)) ** 2, 0.0).sum(axis=1)
    t = log["time"].to_numpy(dtype=float)
    energy = float(np.sum(0.5 * (p[1:] + p[:-1]) * np.diff(t)))
    return energy / (run_weight(summary) * float(summary["distance_m"]))


def failing_signals(run_dir: Path, biped) -> tuple[tuple[str, float], ...]:
    """First time each failing signal trips after the weight shift (earliest first): the
    signals of ``bench/paper_ablation.py`` on the run's log."""
    log = read_log(run_dir)
    log = log[log["time"] >= 0.5].reset_index(drop=True)
    return ablation_signals(SimpleNamespace(biped=biped), log)


def run_knob(knob: Knob, terrain: str, out: Path, seconds: float, quick: bool,
             reuse: bool = False) -> Path:
    """Run one knob on one terrain; the run folder (``reuse``: keep a complete run of the
    same length already there)."""
    folder = out / "runs" / f"{knob.name}_{terrain}"
    if reuse and (folder / "summary.json").is_file():
        s = read_summary(folder)
        if s.get("complete") and abs(float(s.get("duration_s") or -1) - seconds) < 1e-9:
            return folder
    over = ["sweep=null", f"terrain={terrain}", f"command.speed={knob.speed:g}",
            f"sim.duration={seconds:g}", "output.plots=false", *knob.overrides]
    if quick:
        over += ["metrics.settle=0.2", "command.max_acceleration=1.0"]
    sc = load_scenario(SCENARIO, over)
    run_scenario(sc, folder, progress=False, overwrite=True)
    return folder


def figures(knob: Knob, terrain: str, folder: Path, biped, wall: float) -> RunFigures:
    """:class:`RunFigures` of one run folder."""
    s = read_summary(folder)
    fell = bool(s.get("fell"))
    nan = float("nan")
    try:
        c = stance_curves(folder)
        onset, share, frac, n = (c.plateau_onset_pct, c.plateau_share, c.plateau_fraction,
                                 c.n_stances)
        late = late_share(c.cot_cum)
    except (ValueError, KeyError, TypeError):   # too few steady stances, no CoT (a fall)
        onset = share = frac = late = nan
        n = 0
    elec = electrical_cot(folder, s) if s.get("energy_J") and not fell else nan
    return RunFigures(
        knob.name, terrain, knob.speed, str(folder), fell, _num(s.get("fall_time_s")),
        str(s.get("fall_reason") or ""),
        nan if fell else _num(s.get("cot_abs_per_joint")),
        nan if fell else _num(s.get("cot_abs_net")),
        nan if fell else _num(s.get("cot_positive")), elec,
        _num(s.get("mean_speed_mps")), _num(s.get("sinkage_peak_mm_mean")),
        _num(s.get("slip_mm_mean")), n, onset, share, frac, late,
        failing_signals(folder, biped), wall)


def pair_figures(sand: Path, rigid: Path) -> dict:
    """Figures that need a sand and a rigid run: CoT ratio (three readings), opening."""
    ss, sr = read_summary(sand), read_summary(rigid)
    out = {}
    for r in ("abs_per_joint", "abs_net", "positive"):
        a, b = ss.get(f"cot_{r}"), sr.get(f"cot_{r}")
        ok = a and b and not ss.get("fell") and not sr.get("fell")
        out[f"ratio_{r}"] = float(a / b) if ok else float("nan")
    try:
        out["opening_pct"] = opening_phase(stance_curves(sand).cot_cum,
                                           stance_curves(rigid).cot_cum)
    except (ValueError, KeyError, TypeError):
        out["opening_pct"] = float("nan")
    return out


def readings(sand: Path, rigid: Path) -> dict:
    """The no-run knobs on the base runs: stance segmentation, electrical CoT, plateau
    detector threshold."""
    out = {}
    for src in ("contact", "force", "planned"):
        cs, cr = stance_curves(sand, source=src), stance_curves(rigid, source=src)
        out[f"segmentation_{src}"] = {
            "opening_pct": opening_phase(cs.cot_cum, cr.cot_cum),
            "plateau_onset_sand_pct": cs.plateau_onset_pct,
            "plateau_fraction_sand": cs.plateau_fraction,
            "plateau_fraction_rigid": cr.plateau_fraction,
            "late_share_sand": late_share(cs.cot_cum),
            "n_stances": [cs.n_stances, cr.n_stances]}
    ss, sr = read_summary(sand), read_summary(rigid)
    es, er = electrical_cot(sand, ss), electrical_cot(rigid, sr)
    out["cot_electrical"] = {"sand": es, "rigid": er, "ratio": es / er}
    for name, run in (("sand", sand), ("rigid", rigid)):
        log = read_log(run)
        seg = steady_segments(log, float(read_summary(run)["window_s"][0]))
        plat = plateau_by_stance(rolling_from_log(log, segments=seg), rel_threshold=0.2)
        has = plat["n_plateaus"] > 0
        out[f"plateau_threshold_x2_{name}"] = {
            "onset_pct": float(plat.loc[has, "onset_pct"].median()) if has.any() else math.nan,
            "fraction": float(plat["fraction"].mean())}
    return out


#: the rigid-model replays of :func:`rigid_grf_ablation`: label → (other foot free,
#: constraint feedback k [1/s], contact mode, impact mode) — one knob each
RIGID_CASES = {
    "as_validate": (False, 50.0, "pin", "project"),
    "other_foot_free": (True, 50.0, "pin", "project"),
    "stabilisation_x4": (False, 200.0, "pin", "project"),
    "impact_soft": (False, 50.0, "pin", "soft"),
    "pin_current": (False, 50.0, "pin_current", "project"),
    "rolling": (False, 50.0, "rolling", "project"),
    "measured_sink": (False, 50.0, "measured_sink", "project"),
    "measured_path": (False, 50.0, "measured", "project"),
}


def _replay_setup(dataset: Path):
    ds = load_dataset(dataset)
    biped = load_biped(ds.meta.robot, with_visuals=False)
    rm = build_replay_model(biped, model_terrain("dry_sand"),
                            sample_rate_hz=ds.meta.sample_rate_hz)
    windows = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness)
    return ds, biped, rm, windows


def measured_newton(biped, windows, dt_s: float) -> dict:
    """Newton on the measured stances: mean stance-foot F_z [N] against m (g + Δv_z/T) of
    the measured CoM (v_z by differences of the first and last two samples) [N], and the
    CoM height change over the stance [mm]."""
    mdl = biped.model
    data = mdl.createData()
    m, g = biped.mass, 9.81
    fz, need, dz = [], [], []
    for w in windows:
        qs = measured_configurations(biped, w)
        z = []
        for k in (0, 1, w.n - 2, w.n - 1):
            pin.centerOfMass(mdl, data, qs[k])
            z.append(float(data.com[0][2]))
        dv = (z[3] - z[2] - z[1] + z[0]) / dt_s
        fz.append(float(np.mean(w.meas["grf_z"])))
        need.append(m * (g + dv / (w.n * dt_s)))
        dz.append(1e3 * (z[3] - z[0]))
    return {"mean_fz_N": float(np.mean(fz)), "m_g_plus_a_N": float(np.mean(need)),
            "other_foot_fz_N": float(np.mean(need) - np.mean(fz)),
            "com_dz_mm": float(np.mean(dz))}


def rigid_grf_ablation(dataset: Path) -> dict:
    """The rigid-ground model's GRF on the comparison's data set, one knob at a time.

    ``as_validate``: the stances replayed as ``validate --model rigid`` does (the other foot
    pinned too when it starts in contact — the 39 ms touchdown double support — until its
    constraint force would pull). ``other_foot_free``: the other foot free from the start.
    ``stabilisation_x4``: the constraint's drift feedback k 50 → 200 1/s. ``impact_soft``:
    no plastic-impact projection of the initial velocity. ``pin_current``: the pinned
    material point with its Jacobian updated every step. ``rolling``: the sole rolling
    without slip. ``measured_sink``: the contact point sinks as measured (x, y pinned).
    ``measured_path``: the contact point follows its measured path (sinking and slip).
    Per case: mean |F| predicted / measured per axis, the mean F_z [N], and Newton's
    balance (the other foot's mean F_z, m (g + Δv_z/T) of the replayed CoM [N], the CoM's
    height change and final vertical velocity); ``measured_newton`` the same on the data."""
    ds, biped, rm, windows = _replay_setup(dataset)
    chans = ["grf_x", "grf_y", "grf_z"]
    meas = windows_frame(windows, None, chans)
    dt_s = 1.0 / ds.meta.sample_rate_hz
    out = {"n_stances": len(windows),
           "n_other_foot_in_contact": int(sum(w.feet[1 - w.foot].in_contact for w in windows)),
           "measured_mean_fz_N": float(meas["grf_z"].mean()),
           "measured_newton": measured_newton(biped, windows, dt_s),
           "weight_N": 9.81 * biped.mass}
    mdl = biped.model
    data = mdl.createData()
    for label, (free, k, contact, impact) in RIGID_CASES.items():
        preds, other, need, dz, vz_end = [], [], [], [], []
        for w in windows:
            if free and w.feet[1 - w.foot].in_contact:
                feet = list(w.feet)
                feet[1 - w.foot] = dataclasses.replace(feet[1 - w.foot], in_contact=False)
                w = dataclasses.replace(w, feet=tuple(feet))
            p = replay_rigid(rm, w, stabilisation=k, contact=contact, impact=impact,
                             diagnostics=True)
            preds.append(p)
            pin.centerOfMass(mdl, data, w.q0, w.v0)
            z0, vz0 = float(data.com[0][2]), float(data.vcom[0][2])
            other.append(float(np.nanmean(p["other_force"][:, 2])))
            need.append(biped.mass * (9.81 + (p["com_vz"][-1] - vz0) / (w.n * dt_s)))
            dz.append(1e3 * (p["com_z"][-1] - z0))
            vz_end.append(float(p["com_vz"][-1]))
        pred = windows_frame(windows, preds, chans)
        ratio = {}
        for c in chans:
            m, p = meas[c].to_numpy(dtype=float), pred[c].to_numpy(dtype=float)
            ok = np.isfinite(m) & np.isfinite(p)
            ratio[c] = float(np.abs(p[ok]).mean() / np.abs(m[ok]).mean())
        out[label] = {"ratio": ratio, "mean_fz_N": float(np.nanmean(pred["grf_z"])),
                      "other_foot_fz_N": float(np.nanmean(other)),
                      "m_g_plus_a_N": float(np.nanmean(need)),
                      "com_dz_mm": float(np.nanmean(dz)),
                      "com_vz_end_mps": float(np.nanmean(vz_end)),
                      "diverged": int(sum(bool(p.get("diverged")) for p in preds))}
    return out


#: the planar-model replays of :func:`planar_intrusion_ablation` (``frontal`` option)
PLANAR_CASES = ("model", "measured", "measured_roll", "measured_lateral")


def planar_intrusion_ablation(dataset: Path) -> dict:
    """The decoupled planar model's intrusion error, one knob at a time.

    The 3-D granular model and the planar model replay the comparison's stances; the planar
    model's terrain law sees the stance foot's frontal-plane state from its frontal model
    (``model``, the paper's), or from the measured 3-D plant: lateral position, velocity and
    foot roll (``measured``), only the roll (``measured_roll``), only the lateral position
    and velocity (``measured_lateral``). Per case: intrusion_z RMSE and mean signed error
    (predicted − measured) [mm], and per 10 % stance-phase bin the signed intrusion error
    [mm], stance-foot F_z error [N] and mean knee-angle error [rad]."""
    _, _, rm, windows = _replay_setup(dataset)
    meas = windows_frame(windows, None, ["intrusion_z"])["intrusion_z"].to_numpy(dtype=float)
    phase = np.concatenate([w.phase for w in windows])
    bins = np.minimum((phase / 10.0).astype(int), 9)
    depth = [float(1e3 * np.nanmean(meas[bins == b])) for b in range(10)]
    out = {"n_stances": len(windows), "measured_depth_by_phase_mm": depth}

    knees = [c for c in windows[0].meas if c.startswith("q_") and c.endswith("_knee")]
    meas_fz = windows_frame(windows, None, ["grf_z"])["grf_z"].to_numpy(dtype=float)
    meas_kn = windows_frame(windows, None, knees)

    def by_phase(e, scale):
        ok = np.isfinite(e)
        return [float(scale * e[ok & (bins == b)].mean()) for b in range(10)]

    def score(preds):
        fr = windows_frame(windows, preds, ["intrusion_z", "grf_z", *knees])
        e = fr["intrusion_z"].to_numpy(dtype=float) - meas
        ok = np.isfinite(e)
        kn = np.mean([fr[c].to_numpy(dtype=float) - meas_kn[c].to_numpy(dtype=float)
                      for c in knees], axis=0)
        return {"rmse_mm": float(1e3 * np.sqrt(np.mean(e[ok] ** 2))),
                "bias_mm": float(1e3 * e[ok].mean()),
                "error_by_phase_mm": by_phase(e, 1e3),
                "grf_z_error_by_phase_N": by_phase(fr["grf_z"].to_numpy(dtype=float) - meas_fz,
                                                   1.0),
                "knee_error_by_phase_rad": by_phase(kn, 1.0),
                "diverged": int(sum(bool(p.get("diverged")) for p in preds))}

    out["granular"] = score([replay_granular(rm, w, Variant()) for w in windows])
    for mode in PLANAR_CASES:
        out[f"planar_{mode}"] = score([replay_planar(rm, w, frontal=mode) for w in windows])
    return out


def _f(x, nd=2) -> str:
    return f"{x:.{nd}f}" if isinstance(x, (int, float)) and math.isfinite(x) else "—"


def table(results: list[RunFigures], pairs: dict) -> str:
    """Markdown table: one row per knob (sand, rigid, derived figures)."""
    head = ("| knob | v | CoT sand (Σ\\|τq̇\\| / abs_net / pos / elec) | CoT rigid | ratio | "
            "opening [%] | plateau onset sand [%] | plateau cover sand/rigid [%] | "
            "late share sand [%] | sink/slip sand [mm] | fell |\n|" + "---|" * 11)
    lines = [head]
    by = {(r.knob, r.terrain): r for r in results}
    for knob in dict.fromkeys(r.knob for r in results):
        s, r = by.get((knob, SAND)), by.get((knob, RIGID))
        p = pairs.get(knob, {})
        cot = (lambda x: f"{_f(x.cot)} / {_f(x.cot_abs_net)} / {_f(x.cot_positive)} / "
               f"{_f(x.cot_electrical)}" if x else "(base)")
        fell = ", ".join(f"{x.terrain} at {_f(x.fall_time_s)} s" for x in (s, r) if x and x.fell)
        v = (s or r).speed
        lines.append(
            f"| {knob} | {v:g} | {cot(s)} | {cot(r)} | {_f(p.get('ratio_abs_per_joint'))} | "
            f"{_f(p.get('opening_pct'), 0)} | {_f(s.plateau_onset_pct, 0) if s else '—'} | "
            f"{_f(100 * s.plateau_fraction, 0) if s else '—'}/"
            f"{_f(100 * r.plateau_fraction, 0) if r else '—'} | "
            f"{_f(100 * s.late_share, 0) if s else '—'} | "
            f"{_f(s.sinkage_mm, 1) + '/' + _f(s.slip_mm, 1) if s else '—'} | {fell or 'no'} |")
    return "\n".join(lines)


def replay_readings(args) -> dict:
    """The readings that need no paper-sweep run: the rigid-model GRF and planar-model
    intrusion replays (``args.dataset``) and the F_x-swing knobs (``args.fx``)."""
    out = {}
    if args.dataset:
        out["rigid_grf"] = rigid_grf_ablation(Path(args.dataset))
        out["planar_intrusion"] = planar_intrusion_ablation(Path(args.dataset))
    if args.fx:
        res = fx_main(["--out", str(Path(args.out) / "fx"), *(["--reuse"] if args.reuse else [])])
        out["fx_swing"] = {r.knob: dataclasses.asdict(r) for r in res}
    return out


def merge_readings(path: Path, readings_: dict, command: str = "") -> None:
    """Write ``readings_`` into the readings of the JSON at ``path`` (created if absent),
    keeping every other entry; ``command`` is appended to its ``merged`` list."""
    doc = json.loads(path.read_text()) if path.is_file() else {}
    doc.setdefault("readings", {}).update(readings_)
    doc.setdefault("merged", []).append({"command": command, "readings": sorted(readings_)})
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=1, default=str))


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="runs/paper_gaps", help="folder for the runs")
    ap.add_argument("--json", default=None, help="write every figure as JSON to this path")
    ap.add_argument("--cases", nargs="+", default=None, help="knob names (default: all)")
    ap.add_argument("--seconds", type=float, default=12.0, help="simulated seconds per run")
    ap.add_argument("--quick", action="store_true", help="2 knobs x 3 s (a test, not a result)")
    ap.add_argument("--list", action="store_true", help="list the knobs and exit")
    ap.add_argument("--reuse", action="store_true",
                    help="keep complete runs of the same length already in --out")
    ap.add_argument("--dataset", default=None,
                    help="the paper comparison's data set (DIR/dataset): also run the rigid "
                         "model's GRF ablation on it")
    ap.add_argument("--replay-only", action="store_true",
                    help="only the replay ablations (--dataset) and the F_x knobs (--fx), "
                         "merged into the readings of an existing --json (its other entries "
                         "kept); no paper-sweep runs")
    ap.add_argument("--planar-only", action="store_true",
                    help="only the planar model's under-load ablation (bench/paper_planar.py) "
                         "on --dataset, merged into the readings of --json as 'planar_load'")
    ap.add_argument("--fx", action="store_true",
                    help="also run the F_x-swing knobs of bench/paper_fx.py (8 s each)")
    args = ap.parse_args(argv)
    by_name = {k.name: k for k in KNOBS}
    if args.list:
        for k in KNOBS:
            print(f"{k.name:14s} {'+'.join(k.terrains):15s} {k.speed:g} m/s  {k.what}")
        return {}
    if args.planar_only:
        if not args.dataset:
            ap.error("--planar-only needs --dataset")
        rep = {"planar_load": planar_load_run(Path(args.dataset), _replay_setup)}
        if args.json:
            merge_readings(Path(args.json), rep, " ".join(["python bench/paper_gaps.py",
                                                            *(argv or sys.argv[1:])]))
        return rep
    if args.replay_only:
        if not args.dataset and not args.fx:
            ap.error("--replay-only needs --dataset and/or --fx")
        rep = replay_readings(args)
        print(json.dumps(rep, indent=1))
        if args.json:
            merge_readings(Path(args.json), rep, " ".join(["python bench/paper_gaps.py",
                                                            *(argv or sys.argv[1:])]))
        return rep
    names = list(QUICK_KNOBS) if args.quick else (args.cases or [k.name for k in KNOBS])
    unknown = [n for n in names if n not in by_name]
    if unknown:
        ap.error(f"unknown knob(s) {unknown}; known: {sorted(by_name)}")
    if "base" not in names:
        names.insert(0, "base")              # every pair needs the reference
    seconds = 3.0 if args.quick else args.seconds
    out = Path(args.out)
    biped = load_biped(with_visuals=False)
    print(f"GRANULAR_MPC_PROXSUITE={os.environ['GRANULAR_MPC_PROXSUITE']}, {seconds:g} s "
          f"per run", flush=True)
    results: list[RunFigures] = []
    folders: dict = {}
    for name in names:
        knob = by_name[name]
        for terrain in knob.terrains:
            t0 = time.perf_counter()
            folder = run_knob(knob, terrain, out, seconds, args.quick, args.reuse)
            res = figures(knob, terrain, folder, biped, time.perf_counter() - t0)
            folders[(name, terrain)] = folder
            results.append(res)
            sig = ", ".join(f"{n}@{t:.2f}" for n, t in res.first_signals[:4]) or "none"
            print(f"{name:14s} {terrain:9s} {knob.speed:g} m/s  CoT {_f(res.cot)} "
                  f"(elec {_f(res.cot_electrical)})  fell {res.fell} "
                  f"{_f(res.fall_time_s)} {res.fall_reason}  first signals: {sig}  "
                  f"[{res.wall_s:.0f} s]", flush=True)
    pairs = {}
    for name in names:          # paired with the reference run of the same speed
        knob = by_name[name]
        ref = next((n for n in names if n.startswith("base")
                    and by_name[n].speed == knob.speed and (n, RIGID) in folders), None)
        if ref is None:
            continue
        sand = folders.get((name, SAND), folders.get((ref, SAND)))
        rigid = folders.get((name, RIGID), folders[(ref, RIGID)])
        if sand is not None:
            pairs[name] = pair_figures(sand, rigid)
    extra = readings(folders[("base", SAND)], folders[("base", RIGID)])
    extra.update(replay_readings(args))
    print(table(results, pairs))
    print(json.dumps(extra, indent=1))
    doc = {"command": " ".join(["python bench/paper_gaps.py", *(argv or sys.argv[1:])]),
           "quick": bool(args.quick), "seconds": seconds,
           "knobs": {k.name: dataclasses.asdict(k) for k in KNOBS if k.name in names},
           "runs": [dataclasses.asdict(r) for r in results], "pairs": pairs,
           "readings": extra,
           "wall_s": sum(r.wall_s for r in results)}
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(doc, indent=1, default=str))
    print(f"total wall time {doc['wall_s']:.0f} s", file=sys.stderr)
    return doc


if __name__ == "__main__":
    main()
