"""Why the decoupled planar model under-loads its stance foot: one-knob ablations (issue 10,
row ``planar_model`` of the paper comparison; docs/paper-experiment-notes.md §7.2).

    GRANULAR_MPC_PROXSUITE=generic python bench/paper_gaps.py --planar-only \
        --dataset /work/results/paper17/dataset --json granular_mpc/paper/gaps_measured.json

Two families of replays of the comparison's sand stances under the measured torques:

* **the planar model** (``replay_planar``), one opt-in knob each: ``paper`` (the paper's
  model), ``moment`` (the terrain wrench's moment about the sole-arc centre applied to the
  calf / leg angle; the paper's model applies the force only through the contact
  coordinates), ``swing_off`` (the other foot never loaded), with Newton's check on the
  sagittal model's own COM: mean F_z of both feet against m (g + Δv_z/T);
* **the 3-D model with one out-of-plane freedom held** (reference plant, a stiff spring–
  damper): the freedom the sagittal model does not have — trunk ``yaw``, trunk ``roll``,
  ``lateral`` base position, hip ``abduction`` — one at a time and all together. The
  sagittal model is the 3-D model with all of them held (and its legs projected on x–z);
  a hold that reproduces the planar model's under-load names the term.

Also the measured trunk yaw over each stance. Each case: intrusion_z RMSE and mean signed error (predicted − measured) [mm], per 10 %
stance-phase bin the signed intrusion error [mm], stance-foot F_z error [N] and mean
knee-angle error [rad].
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pinocchio as pin

from granular_mpc.dynamics import Plant
from granular_mpc.rotations import matrix_from_quat_xyzw
from granular_mpc.validation.prepare import windows_frame
from granular_mpc.validation.replay import (ReplayModel, Variant, build_replay_model,
                                            model_terrain, replay_granular, replay_planar)
from granular_mpc.validation.replay.rigid import measured_configurations

#: planar-model cases: label → replay_planar keyword arguments (one knob each)
PLANAR_LOAD_CASES = {
    "paper": {},
    "moment": {"moment": "apply"},
    "swing_off": {"swing_force": "off"},
}
#: 3-D cases: label → the out-of-plane freedoms held
HOLD_CASES = {
    "none": (),
    "yaw": ("yaw",),
    "roll": ("roll",),
    "lateral": ("lateral",),
    "abduction": ("abduction",),
    "yaw_abduction": ("yaw", "abduction"),
    "all": ("yaw", "roll", "lateral", "abduction"),
}
#: hold stiffness / damping: trunk rotation [N·m/rad, N·m·s/rad], base y [N/m, N·s/m],
#: abduction joints [N·m/rad, N·m·s/rad]
HOLD_ROT = (2000.0, 50.0)
HOLD_LAT = (2.0e5, 2.0e3)
HOLD_ABD = (500.0, 5.0)
HOLDS = ("yaw", "roll", "lateral", "abduction")


def held_plant(rm: ReplayModel, holds: tuple[str, ...]) -> tuple[Plant, ReplayModel]:
    """The reference 3-D plant with the freedoms ``holds`` (:data:`HOLDS`) held at their
    initial values by stiff spring–dampers (trunk yaw / roll: a moment on the trunk about
    W's z / x from the rotation since the start; ``lateral``: a force along W's y;
    ``abduction``: a joint torque), and a replay model whose ``granular`` replay steps it.

    Returns:
        (plant, replay model).
    """
    bad = [h for h in holds if h not in HOLDS]
    if bad:
        raise ValueError(f"holds must be among {HOLDS}, got {bad}")
    biped = rm.biped
    iabd = np.array([i for i, n in enumerate(biped.joint_names) if n.endswith("_abd")])
    ref: dict = {}

    def abduction_hold(qa, va):
        t = np.zeros(len(qa))
        if "abduction" in holds and ref:
            k, c = HOLD_ABD
            t[iabd] = -k * (qa[iabd] - ref["qa"][iabd]) - c * va[iabd]
        return t

    def base_wrench(q, v):
        R = matrix_from_quat_xyzw(q[3:7])
        w, vl = R @ v[3:6], R @ v[0:3]
        rv = pin.log3(R @ ref["R0"].T)
        out = np.zeros(6)
        k, c = HOLD_ROT
        if "yaw" in holds:
            out[5] = -k * rv[2] - c * w[2]
        if "roll" in holds:
            out[3] = -k * rv[0] - c * w[0]
        if "lateral" in holds:
            out[1] = -HOLD_LAT[0] * (q[1] - ref["y0"]) - HOLD_LAT[1] * vl[1]
        return out

    class HeldPlant(Plant):
        def new_data(self, q0, v0=None):
            d = super().new_data(q0, v0)
            ref.update(qa=d.q[biped.idx_q].copy(), R0=matrix_from_quat_xyzw(d.q[3:7]),
                       y0=float(d.q[1]))
            if {"yaw", "roll", "lateral"} & set(holds):
                d.base_wrench = base_wrench
            return d

    plant = HeldPlant(biped, rm.terrain, rm.sim, joint_effects=(abduction_hold,))

    class HeldReplayModel(ReplayModel):
        def replay_plant(self, variant):
            return plant, None

    return plant, HeldReplayModel(**{f.name: getattr(rm, f.name)
                                     for f in dataclasses.fields(rm) if f.init})


def _scorer(windows):
    meas = windows_frame(windows, None, ["intrusion_z", "grf_z"])
    mi, mf = (meas[c].to_numpy(dtype=float) for c in ("intrusion_z", "grf_z"))
    knees = [c for c in windows[0].meas if c.startswith("q_") and c.endswith("_knee")]
    mk = windows_frame(windows, None, knees)
    bins = np.minimum((np.concatenate([w.phase for w in windows]) / 10.0).astype(int), 9)

    def by_phase(e):
        ok = np.isfinite(e)
        return [float(e[ok & (bins == b)].mean()) for b in range(10)]

    def score(preds) -> dict:
        fr = windows_frame(windows, preds, ["intrusion_z", "grf_z", *knees])
        e = 1e3 * (fr["intrusion_z"].to_numpy(dtype=float) - mi)
        ok = np.isfinite(e)
        kn = np.mean([fr[c].to_numpy(dtype=float) - mk[c].to_numpy(dtype=float)
                      for c in knees], axis=0)
        return {"rmse_mm": float(np.sqrt(np.mean(e[ok] ** 2))), "bias_mm": float(e[ok].mean()),
                "error_by_phase_mm": by_phase(e),
                "grf_z_error_by_phase_N": by_phase(fr["grf_z"].to_numpy(dtype=float) - mf),
                "knee_error_by_phase_rad": by_phase(kn),
                "diverged": int(sum(bool(p.get("diverged")) for p in preds))}
    return score


def planar_newton(biped, windows, preds, dt_s: float) -> dict:
    """Newton's check of planar replays (``diagnostics=True``): mean F_z of both feet [N]
    against m (g + Δv_z/T) of the sagittal model's COM (start: the measured 3-D COM
    velocity) [N], and the COM height change over the stance [mm]."""
    data = biped.model.createData()
    fz, need, dz = [], [], []
    for w, p in zip(windows, preds):
        pin.centerOfMass(biped.model, data, w.q0, w.v0)
        vz0 = float(data.vcom[0][2])
        fz.append(float(np.nanmean(p["grf_z"]) + np.nanmean(p["other_force"][:, 2])))
        need.append(biped.mass * (9.81 + (p["com_vz"][-1] - vz0) / (w.n * dt_s)))
        dz.append(1e3 * float(p["com_z"][-1] - p["com_z"][0]))
    return {"mean_fz_both_N": float(np.mean(fz)), "m_g_plus_a_N": float(np.mean(need)),
            "com_dz_mm": float(np.mean(dz))}


def measured_yaw(biped, windows) -> dict:
    """The measured trunk yaw over each stance (the freedom the sagittal model lacks): mean
    |yaw(lift-off) − yaw(touchdown)| and mean within-stance range [mrad], and the mean
    signed change per stance side [mrad]."""
    change, span, by_side = [], [], {}
    for w in windows:
        yaw = np.unwrap([math.atan2(R[1, 0], R[0, 0]) for R in
                         (matrix_from_quat_xyzw(q[3:7])
                          for q in measured_configurations(biped, w))])
        change.append(1e3 * (yaw[-1] - yaw[0]))
        span.append(1e3 * float(yaw.max() - yaw.min()))
        by_side.setdefault(w.side, []).append(change[-1])
    return {"abs_change_mrad": float(np.mean(np.abs(change))),
            "range_mrad": float(np.mean(span)),
            "change_by_side_mrad": {k: float(np.mean(v)) for k, v in by_side.items()}}


def planar_load_ablation(ds, biped, rm: ReplayModel, windows) -> dict:
    """Every case of the module docstring on ``windows`` (the comparison's sand stances)."""
    score = _scorer(windows)
    dt_s = 1.0 / ds.meta.sample_rate_hz
    out = {"n_stances": len(windows), "mass_kg": biped.mass,
           "measured_yaw": measured_yaw(biped, windows),
           "hold_stiffness": {"rotation": HOLD_ROT, "lateral": HOLD_LAT,
                              "abduction": HOLD_ABD}}
    for label, kw in PLANAR_LOAD_CASES.items():
        preds = [replay_planar(rm, w, diagnostics=True, **kw) for w in windows]
        out[f"planar_{label}"] = {**score(preds),
                                  "newton": planar_newton(biped, windows, preds, dt_s)}
    ref = build_replay_model(biped, model_terrain("dry_sand"),
                             sample_rate_hz=ds.meta.sample_rate_hz, plant="reference")
    for label, holds in HOLD_CASES.items():
        _, held = held_plant(ref, holds)
        out[f"held_{label}"] = score([replay_granular(held, w, Variant()) for w in windows])
    return out


def table(res: dict) -> str:
    """Markdown table of :func:`planar_load_ablation`."""
    lines = ["| replay | intrusion_z RMSE [mm] | bias [mm] | signed error by 10 % of stance "
             "[mm] | stance F_z error by 10 % [N] | knee error at lift-off [rad] |",
             "|---|---|---|---|---|---|"]
    for k, v in res.items():
        if not isinstance(v, dict) or "rmse_mm" not in v:
            continue
        f = lambda xs, nd: " ".join(f"{x:+.{nd}f}" for x in xs)  # noqa: E731
        lines.append(f"| {k} | {v['rmse_mm']:.2f} | {v['bias_mm']:+.2f} | "
                     f"{f(v['error_by_phase_mm'], 1)} | {f(v['grf_z_error_by_phase_N'], 1)} | "
                     f"{v['knee_error_by_phase_rad'][-1]:+.3f} |")
    return "\n".join(lines)


def run(dataset: Path, setup) -> dict:
    """:func:`planar_load_ablation` on the data set at ``dataset``; ``setup`` is
    ``paper_gaps._replay_setup`` (data set, biped, replay model, stance windows)."""
    ds, biped, rm, windows = setup(dataset)
    res = planar_load_ablation(ds, biped, rm, windows)
    print(table(res), flush=True)
    return res
