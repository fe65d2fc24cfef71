"""Coordinate maps between the biped's actuated joints and the paper's planar coordinates.

Sagittal: the link angles q^s (swing thigh, swing calf, stance thigh, stance calf, trunk;
absolute pitch about +y) from the hip-pitch and knee angles and the trunk pitch, and back;
frontal: the leg-line angles q^f (about +x) from the abduction angles and the trunk roll,
and back. Every map is linear (affine for the frontal angles), so it maps rates too, and the
torque maps are the transposes (power-preserving). The planar models themselves are in
:mod:`granular_mpc.dynamics.planar`, which re-exports these names.

Numbers: SI units; arrays are NumPy arrays (or nested sequences), one row per sample.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ConfigError
from ..robot.planar import FrontalView, SagittalView


def _actuator_rows(q_a) -> tuple[np.ndarray, bool]:
    """``q_a`` as (N, 6) rows [rad] and whether it was one (6,) vector."""
    q_a = np.asarray(q_a, dtype=float)
    qa = np.atleast_2d(q_a)
    if qa.shape[1] != 6:
        raise ConfigError(f"q_a must have 6 columns, got {q_a.shape}", key="q_a")
    return qa, q_a.ndim == 1


def sagittal_from_actuated(view: SagittalView, q_a, trunk_pitch) -> np.ndarray:
    """q^s from actuator angles and the trunk pitch (inverse of q_a = S_s q^s).

    θ_b = trunk pitch; θ_thigh = θ_b + s_p q_pitch; θ_calf = θ_thigh + s_k q_knee
    (abduction ignored: the sagittal projection). The map is linear, so it maps rates
    (q̇_a, pitch rate) to q̇^s as well.

    Args:
        view: sagittal parameters (stance side, joint signs).
        q_a: (6,) or (N, 6) actuator angles [rad] (rates [rad/s]).
        trunk_pitch: scalar or (N,) trunk pitch about +y [rad] (rate [rad/s]).

    Returns:
        (5,) or (N, 5) [θ_swing thigh, θ_swing calf, θ_stance thigh, θ_stance calf, θ_trunk].
    """
    qa, single = _actuator_rows(q_a)
    th_b = np.broadcast_to(np.asarray(trunk_pitch, dtype=float), (qa.shape[0],))
    out = np.empty((qa.shape[0], 5))
    out[:, 4] = th_b
    for k, side in enumerate((view.stance, view.swing)):   # k: 0 stance, 1 swing
        r = 0 if side == "left" else 3
        th_t = th_b + view.sign_pitch[k] * qa[:, r + 1]
        th_c = th_t + view.sign_knee[k] * qa[:, r + 2]
        ct = 2 if k == 0 else 0
        out[:, ct], out[:, ct + 1] = th_t, th_c
    return out[0] if single else out


def actuated_from_sagittal(view: SagittalView, q_sag) -> np.ndarray:
    """q_a = S_s q^s (6,) or (N, 6) [rad]; abduction entries are 0 (no sagittal content)."""
    q = np.asarray(q_sag, dtype=float)
    if q.shape[-1] != 5:
        raise ConfigError(f"q^s must have 5 entries, got {q.shape}", key="q_sag")
    return q @ view.selection.T


def sagittal_torques(view: SagittalView, tau_a) -> np.ndarray:
    """τ_s = (∂q_a/∂q^s)ᵀ τ_a = S_sᵀ τ_a (5,) or (N, 5) [N·m].

    Power-preserving: τ_sᵀ q̇^s = τ_aᵀ q̇_a over the hip-pitch and knee joints. Entry 5
    (trunk) is −(s_p,st τ_pitch,st + s_p,sw τ_pitch,sw), the reaction of the hip torques
    on the trunk, which the paper's B_s = [I₄ 0]ᵀ leaves out.
    """
    tau = np.asarray(tau_a, dtype=float)
    if tau.shape[-1] != 6:
        raise ConfigError(f"tau_a must have 6 entries, got {tau.shape}", key="tau_a")
    return tau @ view.selection


def _abd_cols(view: FrontalView) -> tuple[int, int]:
    return (0 if view.stance == "left" else 3), (0 if view.swing == "left" else 3)


def frontal_from_actuated(view: FrontalView, q_a, trunk_roll, *,
                          velocity: bool = False) -> np.ndarray:
    """q^f from actuator angles and the trunk roll (the frontal hip mapping, inverted).

    φ_st = φ_B + s_st q_abd,st, φ_sw = φ_B + s_sw q_abd,sw and
    q1f = φ_st + o_st, q2f = φ_B + o_B, q3f = φ_sw + o_sw (offsets from the geometry, see
    :class:`FrontalView`). With ``velocity=True`` the offsets are dropped (rates map).

    Args:
        view: frontal parameters.
        q_a: (6,) or (N, 6) actuator angles [rad] (rates [rad/s]).
        trunk_roll: scalar or (N,) trunk roll about +x [rad] (rate [rad/s]).
    """
    qa, single = _actuator_rows(q_a)
    ph_b = np.broadcast_to(np.asarray(trunk_roll, dtype=float), (qa.shape[0],))
    st, sw = _abd_cols(view)
    k = 0.0 if velocity else 1.0
    out = np.empty((qa.shape[0], 3))
    out[:, 0] = ph_b + view.sign_abd[0] * qa[:, st] + k * view.offset_stance
    out[:, 1] = ph_b + k * view.offset_trunk
    out[:, 2] = ph_b + view.sign_abd[1] * qa[:, sw] + k * view.offset_swing
    return out[0] if single else out


def actuated_from_frontal(view: FrontalView, q_front) -> np.ndarray:
    """Abduction angles from q^f, as a (6,) or (N, 6) actuator vector [rad] (other entries 0).

    Our form of the paper's hip mapping (paper: q1 = −q1f + q2f, q4 = π − q2f + q3f)::

        q_abd,st = s_st (q1f − q2f − o_st + o_B),   q_abd,sw = s_sw (q3f − q2f − o_sw + o_B)
    """
    q = np.asarray(q_front, dtype=float)
    if q.shape[-1] != 3:
        raise ConfigError(f"q^f must have 3 entries, got {q.shape}", key="q_front")
    st, sw = _abd_cols(view)
    out = np.zeros(q.shape[:-1] + (6,))
    out[..., st] = view.sign_abd[0] * (q[..., 0] - q[..., 1] - view.offset_stance
                                       + view.offset_trunk)
    out[..., sw] = view.sign_abd[1] * (q[..., 2] - q[..., 1] - view.offset_swing
                                       + view.offset_trunk)
    return out


def frontal_jacobian(view: FrontalView) -> np.ndarray:
    """∂q_a/∂q^f (6 × 3) [-] (constant; only the abduction rows are non-zero)."""
    return view.selection


def frontal_torques(view: FrontalView, tau_a) -> np.ndarray:
    """τ_f = (∂q_a/∂q^f)ᵀ τ_a (3,) or (N, 3) [N·m]::

        τ1f = s_st τ_abd,st,   τ2f = −(s_st τ_abd,st + s_sw τ_abd,sw),   τ3f = s_sw τ_abd,sw

    (paper: τ2f = τ1 − τ4, τ3f = τ4 with its sign conventions; its B_f drops τ1f).
    Power-preserving: τ_fᵀ q̇^f = τ_aᵀ q̇_a over the abduction joints.
    """
    tau = np.asarray(tau_a, dtype=float)
    if tau.shape[-1] != 6:
        raise ConfigError(f"tau_a must have 6 entries, got {tau.shape}", key="tau_a")
    return tau @ frontal_jacobian(view)


def stance_foot_pitch(view: SagittalView, q_s) -> float:
    """Pitch of the stance foot frame ``F`` about +y: θ_stance calf + mount pitch [rad]."""
    return float(np.asarray(q_s, dtype=float)[3] + view.foot_mount_pitch)


def contact_on_sole(view: SagittalView, q_s) -> bool:
    """True while C1 = arc centre − R ẑ lies on the sole arc (|foot pitch| ≤ half-angle)."""
    return abs(stance_foot_pitch(view, q_s)) <= view.foot_half_angle
