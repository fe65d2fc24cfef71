"""A synthetic run log with the run-log columns (granular_mpc.runlog) and known answers.

Alternating single stances (left, right, left …) of ``stance_rows`` samples each, optional
``none`` rows before, between and after them. Every signal is a closed-form function of the
stance phase s ∈ [0, 1] plus a per-stance offset, so tests can recompute what the analysis
should find without using the package.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.integrate import cumulative_trapezoid

JOINTS = ("left_hip_abd", "left_hip_pitch", "left_knee",
          "right_hip_abd", "right_hip_pitch", "right_knee")
LEG = ("hip_abd", "hip_pitch", "knee")
MASS = 10.7          # kg
G = 9.81
ROLL_RADIUS = 0.06   # m, the radius our synthetic foot rolls with (x_s = R |Δψ| + slip)
ROLL_TOTAL = 0.35    # rad, |Δθ_r| over one stance


def ramp_plateau_ramp(s: np.ndarray, a: float = 0.4, b: float = 0.7) -> np.ndarray:
    """0 → 1 over s ∈ [0, 1]: linear on [0, a], flat on [a, b], linear on [b, 1]."""
    s = np.asarray(s, dtype=float)
    rate = 1.0 / (a + (1.0 - b))
    return np.where(s < a, rate * s, np.where(s < b, rate * a, rate * (a + s - b)))


def rpy_to_quat(roll, pitch, yaw):
    """(w, x, y, z) of R = Rz(yaw) Ry(pitch) Rx(roll), textbook half-angle formula."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


@dataclass
class SyntheticLog:
    df: pd.DataFrame
    segments: list = field(default_factory=list)   # (side, row_start, row_stop)
    dt: float = 0.002
    roll: np.ndarray | None = None                # true trunk roll, pitch, yaw [rad] (n, 3)


def make_log(n_stances: int = 6, *, stance_rows: int = 101, dt: float = 0.002,
             lead_rows: int = 10, gap_rows: int = 0, first_side: str = "left",
             speed: float = 0.2, seed: int = 0) -> SyntheticLog:
    rng = np.random.default_rng(seed)
    sides = [("left", "right")[(i + (first_side == "right")) % 2] for i in range(n_stances)]
    labels, seg_rows, phase = [], [], []
    row = 0

    def add_none(k):
        nonlocal row
        labels.extend(["none"] * k)
        phase.extend([np.nan] * k)
        row += k

    add_none(lead_rows)
    for i, side in enumerate(sides):
        if i > 0:
            add_none(gap_rows)
        seg_rows.append((side, row, row + stance_rows))
        labels.extend([side] * stance_rows)
        phase.extend(np.linspace(0.0, 1.0, stance_rows))
        row += stance_rows
    add_none(lead_rows)
    n = row
    t = np.arange(n) * dt
    s = np.asarray(phase)
    stance = np.asarray(labels, dtype=object)
    sid = np.full(n, -1)
    for k, (_, a, b) in enumerate(seg_rows):
        sid[a:b] = k
    q_off = rng.normal(0.0, 0.03, size=(n_stances, 6))
    f_off = rng.normal(0.0, 2.0, size=(n_stances, 3))
    psi0 = rng.normal(0.15, 0.02, size=n_stances)

    cols: dict[str, np.ndarray] = {"time": t, "stance": stance}
    # joints by role: stance leg / swing leg shapes over s, plus per-stance offsets
    st_shape = lambda u: np.vstack([0.03 * np.sin(np.pi * u), -0.6 + 0.35 * (u - 0.5),
                                    1.2 + 0.15 * np.sin(np.pi * u)])
    sw_shape = lambda u: np.vstack([-0.02 * np.ones_like(u), -0.6 - 0.5 * np.sin(np.pi * u),
                                    1.2 + 0.6 * np.sin(np.pi * u)])
    q = {j: np.zeros(n) for j in JOINTS}
    for k, (side, a, b) in enumerate(seg_rows):
        other = "right" if side == "left" else "left"
        u = s[a:b]
        for j, name in enumerate(LEG):
            q[f"{side}_{name}"][a:b] = st_shape(u)[j] + q_off[k, j]
            q[f"{other}_{name}"][a:b] = sw_shape(u)[j] + q_off[k, 3 + j]
    # between stances hold the last values (keeps signals finite)
    for j in JOINTS:
        q[j] = pd.Series(np.where(np.isnan(s), np.nan, q[j])).ffill().bfill().to_numpy()
    for i, j in enumerate(JOINTS):
        cols[f"q_{j}"] = q[j]
        cols[f"dq_{j}"] = np.gradient(q[j], t)
        cols[f"tau_{j}"] = 4.0 * np.sin(2 * np.pi * t / 0.4 + i)

    # per-foot contact quantities
    weight = MASS * G
    for side in ("left", "right"):
        on = stance == side
        sign = 1.0 if side == "left" else -1.0
        fx = np.zeros(n)
        fy = np.zeros(n)
        fz = np.zeros(n)
        pitch = np.full(n, 0.1)
        xs = np.zeros(n)
        ys = np.zeros(n)
        zs = np.zeros(n)
        for k, (sd, a, b) in enumerate(seg_rows):
            if sd != side:
                continue
            uu = s[a:b]
            fx[a:b] = 15.0 * np.sin(2 * np.pi * uu) + f_off[k, 0]
            fy[a:b] = sign * 4.0 * np.sin(np.pi * uu) + f_off[k, 1]
            fz[a:b] = weight * (1.0 - 0.25 * np.cos(2 * np.pi * uu)) + f_off[k, 2]
            dpsi = -ROLL_TOTAL * ramp_plateau_ramp(uu)
            pitch[a:b] = psi0[k] + dpsi
            xs[a:b] = ROLL_RADIUS * (-dpsi) + 0.004 * uu
            ys[a:b] = sign * 0.002 * uu
            zs[a:b] = 0.015 * (1.0 - np.exp(-6.0 * uu))
        cols[f"{side}_grf_x"], cols[f"{side}_grf_y"], cols[f"{side}_grf_z"] = fx, fy, fz
        cols[f"{side}_intrusion_x"] = xs
        cols[f"{side}_intrusion_y"] = ys
        cols[f"{side}_intrusion_z"] = zs
        cols[f"{side}_contact"] = on.astype(int)
        cols[f"{side}_depth"] = np.where(on, 0.005 + zs, 0.0)
        cols[f"{side}_px"] = 0.2 * t + xs
        cols[f"{side}_py"] = sign * 0.08 + ys
        cols[f"{side}_pz"] = -zs
        cols[f"{side}_pitch"] = pitch
        cols[f"{side}_cap_z"] = np.where(on, 2.0 * weight, 0.0)
    for ax in "xyz":
        st = np.select([stance == "left", stance == "right"],
                       [cols[f"left_grf_{ax}"], cols[f"right_grf_{ax}"]], 0.0)
        si = np.select([stance == "left", stance == "right"],
                       [cols[f"left_intrusion_{ax}"], cols[f"right_intrusion_{ax}"]], 0.0)
        cols[f"grf_{ax}"] = st
        cols[f"intrusion_{ax}"] = si

    # CoM consistent with the vertical impulse balance: m dv_z/dt = ΣF_z − m g
    fz_tot = cols["left_grf_z"] + cols["right_grf_z"]
    vz = cumulative_trapezoid((fz_tot - weight) / MASS, t, initial=0.0)
    vx = speed + 0.03 * np.sin(2 * np.pi * t / 0.4)
    vy = 0.05 * np.cos(2 * np.pi * t / 0.8)
    cols["com_vx"], cols["com_vy"], cols["com_vz"] = vx, vy, vz
    cols["com_x"] = cumulative_trapezoid(vx, t, initial=0.0)
    cols["com_y"] = cumulative_trapezoid(vy, t, initial=0.0)
    cols["com_z"] = 0.41 + cumulative_trapezoid(vz, t, initial=0.0)

    roll = 0.02 * np.sin(2 * np.pi * t / 0.8)
    pitch_b = 0.03 * np.cos(2 * np.pi * t / 0.4)
    yaw = 0.05 * t
    qw, qx, qy, qz = rpy_to_quat(roll, pitch_b, yaw)
    cols.update(base_x=cols["com_x"] + 0.01, base_y=cols["com_y"], base_z=cols["com_z"] + 0.03,
                base_qw=qw, base_qx=qx, base_qy=qy, base_qz=qz, base_vx=vx, base_vy=vy,
                base_vz=vz, base_wx=np.gradient(roll, t), base_wy=np.gradient(pitch_b, t),
                base_wz=np.full(n, 0.05))
    df = pd.DataFrame(cols)
    return SyntheticLog(df=df, segments=seg_rows, dt=dt,
                        roll=np.column_stack([roll, pitch_b, yaw]))


def interp_segment(df: pd.DataFrame, column: str, a: int, b: int, grid: np.ndarray) -> np.ndarray:
    """Independent resampling of rows a..b−1 of ``column`` onto ``grid`` [%]."""
    t = df["time"].to_numpy()[a:b]
    ph = 100.0 * (t - t[0]) / (t[-1] - t[0])
    return np.interp(grid, ph, df[column].to_numpy()[a:b])


@dataclass
class ContactLog:
    """A synthetic run log whose feet touch down before and lift off after the plan.

    Attributes:
        df: the log (make_log's columns; per-foot contact, grf_z and intrusion rewritten).
        planned: (side, row_start, row_stop) of the planned stances (``stance`` column).
        contact: (side, row_start, row_stop) of the true stances, touchdown to lift-off
            (before any chatter is injected), clipped to the log.
        dt: sample period [s].
    """

    df: pd.DataFrame
    planned: list
    contact: list
    dt: float


CONTACT_FZ = 60.0        # N, vertical force floor of a foot on the ground
SINK_DEPTH = 0.03        # m, z_s approached during a stance: z_s = D (1 − exp(−5 u))


def make_contact_log(n_stances: int = 4, *, stance_rows: int = 51, gap_rows: int = 10,
                     early: int = 4, late: int = 2, lead_rows: int = 10,
                     first_side: str = "left", chatter=(), dt: float = 0.002,
                     seed: int = 0) -> ContactLog:
    """make_log's planned stances, with each foot on the ground from ``early`` rows before
    its planned stance to ``late`` rows after it (clipped to the log), as on sand where the
    plan says ``none`` during load transfer.

    Per foot: ``<side>_contact`` is 1 on the true stance; ``<side>_grf_z`` is
    CONTACT_FZ (1 + sin(π u)) there and 0 elsewhere; ``<side>_intrusion_z`` = SINK_DEPTH
    (1 − exp(−5 u)) and ``<side>_intrusion_x`` = 0.01 u, with u ∈ [0, 1] the phase of the
    true stance (0 at touchdown). ``chatter`` is a sequence of (side, row) whose contact
    flag and force are flipped (one-sample chatter). The v1 ``stance``/``grf_*``/
    ``intrusion_*`` columns stay those of the plan.
    """
    L = make_log(n_stances, stance_rows=stance_rows, dt=dt, lead_rows=lead_rows,
                 gap_rows=gap_rows, first_side=first_side, seed=seed)
    df = L.df.copy()
    n = len(df)
    contact = []
    cols = {s: {"contact": np.zeros(n, dtype=int), "grf_z": np.zeros(n),
                "intrusion_z": np.zeros(n), "intrusion_x": np.zeros(n)}
            for s in ("left", "right")}
    for side, a, b in L.segments:
        a2, b2 = max(a - early, 0), min(b + late, n)
        contact.append((side, a2, b2))
        u = np.linspace(0.0, 1.0, b2 - a2)
        c = cols[side]
        c["contact"][a2:b2] = 1
        c["grf_z"][a2:b2] = CONTACT_FZ * (1.0 + np.sin(np.pi * u))
        c["intrusion_z"][a2:b2] = SINK_DEPTH * (1.0 - np.exp(-5.0 * u))
        c["intrusion_x"][a2:b2] = 0.01 * u
    for side, row in chatter:
        c = cols[side]
        on = c["contact"][row] == 1
        c["contact"][row] = 0 if on else 1
        c["grf_z"][row] = 0.0 if on else CONTACT_FZ
    for side, c in cols.items():
        for name, values in c.items():
            df[f"{side}_{name}"] = values
    return ContactLog(df=df, planned=list(L.segments), contact=contact, dt=dt)
