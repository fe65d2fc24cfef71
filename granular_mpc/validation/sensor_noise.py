"""Sensor noise of synthetic measurement data (format v1): the realistic model and
per-column white noise.

**Noise model** (``noise=level``; level 1 = a realistic laboratory set-up, 0 = none):

=====================  =====================================================================
column                 noise (σ at level 1; scales with the level)
=====================  =====================================================================
``q_*``                encoder: white, 1e-3 rad
``dq_*``               differentiated encoder noise: backward difference of the q noise,
                       low-passed (2nd-order Butterworth, 80 Hz): ≈ 0.2 rad/s
``tau_*``              motor-current torque: white, 3 % of |τ| + 0.02 N·m
``grf_*``              foot force sensor: white, 1 N + 1 % of |F| (stance rows only)
``base_x,y,z``         motion capture: white, 1 mm
``base_q*``            motion capture: white rotation vector, 0.5° per axis (renormalised)
``base_v*``            state estimate: low-passed (40 Hz) noise, 0.02 m/s
``base_w*``            IMU gyro: white, 0.01 rad/s
``intrusion_*``        foot marker: white, 1 mm (stance rows only)
=====================  =====================================================================

``noise`` may instead be a mapping: ``{"level": L}`` selects the model above and any other
key ``PREFIX: σ`` replaces the model by white Gaussian noise of σ (column units) on the
columns starting with PREFIX (longest prefix wins) — the ``--noise PREFIX=STD`` of the
command line.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy.signal import butter, lfilter

from ..columns import (BASE_ANGULAR_VELOCITY, BASE_COLUMNS, BASE_LINEAR_VELOCITY,
                       BASE_POSITION, BASE_QUATERNION, GRF_COLUMNS, INTRUSION_COLUMNS,
                       JOINT_PREFIXES, STANCE, TIME, joint_columns)
from ..exceptions import ConfigError
from ..rotations import quat_mul_rows_wxyz, quat_rows_wxyz_from_rotvec

#: default noise standard deviations at level 1 (see the module docstring)
NOISE_MODEL = {
    "q": 1e-3, "dq_cutoff_hz": 80.0, "tau_rel": 0.03, "tau_abs": 0.02, "grf_abs": 1.0,
    "grf_rel": 0.01, "base_pos": 1e-3, "base_rot_deg": 0.5, "base_v": 0.02,
    "base_v_cutoff_hz": 40.0, "base_w": 0.01, "intrusion": 1e-3,
}


def _butter_lowpass(x: np.ndarray, cutoff_hz: float, fs: float) -> np.ndarray:
    """Causal 2nd-order Butterworth low-pass along axis 0."""
    wn = min(cutoff_hz / (0.5 * fs), 0.99)
    b, a = butter(2, wn)
    return lfilter(b, a, x, axis=0)


def _quat_noise(quat_wxyz: np.ndarray, sigma_rad: float, rng) -> np.ndarray:
    """Perturb unit quaternions (w, x, y, z) by a random body rotation of σ per axis [rad]."""
    n = quat_wxyz.shape[0]
    rv = rng.normal(0.0, sigma_rad, size=(n, 3))
    out = quat_mul_rows_wxyz(quat_wxyz, quat_rows_wxyz_from_rotvec(rv))
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    out *= np.sign(out[:, :1] + (out[:, :1] == 0))
    return out


def normalise_noise(noise: float | Mapping[str, float] | None) -> tuple[float, dict[str, float]]:
    """(level of the realistic model, per-prefix white-noise overrides).

    Raises:
        ConfigError: a negative or non-finite level or standard deviation.
    """
    if noise is None:
        return 1.0, {}
    if isinstance(noise, (int, float)):
        if noise < 0 or not math.isfinite(noise):
            raise ConfigError(f"noise level must be a finite number ≥ 0, got {noise}", key="noise")
        return float(noise), {}
    items = dict(noise)
    level = float(items.pop("level", 0.0 if items else 1.0))
    for k, v in items.items():
        if not (float(v) >= 0.0 and math.isfinite(float(v))):
            raise ConfigError(f"noise {k!r}: the standard deviation must be ≥ 0", key="noise")
    if level < 0:
        raise ConfigError("noise level must be ≥ 0", key="noise.level")
    return level, {k: float(v) for k, v in items.items()}


def noise_prefixes(joint_names: Sequence[str] | None = None) -> list[str]:
    """The column prefixes a ``--noise PREFIX=STD`` may name: the column families
    (``q_``, ``dq_``, ``tau_``, ``base_``, ``grf_``, ``intrusion_``) and, with
    ``joint_names``, every noisy column itself."""
    out = list(JOINT_PREFIXES) + ["base_", "grf_", "intrusion_"]
    if joint_names is not None:
        for kind in ("q", "dq", "tau"):
            out += joint_columns(joint_names, kind)
        out += list(BASE_COLUMNS) + list(GRF_COLUMNS) + list(INTRUSION_COLUMNS)
    return out


def check_noise_prefixes(white: Mapping[str, float],
                         joint_names: Sequence[str] | None = None) -> None:
    """Every per-column noise key must match at least one noisy column.

    Without ``joint_names`` a key passes if it could start a column of a family
    (``q_left`` could be ``q_left_knee``); with them, it must start an actual column.

    Raises:
        ConfigError: a key matches no column (names it and lists the allowed prefixes).
    """
    families = noise_prefixes(None)
    columns = noise_prefixes(joint_names)[len(families):] if joint_names is not None else []
    for key in white:
        if joint_names is not None:
            ok = any(c.startswith(key) for c in columns)
        else:
            ok = any(f.startswith(key) or key.startswith(f) for f in families)
        if not ok:
            allowed = ", ".join(families) + (", or a full column name such as "
                                             f"{columns[0]}" if columns else
                                             ", or a full column name")
            raise ConfigError(f"noise prefix {key!r} matches no column of the data set",
                              key="--noise", value=key, allowed=allowed)


def add_noise(df: pd.DataFrame, joint_names: Sequence[str], level: float,
              white: Mapping[str, float], rng: np.random.Generator,
              sample_rate_hz: float) -> pd.DataFrame:
    """A copy of the format-v1 frame ``df`` with sensor noise (see the module docstring).

    Args:
        df: a format-v1 trial (not modified).
        joint_names: actuated joints, actuator order.
        level: level of the realistic model (0: none).
        white: column prefix → σ of white noise (column units), applied after the model.
        rng: the random generator (draws are made in a fixed order: seeded results repeat).
        sample_rate_hz: sample rate of ``df`` [Hz] (for the low-pass filters).
    """
    out = df.copy()
    n = len(df)
    stance = (df[STANCE].astype(str).to_numpy() != "none").astype(float)
    L = float(level)
    M = NOISE_MODEL
    fs = sample_rate_hz
    quat_cols = list(BASE_QUATERNION)
    if L > 0:
        qn = rng.normal(0.0, M["q"] * L, size=(n, len(joint_names)))
        dqn = np.vstack([np.zeros((1, qn.shape[1])), np.diff(qn, axis=0) * fs])
        dqn = _butter_lowpass(dqn, M["dq_cutoff_hz"], fs)
        for k, (qc, dqc, tauc) in enumerate(zip(joint_columns(joint_names, "q"),
                                                joint_columns(joint_names, "dq"),
                                                joint_columns(joint_names, "tau"))):
            out[qc] = df[qc].to_numpy() + qn[:, k]
            out[dqc] = df[dqc].to_numpy() + dqn[:, k]
            tau = df[tauc].to_numpy()
            out[tauc] = tau + rng.normal(0.0, 1.0, n) * L * (M["tau_rel"] * np.abs(tau)
                                                             + M["tau_abs"])
        for grf, intrusion, base in zip(GRF_COLUMNS, INTRUSION_COLUMNS, BASE_POSITION):
            f = df[grf].to_numpy()
            out[grf] = f + stance * rng.normal(0.0, 1.0, n) * L * (
                M["grf_abs"] + M["grf_rel"] * np.abs(f))
            out[intrusion] = (df[intrusion].to_numpy()
                              + stance * rng.normal(0.0, M["intrusion"] * L, n))
            out[base] = df[base].to_numpy() + rng.normal(0.0, M["base_pos"] * L, n)
        vn = _butter_lowpass(rng.normal(0.0, 1.0, size=(n, 3)), M["base_v_cutoff_hz"], fs)
        vn *= M["base_v"] * L / max(float(np.std(vn)), 1e-12)
        for k, (vc, wc) in enumerate(zip(BASE_LINEAR_VELOCITY, BASE_ANGULAR_VELOCITY)):
            out[vc] = df[vc].to_numpy() + vn[:, k]
            out[wc] = df[wc].to_numpy() + rng.normal(0.0, M["base_w"] * L, n)
        quat = df[quat_cols].to_numpy(dtype=float)
        quat = _quat_noise(quat, math.radians(M["base_rot_deg"]) * L, rng)
        out[quat_cols] = quat
    for prefix, sigma in sorted(white.items(), key=lambda kv: len(kv[0])):
        cols = [c for c in df.columns if c.startswith(prefix) and c not in (TIME, STANCE)]
        for c in cols:
            mask = stance if c.startswith(("grf_", "intrusion_")) else 1.0
            out[c] = df[c].to_numpy(dtype=float) + mask * rng.normal(0.0, sigma, n)
        if any(c.startswith("base_q") for c in cols):
            quat = out[quat_cols].to_numpy(dtype=float)
            quat /= np.linalg.norm(quat, axis=1, keepdims=True)
            out[quat_cols] = quat
    return out


__all__ = ["NOISE_MODEL", "normalise_noise", "add_noise", "noise_prefixes",
           "check_noise_prefixes"]
