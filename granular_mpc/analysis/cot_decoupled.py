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

Integrals are trapezoidal over the samples; d is passed in (the CoM forward distance, see
:mod:`granular_mpc.analysis.cot`). The full CoT lives in :mod:`granular_mpc.analysis.cot`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import trapezoid

from ..exceptions import ConfigError
from ..robot.model import SIDES, Biped
from ..robot.planar import (frontal_selection, frontal_view, sagittal_selection,
                            sagittal_view)

ACTUATIONS = ("exact", "paper")


@dataclass(frozen=True)
class DecoupledEnergy:
    """Absolute mechanical work of the two planar models over a window.

    Attributes:
        sagittal_J: ∫ |(B_s τ_s)ᵀ q̇_s| dt [J].
        frontal_J: ∫ |(B_f τ_f)ᵀ q̇_f| dt [J].
        actuation: ``"exact"`` or ``"paper"`` (see the module docstring).
    """

    sagittal_J: float
    frontal_J: float
    actuation: str

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
    P_s = np.empty(n)
    P_f = np.empty(n)
    for side in SIDES:
        mask = (sides == side) | ((sides == "none") & (side == "left"))
        if not mask.any():
            continue
        sp, sk, sa = signs[side]
        Ss = sagittal_selection(side, sp, sk)
        Sf = frontal_selection(side, sa)
        dqs = _rates_from_actuated(Ss, dq_a[mask], dpitch[mask], 4)
        dqf = _rates_from_actuated(Sf, dq_a[mask], droll[mask], 1)
        tau_s = tau_a[mask] @ Ss            # τ_s = S_sᵀ τ_a, row-wise
        tau_f = tau_a[mask] @ Sf
        if actuation == "paper":
            tau_s[:, 4] = 0.0               # B_s = [I4 0]ᵀ
            tau_f[:, 0] = 0.0               # B_f = [0 I2 0]ᵀ
        P_s[mask] = np.sum(tau_s * dqs, axis=1)
        P_f[mask] = np.sum(tau_f * dqf, axis=1)
    return P_s, P_f


def decoupled_energy(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side, *,
                     biped: Biped | None = None, dtrunk_pitch=None, dtrunk_roll=None,
                     actuation: str = "exact") -> DecoupledEnergy:
    """∫|P_s| dt and ∫|P_f| dt [J] (trapezoidal), arguments as :func:`cot_decoupled`."""
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0) or not np.isfinite(t).all():
        raise ConfigError("times must be a finite, strictly increasing 1-D array of ≥ 2 "
                          "samples [s]", key="times")
    n = t.size
    if dtrunk_pitch is None:
        dtrunk_pitch = np.gradient(np.unwrap(_series(trunk_pitch, n, "trunk_pitch")), t)
    if dtrunk_roll is None:
        dtrunk_roll = np.gradient(np.unwrap(_series(trunk_roll, n, "trunk_roll")), t)
    P_s, P_f = decoupled_power(q_a, dq_a, tau_a, dtrunk_pitch, dtrunk_roll, stance_side,
                               biped=biped, actuation=actuation)
    return DecoupledEnergy(float(trapezoid(np.abs(P_s), t)),
                           float(trapezoid(np.abs(P_f), t)), actuation)


def cot_decoupled(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side, weight,
                  distance, *, biped: Biped | None = None, dtrunk_pitch=None,
                  dtrunk_roll=None, actuation: str = "exact") -> float:
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

    Raises:
        ConfigError: bad shapes, non-finite values, unknown stance side, W_r ≤ 0.
    """
    if not (np.isfinite(weight) and weight > 0.0):
        raise ConfigError("weight must be a positive force [N]", key="weight", value=weight)
    e = decoupled_energy(times, q_a, dq_a, tau_a, trunk_pitch, trunk_roll, stance_side,
                         biped=biped, dtrunk_pitch=dtrunk_pitch, dtrunk_roll=dtrunk_roll,
                         actuation=actuation)
    if not distance > 0.0:
        return float("nan")
    return e.total_J / (float(weight) * float(distance))


__all__ = ["cot_decoupled", "decoupled_energy", "decoupled_power", "DecoupledEnergy",
           "ACTUATIONS"]
