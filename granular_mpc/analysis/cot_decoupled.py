"""The paper's decoupled (sagittal + frontal) cost of transport (Sec. III-A)::

    CoT_dec = 1/(W_r d) · Σ_{i ∈ {s, f}} ∫_{t0}^{tf} |(B_i τ_i)ᵀ q̇_i| dt

with the planar coordinates and torques of :mod:`granular_mpc.dynamics.planar`:

* sagittal: q̇^s = rates of the absolute link pitches [swing thigh, swing calf, stance
  thigh, stance calf, trunk] [rad/s], τ_s = S_sᵀ τ_a [N·m];
* frontal: q̇^f = rates of [stance leg, hip line, swing leg] roll angles [rad/s],
  τ_f = (∂q_a/∂q^f)ᵀ τ_a [N·m].

The contact coordinates (x_s, z_s, y_s) carry no actuator torque (B has zero rows there),
so only the angle rates enter. Two choices of B (``actuation``):

* ``"exact"`` (default): B = [I; 0], every generalised torque component kept. Then
  (B_s τ_s)ᵀ q̇_s = Σ τ_j q̇_j over the hip-pitch and knee joints and (B_f τ_f)ᵀ q̇_f =
  Σ τ_j q̇_j over the abduction joints (the maps preserve power), so
  CoT_dec = (∫|P_sag| + ∫|P_front|)/(W_r d) ≥ the full CoT (∫|P_sag + P_front|)/(W_r d).
* ``"paper"``: the paper's B_s = [I₄ 0]ᵀ and B_f = [0 I₂ 0]ᵀ — the trunk component of τ_s
  and the stance-leg component of τ_f are dropped, i.e. P_s = P_sag + (s τ_pitch,L +
  s τ_pitch,R) θ̇_trunk and P_f = P_front − τ_1f q̇_1f. These need the trunk pitch/roll rates
  and the stance side of every sample.

**Readings** (as for the full CoT, :mod:`granular_mpc.analysis.cot`). Each planar power is
split over the actuators: joint j's share of the sagittal power is
p^s_j = τ_j [S_s D_s q̇_s]_j with D_s = B_s B_sᵀ (identity for ``"exact"``, the trunk rate
zeroed for ``"paper"``), so Σ_j p^s_j = (B_s τ_s)ᵀ q̇_s; likewise p^f_j with S_f, D_f
(:func:`decoupled_joint_power`). Then, with i ∈ {s, f}:

* ``"abs_net"`` (the literal paper form, what :func:`cot_decoupled` computes by default):
  E = Σ_i ∫ |Σ_j p^i_j| dt;
* ``"abs_per_joint"`` (the package's default reading): E = Σ_i ∫ Σ_j |p^i_j| dt;
* ``"positive"``: E = Σ_i ∫ Σ_j max(p^i_j, 0) dt.

With ``"exact"`` actuation p^s_j + p^f_j = τ_j q̇_j, so the decoupled ``abs_per_joint`` and
``positive`` equal the full ones, and only ``abs_net`` differs (|P_s| + |P_f| ≥ |P_s + P_f|).

Integrals are trapezoidal over the samples; d is passed in (the CoM forward distance, see
:mod:`granular_mpc.analysis.cot`). The full CoT lives in :mod:`granular_mpc.analysis.cot`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import trapezoid

from ..exceptions import ConfigError
from .cot import COT_READINGS, combine_joint_powers, reading_mode
from ..robot.model import SIDES, Biped
from ..robot.planar import (frontal_selection, frontal_view, sagittal_selection,
                            sagittal_view)

ACTUATIONS = ("exact", "paper")


@dataclass(frozen=True)
class DecoupledEnergy:
    """Mechanical work of the two planar models over a window, under one reading.

    Attributes:
        sagittal_J: ∫ |(B_s τ_s)ᵀ q̇_s| dt [J] (reading ``abs_net``; other readings: the
            module docstring).
        frontal_J: ∫ |(B_f τ_f)ᵀ q̇_f| dt [J] (same).
        actuation: ``"exact"`` or ``"paper"`` (see the module docstring).
        reading: ``"abs_net"`` (default), ``"abs_per_joint"`` or ``"positive"``.
    """

    sagittal_J: float
    frontal_J: float
    actuation: str
    reading: str = "abs_net"

    @property
    def total_J(self) -> float:
        return self.sagittal_J + self.frontal_J


def _signs(biped: Biped | None) -> dict[str, tuple]:
    """Joint-axis signs per stance side: (sign_pitch, sign_knee, sign_abd), each
    [stance, swing]. Without a robot: the package convention (pitch and knee about +y,
    abduction about +x, docs/notation.md), i.e. all +1."""
    out = {}
    for side in SIDES:
        if biped is None:
            out[side] = ((1, 1), (1, 1), (1, 1))
        else:
            sv = sagittal_view(biped, side)
            fv = frontal_view(biped, side)
            out[side] = (sv.sign_pitch, sv.sign_knee, fv.sign_abd)
    return out


def _rates_from_actuated(S: np.ndarray, dq_a: np.ndarray, rate_ref: np.ndarray, ref: int
                         ) -> np.ndarray:
    """Planar angle rates q̇ (N × n) with S q̇ = q̇_a and q̇[ref] = rate_ref, row-wise.

    S (6 × n) maps planar angles to actuator angles through differences of angles, so its
    null space is the common rotation 1: q̇ = S⁺ q̇_a + (rate_ref − (S⁺ q̇_a)[ref]) 1.
    """
    p = dq_a @ np.linalg.pinv(S).T
    return p + (rate_ref - p[:, ref])[:, None]


def _stance_array(stance_side, n: int) -> np.ndarray:
    if isinstance(stance_side, str):
        arr = np.full(n, stance_side, dtype=object)
    else:
        arr = np.asarray(list(stance_side), dtype=object)
    if arr.shape != (n,):
        raise ConfigError(f"stance_side must be a string or {n} values, got {arr.shape}",
                          key="stance_side")
    bad = sorted({str(s) for s in arr if s not in (*SIDES, "none")})
    if bad:
        raise ConfigError(f"unknown stance side(s) {bad}", key="stance_side", value=bad,
                          allowed="left | right | none")
    return arr


def _series(x, n: int, name: str, cols: int | None = None) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    shape = (n,) if cols is None else (n, cols)
    if a.shape != shape:
        raise ConfigError(f"{name} must have shape {shape}, got {a.shape}", key=name)
    if not np.isfinite(a).all():
        raise ConfigError(f"{name} has non-finite values", key=name)
    return a


def decoupled_joint_power(q_a, dq_a, tau_a, dtrunk_pitch, dtrunk_roll, stance_side, *,
                          biped: Biped | None = None, actuation: str = "exact"
                          ) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample, per-actuator shares (p^s, p^f) of the planar powers [W], each (N, 6).

    p^s_j = τ_j [S_s D_s q̇_s]_j and p^f_j = τ_j [S_f D_f q̇_f]_j (module docstring); row sums
    are the powers of :func:`decoupled_power`. Arguments as :func:`decoupled_power`.
    """
    if actuation not in ACTUATIONS:
        raise ConfigError(f"unknown actuation {actuation!r}", key="actuation",
                          value=actuation, allowed=" | ".join(ACTUATIONS))
    dq_a = np.atleast_2d(np.asarray(dq_a, dtype=float))
    n = dq_a.shape[0]
    _series(q_a, n, "q_a", 6)
    dq_a = _series(dq_a, n, "dq_a", 6)
    tau_a = _series(tau_a, n, "tau_a", 6)
    dpitch = _series(np.broadcast_to(dtrunk_pitch, (n,)), n, "dtrunk_pitch")
    droll = _series(np.broadcast_to(dtrunk_roll, (n,)), n, "dtrunk_roll")
    sides = _stance_array(stance_side, n)
    if actuation == "paper" and np.any(sides == "none"):
        idx = np.flatnonzero(sides == "none")[:10].tolist()
        raise ConfigError("the paper's B_s/B_f need a stance leg in every sample; samples "
                          f"{idx} have stance 'none'", key="stance_side")
    signs = _signs(biped)
    p_s = np.zeros((n, 6))
    p_f = np.zeros((n, 6))
    for side in SIDES:
        mask = (sides == side) | ((sides == "none") & (side == "left"))
        if not mask.any():
            continue
        sp, sk, sa = signs[side]
        Ss = sagittal_selection(side, sp, sk)
        Sf = frontal_selection(side, sa)
        dqs = _rates_from_actuated(Ss, dq_a[mask], dpitch[mask], 4)
        dqf = _rates_from_actuated(Sf, dq_a[mask], droll[mask], 1)
        if actuation == "paper":
            dqs[:, 4] = 0.0                 # B_s = [I4 0]ᵀ: no torque on the trunk angle
            dqf[:, 0] = 0.0                 # B_f = [0 I2 0]ᵀ: none on the stance-leg angle
        p_s[mask] = tau_a[mask] * (dqs @ Ss.T)   # τ_j [S_s D_s q̇_s]_j, row-wise
        p_f[mask] = tau_a[mask] * (dqf @ Sf.T)
    return p_s, p_f


def decoupled_power(q_a, dq_a, tau_a, dtrunk_pitch, dtrunk_roll, stance_side, *,
                    biped: Biped | None = None, actuation: str = "exact"
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample planar powers ((B_s τ_s)ᵀ q̇_s, (B_f τ_f)ᵀ q̇_f) [W].

    Args:
        q_a: (N, 6) actuator angles [rad] (unused by the rates; kept for shape checks).
        dq_a: (N, 6) actuator rates [rad/s]; tau_a: (N, 6) torques [N·m], actuator order.
        dtrunk_pitch, dtrunk_roll: (N,) trunk pitch (about +y) and roll (about +x) rates
            [rad/s].
        stance_side: ``"left"``/``"right"``, or one of ``"left"``, ``"right"``, ``"none"``
            per sample (``"none"`` only with ``actuation="exact"``).
        biped: robot whose joint-axis signs are used (default: +y / +x axes).
        actuation: ``"exact"`` or ``"paper"`` (module docstring).
    """
    p_s, p_f = decoupled_joint_power(q_a, dq_a, tau_a, dtrunk_pitch, dtrunk_roll, stance_side,
                                     biped=biped, actuation=actuation)
    return p_s.sum(axis=1), p_f.sum(axis=1)


def _joint_powers(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side, *, biped,
                  dtrunk_pitch, dtrunk_roll, actuation):
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0) or not np.isfinite(t).all():
        raise ConfigError("times must be a finite, strictly increasing 1-D array of ≥ 2 "
                          "samples [s]", key="times")
    n = t.size
    if dtrunk_pitch is None:
        dtrunk_pitch = np.gradient(np.unwrap(_series(trunk_pitch, n, "trunk_pitch")), t)
    if dtrunk_roll is None:
        dtrunk_roll = np.gradient(np.unwrap(_series(trunk_roll, n, "trunk_roll")), t)
    p_s, p_f = decoupled_joint_power(q_a, dq_a, tau_a, dtrunk_pitch, dtrunk_roll, stance_side,
                                     biped=biped, actuation=actuation)
    return t, p_s, p_f


def _energy(t, p_s, p_f, actuation: str, reading: str) -> DecoupledEnergy:
    mode = reading_mode(reading)
    return DecoupledEnergy(float(trapezoid(combine_joint_powers(p_s, mode), t)),
                           float(trapezoid(combine_joint_powers(p_f, mode), t)), actuation,
                           reading)


def decoupled_energy(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side, *,
                     biped: Biped | None = None, dtrunk_pitch=None, dtrunk_roll=None,
                     actuation: str = "exact", reading: str = "abs_net") -> DecoupledEnergy:
    """Sagittal and frontal work [J] (trapezoidal) under ``reading``; default ``"abs_net"``:
    ∫|P_s| dt and ∫|P_f| dt. Other arguments as :func:`cot_decoupled`."""
    reading_mode(reading)
    t, p_s, p_f = _joint_powers(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side,
                                biped=biped, dtrunk_pitch=dtrunk_pitch,
                                dtrunk_roll=dtrunk_roll, actuation=actuation)
    return _energy(t, p_s, p_f, actuation, reading)


def cot_decoupled(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side, weight,
                  distance, *, biped: Biped | None = None, dtrunk_pitch=None,
                  dtrunk_roll=None, actuation: str = "exact", reading: str = "abs_net") -> float:
    """Decoupled CoT = (E_s + E_f) / (W_r d) [-] (paper Sec. III-A, module docstring).

    Args:
        times: (N,) sample times [s], strictly increasing.
        q_a, dq_a, tau_a: (N, 6) actuator angles [rad], rates [rad/s], torques [N·m]
            (order: left abd, pitch, knee, right abd, pitch, knee).
        trunk_pitch, trunk_roll: (N,) trunk pitch about +y and roll about +x [rad]; their
            rates are taken by finite differences unless ``dtrunk_pitch``/``dtrunk_roll``
            [rad/s] are given. (With ``actuation="exact"`` the result does not depend on
            them.)
        stance_side: ``"left"``/``"right"`` or one value per sample (``"none"`` allowed
            with ``actuation="exact"``).
        weight: W_r = m g [N] (> 0).
        distance: d, forward distance of the CoM [m]; NaN is returned if d ≤ 0.
        biped: the robot (joint-axis signs); default: the package axis conventions.
        actuation: ``"exact"`` (default) or ``"paper"``.
        reading: ``"abs_net"`` (default, the literal paper form), ``"abs_per_joint"`` or
            ``"positive"`` (module docstring).

    Raises:
        ConfigError: bad shapes, non-finite values, unknown stance side, W_r ≤ 0.
        ValueError: unknown reading.
    """
    if not (np.isfinite(weight) and weight > 0.0):
        raise ConfigError("weight must be a positive force [N]", key="weight", value=weight)
    e = decoupled_energy(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side,
                         biped=biped, dtrunk_pitch=dtrunk_pitch, dtrunk_roll=dtrunk_roll,
                         actuation=actuation, reading=reading)
    if not distance > 0.0:
        return float("nan")
    return e.total_J / (float(weight) * float(distance))


@dataclass(frozen=True)
class DecoupledCotReadings:
    """Decoupled CoT of one window under each reading.

    Attributes:
        abs_per_joint, abs_net, positive: CoT = (E_s + E_f) / (W_r d) [-] (NaN if d ≤ 0).
        energies: the :class:`DecoupledEnergy` of each reading, in :data:`COT_READINGS`
            order.
        weight_N: W_r [N]; distance_m: d [m]; actuation: ``"exact"`` or ``"paper"``.
    """

    abs_per_joint: float
    abs_net: float
    positive: float
    energies: tuple[DecoupledEnergy, ...]
    weight_N: float
    distance_m: float
    actuation: str

    def get(self, reading: str) -> float:
        """CoT under ``reading`` [-]."""
        reading_mode(reading)
        return getattr(self, reading)

    def cots(self) -> dict[str, float]:
        """``{reading: CoT}`` for every reading [-]."""
        return {r: self.get(r) for r in COT_READINGS}


def cot_decoupled_readings(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side,
                           weight, distance, *, biped: Biped | None = None, dtrunk_pitch=None,
                           dtrunk_roll=None, actuation: str = "exact") -> DecoupledCotReadings:
    """Decoupled CoT under every reading at once; arguments as :func:`cot_decoupled`."""
    if not (np.isfinite(weight) and weight > 0.0):
        raise ConfigError("weight must be a positive force [N]", key="weight", value=weight)
    t, p_s, p_f = _joint_powers(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side,
                                biped=biped, dtrunk_pitch=dtrunk_pitch,
                                dtrunk_roll=dtrunk_roll, actuation=actuation)
    energies = tuple(_energy(t, p_s, p_f, actuation, r) for r in COT_READINGS)
    d = float(distance)
    cot = [e.total_J / (float(weight) * d) if d > 0.0 else float("nan") for e in energies]
    return DecoupledCotReadings(*cot, energies=energies, weight_N=float(weight), distance_m=d,
                                actuation=actuation)


__all__ = ["cot_decoupled", "decoupled_energy", "decoupled_power", "decoupled_joint_power",
           "DecoupledEnergy", "DecoupledCotReadings", "cot_decoupled_readings", "ACTUATIONS"]
