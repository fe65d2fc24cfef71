"""The paper's planar augmented models (sagittal 7-DoF, frontal 5-DoF), derived with
CasADi SX Lagrangian mechanics from the link parameters of :mod:`granular_mpc.robot.planar`.

Sagittal (paper Sec. II, "Sagittal Dynamics")::

    q_s = [q1 q2 q3 q4 q5 x_s z_s] ∈ R⁷
        q1, q2 = pitch (about +y) of the swing thigh and swing calf,
        q3, q4 = pitch of the stance thigh and stance calf,
        q5     = pitch of the trunk                                    [rad]
        (x_s, z_s) = contact point C1 of the stance foot in W           [m]

Frontal (paper Sec. II, "Frontal Dynamics")::

    q_f = [q1f q2f q3f y_s z_s] ∈ R⁵
        q1f = stance leg line (arc centre → abduction axis) from the upward vertical,
        q2f = hip line (stance → swing abduction axis) from the downward vertical,
        q3f = swing leg line (abduction axis → arc centre) from the downward vertical,
        all about +x [rad];  (y_s, z_s) = C1 in W [m]

C1 is the lowest point of the stance sole arc; the chain starts at the arc centre
A = C1 + R ẑ (valid while C1 lies on the sole, |foot pitch| ≤ arc half-angle; in the frontal
plane C1 is the point R below the arc centre, the same z_s as the sagittal model).

Both obey (paper eqs. sagittal / frontalDyn)::

    D(q) q̈ + C(q, q̇) q̇ + G(q) = B τ + Jᵀ F

with T = Σ_i ½ m_i |ṗ_i|² + ½ I_i θ̇_i²  (p_i COM of link i, θ_i its absolute angle),
V = Σ_i m_i g z_i, and

    D = Σ_i m_i J_iᵀ J_i + I_i e_iᵀ e_i         (J_i = ∂p_i/∂q, e_i = ∂θ_i/∂q)
    C_kj = Σ_i ½ (∂D_kj/∂q_i + ∂D_ki/∂q_j − ∂D_ij/∂q_k) q̇_i      (Christoffel form)
    G = ∂V/∂q,   J = ∂(contact coordinates)/∂q = [0 I₂]            (2 × n)

τ are the generalised forces on the link angles obtained from the actuator torques by the
power-preserving maps below: τ_s = S_sᵀ τ_a ∈ R⁵ and τ_f ∈ R³, so B = [I; 0]. The paper's
B_s = [I₄ 0]ᵀ and B_f = [0 I₂ 0]ᵀ keep only some of these components (the reaction of
the hip torques on the trunk, resp. on the stance leg, is dropped); they are given as
:attr:`PlanarModel.B_paper` for comparison — see docs/planar-models.md.

Numbers: SI units; every array argument is a NumPy array (or nested sequence).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import casadi as ca
import numpy as np

from ..exceptions import ConfigError
from ..robot.model import Biped
from ..robot.planar import (FrontalView, SagittalView, check_side, frontal_view,
                            sagittal_selection, sagittal_view)
from .planar_maps import (actuated_from_frontal, actuated_from_sagittal, contact_on_sole,
                          frontal_from_actuated, frontal_jacobian, frontal_torques,
                          sagittal_from_actuated, sagittal_torques, stance_foot_pitch)

SAGITTAL_COORDINATES = ("q1_swing_thigh", "q2_swing_calf", "q3_stance_thigh",
                        "q4_stance_calf", "q5_trunk", "x_s", "z_s")
FRONTAL_COORDINATES = ("q1f_stance_leg", "q2f_hip_line", "q3f_swing_leg", "y_s", "z_s")


# ------------------------------------------------------------------------------- model
@dataclass(frozen=True, eq=False)
class PlanarModel:
    """An immutable planar augmented model and its compiled CasADi functions.

    Attributes:
        kind: ``"sagittal"`` or ``"frontal"``.
        view: the link parameters it was built from.
        coordinates: names of the generalised coordinates.
        n_angles: number of link angles (5 sagittal, 3 frontal); the last two
            coordinates are the contact point C1 [m].
        B: (n × n_angles) input matrix [I; 0] of the generalised link torques.
        B_paper: the paper's input matrix ([I₄ 0]ᵀ sagittal, [0 I₂ 0]ᵀ frontal).
        fn_D, fn_C, fn_G, fn_J: CasADi functions q → D, (q, q̇) → C, q → G, q → J.
        fn_forward: (q, q̇, τ, F) → q̈.
        fn_energy: (q, q̇) → (T, V) [J].
        fn_points: q → 2 × k matrix of named points (columns, :attr:`point_names`) [m].
        fn_swing_jacobian: q → ∂(swing-foot C)/∂q (2 × n).
        fn_rk4: (x = [q; q̇], τ, F, h) → x after one classical RK4 step of h [s].
        point_names: names of the columns of ``fn_points``.
    """

    kind: str
    view: SagittalView | FrontalView
    coordinates: tuple[str, ...]
    n_angles: int
    B: np.ndarray
    B_paper: np.ndarray
    fn_D: ca.Function
    fn_C: ca.Function
    fn_G: ca.Function
    fn_J: ca.Function
    fn_forward: ca.Function
    fn_energy: ca.Function
    fn_points: ca.Function
    fn_swing_jacobian: ca.Function
    fn_rk4: ca.Function
    point_names: tuple[str, ...]
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def nq(self) -> int:
        return len(self.coordinates)

    @property
    def stance(self) -> str:
        return self.view.stance


# ------------------------------------------------------------------------------- kinematics
def _rot_y(theta, v):
    """World (x, z) of a link-frame vector v = (b_x, b_z) for pitch θ about +y."""
    c, s = ca.cos(theta), ca.sin(theta)
    return ca.vertcat(v[0] * c + v[1] * s, -v[0] * s + v[1] * c)


def _rot_x(phi, v):
    """World (y, z) of a link-frame vector v = (b_y, b_z) for roll φ about +x."""
    c, s = ca.cos(phi), ca.sin(phi)
    return ca.vertcat(v[0] * c - v[1] * s, v[0] * s + v[1] * c)


def _vec(t) -> ca.DM:
    return ca.DM([float(t[0]), float(t[1])])


def _compile(kind, view, q, dq, bodies, points, swing_contact, n_angles, coordinates,
             B_paper) -> PlanarModel:
    """Lagrangian → D, C, G, J and the compiled functions (see the module docstring).

    ``bodies``: list of (m [kg], I [kg m²], p_com (2×1 SX), θ (SX)).
    """
    n = q.shape[0]
    g = view.gravity
    D = ca.SX.zeros(n, n)
    V = 0
    T = 0
    for m, inertia, p, th in bodies:
        Jp = ca.jacobian(p, q)
        e = ca.jacobian(th, q)
        D += m * (Jp.T @ Jp) + inertia * (e.T @ e)
        v = Jp @ dq
        w = e @ dq
        T += 0.5 * m * ca.dot(v, v) + 0.5 * inertia * w * w
        V += m * g * p[1]
    # Christoffel form: C = ½ (Ḋ + ∂(D q̇)/∂q − ∂(D q̇)/∂qᵀ), Ḋ = Σ_i ∂D/∂q_i q̇_i
    Ddot = ca.reshape(ca.jacobian(ca.vec(D), q) @ dq, n, n)
    Jdq = ca.jacobian(D @ dq, q)
    C = 0.5 * (Ddot + Jdq - Jdq.T)
    G = ca.gradient(V, q)
    contact = q[n - 2:n]
    J = ca.jacobian(contact, q)
    B = np.vstack([np.eye(n_angles), np.zeros((n - n_angles, n_angles))])
    tau = ca.SX.sym("tau", n_angles)
    F = ca.SX.sym("F", 2)
    rhs = ca.DM(B) @ tau + J.T @ F - C @ dq - G
    ddq = ca.solve(D, rhs)
    x = ca.vertcat(q, dq)
    h = ca.SX.sym("h")
    fwd = ca.Function("forward", [q, dq, tau, F], [ddq])

    def f(xx):
        return ca.vertcat(xx[n:], fwd(xx[:n], xx[n:], tau, F))

    k1 = f(x)
    k2 = f(x + 0.5 * h * k1)
    k3 = f(x + 0.5 * h * k2)
    k4 = f(x + h * k3)
    x_next = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    names = tuple(points)
    P = ca.horzcat(*[points[k] for k in names])
    return PlanarModel(
        kind=kind, view=view, coordinates=coordinates, n_angles=n_angles, B=B,
        B_paper=B_paper,
        fn_D=ca.Function(f"{kind}_D", [q], [D], ["q"], ["D"]),
        fn_C=ca.Function(f"{kind}_C", [q, dq], [C], ["q", "dq"], ["C"]),
        fn_G=ca.Function(f"{kind}_G", [q], [G], ["q"], ["G"]),
        fn_J=ca.Function(f"{kind}_J", [q], [J], ["q"], ["J"]),
        fn_forward=ca.Function(f"{kind}_forward", [q, dq, tau, F], [ddq],
                               ["q", "dq", "tau", "F"], ["ddq"]),
        fn_energy=ca.Function(f"{kind}_energy", [q, dq], [T, V], ["q", "dq"], ["T", "V"]),
        fn_points=ca.Function(f"{kind}_points", [q], [P], ["q"], ["P"]),
        fn_swing_jacobian=ca.Function(f"{kind}_J_swing", [q],
                                      [ca.jacobian(swing_contact, q)], ["q"], ["J_swing"]),
        fn_rk4=ca.Function(f"{kind}_rk4", [x, tau, F, h], [x_next],
                           ["x", "tau", "F", "h"], ["x_next"]),
        point_names=names)


def sagittal_model(view: SagittalView) -> PlanarModel:
    """Build the sagittal 7-DoF augmented model from a :class:`SagittalView`.

    Chain (link frames rotated by R_y(θ), see :func:`_rot_y`; c = link COM, t = link tip,
    h = hip-pitch joints in the trunk frame)::

        A      = (x_s, z_s + R)                        stance sole-arc centre
        K_st   = A − R(q4) t_calf,st                   stance knee
        H_st   = K_st − R(q3) t_thigh,st               stance hip
        O_B    = H_st − R(q5) h_st                      trunk frame origin
        H_sw   = O_B + R(q5) h_sw,   K_sw = H_sw + R(q1) t_thigh,sw,
        A_sw   = K_sw + R(q2) t_calf,sw,   C_sw = A_sw − (0, R)
        COM of link i = (its frame origin) + R(θ_i) c_i
    """
    q = ca.SX.sym("q", 7)
    dq = ca.SX.sym("dq", 7)
    th_wt, th_wc, th_st, th_sc, th_b, xs, zs = (q[i] for i in range(7))
    R = view.foot_radius
    A = ca.vertcat(xs, zs + R)
    K_st = A - _rot_y(th_sc, _vec(view.calf_stance.tip))
    H_st = K_st - _rot_y(th_st, _vec(view.thigh_stance.tip))
    O_B = H_st - _rot_y(th_b, _vec(view.hip_stance))
    H_sw = O_B + _rot_y(th_b, _vec(view.hip_swing))
    K_sw = H_sw + _rot_y(th_wt, _vec(view.thigh_swing.tip))
    A_sw = K_sw + _rot_y(th_wc, _vec(view.calf_swing.tip))
    C_sw = A_sw - ca.vertcat(0, R)
    coms = {
        "com_swing_thigh": H_sw + _rot_y(th_wt, _vec(view.thigh_swing.com)),
        "com_swing_calf": K_sw + _rot_y(th_wc, _vec(view.calf_swing.com)),
        "com_stance_thigh": H_st + _rot_y(th_st, _vec(view.thigh_stance.com)),
        "com_stance_calf": K_st + _rot_y(th_sc, _vec(view.calf_stance.com)),
        "com_trunk": O_B + _rot_y(th_b, _vec(view.trunk.com)),
    }
    links = view.links
    angles = (th_wt, th_wc, th_st, th_sc, th_b)
    bodies = [(lk.mass, lk.inertia, p, th) for lk, p, th in zip(links, coms.values(), angles)]
    M = view.total_mass
    com = sum((lk.mass * p for lk, p in zip(links, coms.values())), ca.SX.zeros(2)) / M
    points = {"contact_stance": ca.vertcat(xs, zs), "arc_stance": A, "knee_stance": K_st,
              "hip_stance": H_st, "trunk_origin": O_B, "hip_swing": H_sw, "knee_swing": K_sw,
              "arc_swing": A_sw, "contact_swing": C_sw, **coms, "com": com}
    B_paper = np.vstack([np.eye(4), np.zeros((3, 4))])
    return _compile("sagittal", view, q, dq, bodies, points, C_sw, 5, SAGITTAL_COORDINATES,
                    B_paper)


def frontal_model(view: FrontalView) -> PlanarModel:
    """Build the frontal 5-DoF augmented model from a :class:`FrontalView`.

    Link rolls φ = line angle − offset (φ_st = q1f − o_st, φ_B = q2f − o_B,
    φ_sw = q3f − o_sw); link frames rotated by R_x(φ) (:func:`_rot_x`)::

        A    = (y_s, z_s + R)                  stance sole-arc centre
        H_st = A − R(φ_st) t_leg,st            stance abduction axis
        O_B  = H_st − R(φ_B) h_st              trunk frame origin
        H_sw = O_B + R(φ_B) h_sw,   A_sw = H_sw + R(φ_sw) t_leg,sw,   C_sw = A_sw − (0, R)
        COM of link i = (its frame origin) + R(φ_i) c_i
    """
    q = ca.SX.sym("q", 5)
    dq = ca.SX.sym("dq", 5)
    q1, q2, q3, ys, zs = (q[i] for i in range(5))
    ph_st = q1 - view.offset_stance
    ph_b = q2 - view.offset_trunk
    ph_sw = q3 - view.offset_swing
    R = view.foot_radius
    A = ca.vertcat(ys, zs + R)
    H_st = A - _rot_x(ph_st, _vec(view.leg_stance.tip))
    O_B = H_st - _rot_x(ph_b, _vec(view.hip_stance))
    H_sw = O_B + _rot_x(ph_b, _vec(view.hip_swing))
    A_sw = H_sw + _rot_x(ph_sw, _vec(view.leg_swing.tip))
    C_sw = A_sw - ca.vertcat(0, R)
    coms = {
        "com_stance_leg": H_st + _rot_x(ph_st, _vec(view.leg_stance.com)),
        "com_trunk": O_B + _rot_x(ph_b, _vec(view.trunk.com)),
        "com_swing_leg": H_sw + _rot_x(ph_sw, _vec(view.leg_swing.com)),
    }
    links = view.links
    bodies = [(lk.mass, lk.inertia, p, th)
              for lk, p, th in zip(links, coms.values(), (ph_st, ph_b, ph_sw))]
    M = view.total_mass
    com = sum((lk.mass * p for lk, p in zip(links, coms.values())), ca.SX.zeros(2)) / M
    points = {"contact_stance": ca.vertcat(ys, zs), "arc_stance": A, "hip_stance": H_st,
              "trunk_origin": O_B, "hip_swing": H_sw, "arc_swing": A_sw,
              "contact_swing": C_sw, **coms, "com": com}
    B_paper = np.zeros((5, 2))
    B_paper[1, 0] = B_paper[2, 1] = 1.0
    return _compile("frontal", view, q, dq, bodies, points, C_sw, 3, FRONTAL_COORDINATES,
                    B_paper)


def build_planar_models(biped: Biped, stance: str = "left",
                        reference_joints: Sequence[float] | None = None
                        ) -> tuple[PlanarModel, PlanarModel]:
    """(sagittal, frontal) models of ``biped`` for one stance side.

    Args:
        biped: the 3-D robot.
        stance: ``"left"`` or ``"right"``.
        reference_joints: actuator angles [rad] at which the frontal legs are frozen
            (default: the standing pose).
    """
    return (sagittal_model(sagittal_view(biped, stance)),
            frontal_model(frontal_view(biped, stance, reference_joints)))


# ------------------------------------------------------------------------------- numpy API
def _arr(x, n: int, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float).reshape(-1)
    if a.shape != (n,):
        raise ConfigError(f"{name} must have {n} entries, got shape {np.shape(x)}", key=name)
    return a


def mass_matrix(model: PlanarModel, q) -> np.ndarray:
    """D(q) [kg, kg·m, kg·m²] (n × n), symmetric positive definite."""
    return np.array(model.fn_D(_arr(q, model.nq, "q")))


def coriolis_matrix(model: PlanarModel, q, dq) -> np.ndarray:
    """C(q, q̇) in Christoffel form (Ḋ − 2C skew-symmetric) (n × n)."""
    return np.array(model.fn_C(_arr(q, model.nq, "q"), _arr(dq, model.nq, "dq")))


def gravity_vector(model: PlanarModel, q) -> np.ndarray:
    """G(q) = ∂V/∂q [N, N·m] (n,)."""
    return np.array(model.fn_G(_arr(q, model.nq, "q"))).reshape(-1)


def contact_jacobian(model: PlanarModel, q) -> np.ndarray:
    """J = ∂(contact coordinates)/∂q (2 × n) [-]; rows (x_s, z_s) or (y_s, z_s)."""
    return np.array(model.fn_J(_arr(q, model.nq, "q")))


def swing_contact_jacobian(model: PlanarModel, q) -> np.ndarray:
    """∂(swing-foot arc bottom in W)/∂q (2 × n) [m/rad, -]."""
    return np.array(model.fn_swing_jacobian(_arr(q, model.nq, "q")))


def forward_dynamics(model: PlanarModel, q, dq, tau=None, F=None) -> np.ndarray:
    """q̈ = D⁻¹ (B τ + Jᵀ F − C q̇ − G).

    Args:
        q, dq: coordinates [rad, m] and rates [rad/s, m/s] (n,).
        tau: generalised torques on the link angles τ_s (5) / τ_f (3) [N·m]
            (from :func:`sagittal_torques` / :func:`frontal_torques`); default 0.
        F: force of the ground on the stance foot at C1, (F_x, F_z) / (F_y, F_z) [N];
            default 0.
    """
    tau = np.zeros(model.n_angles) if tau is None else _arr(tau, model.n_angles, "tau")
    F = np.zeros(2) if F is None else _arr(F, 2, "F")
    return np.array(model.fn_forward(_arr(q, model.nq, "q"), _arr(dq, model.nq, "dq"),
                                     tau, F)).reshape(-1)


def inverse_dynamics(model: PlanarModel, q, dq, ddq) -> np.ndarray:
    """D q̈ + C q̇ + G [N, N·m] (n,): the generalised force B τ + Jᵀ F that produces ``ddq``.
    Its last two entries are the ground force (F_x, F_z) / (F_y, F_z) [N]."""
    q = _arr(q, model.nq, "q")
    dq = _arr(dq, model.nq, "dq")
    ddq = _arr(ddq, model.nq, "ddq")
    return (mass_matrix(model, q) @ ddq + coriolis_matrix(model, q, dq) @ dq
            + gravity_vector(model, q))


def energy(model: PlanarModel, q, dq) -> tuple[float, float]:
    """(kinetic T, potential V) [J]; V = Σ m_i g z_i with z measured in W (z = 0 datum)."""
    T, V = model.fn_energy(_arr(q, model.nq, "q"), _arr(dq, model.nq, "dq"))
    return float(T), float(V)


def points(model: PlanarModel, q) -> dict[str, np.ndarray]:
    """Named points (joints, arc centres, contact points, link COMs, whole-body COM) in
    W-plane coordinates [m]: (x, z) sagittal, (y, z) frontal."""
    P = np.array(model.fn_points(_arr(q, model.nq, "q")))
    return {name: P[:, i] for i, name in enumerate(model.point_names)}


def simulate_rk4(model: PlanarModel, q0, dq0, tau, F=None, *, dt: float,
                 n_steps: int) -> np.ndarray:
    """Integrate q̈ = forward(q, q̇, τ, F) with classical RK4 (one compiled CasADi call).

    Args:
        q0, dq0: initial state (n,).
        tau: (n_angles,) held, or (n_steps, n_angles) per step [N·m].
        F: (2,) held, or (n_steps, 2) per step [N]; default 0.
        dt: step h [s]; n_steps: number of steps.

    Returns:
        (n_steps + 1, 2n) states [q, q̇], first row the initial state.
    """
    if n_steps < 1 or not dt > 0.0:
        raise ConfigError("simulate_rk4 needs n_steps ≥ 1 and dt > 0", key="dt", value=dt)
    n, na = model.nq, model.n_angles
    tau = np.asarray(tau, dtype=float)
    tau = np.tile(tau.reshape(na, 1), (1, n_steps)) if tau.ndim == 1 else tau.T
    F = np.zeros(2) if F is None else np.asarray(F, dtype=float)
    F = np.tile(F.reshape(2, 1), (1, n_steps)) if F.ndim == 1 else F.T
    if tau.shape != (na, n_steps) or F.shape != (2, n_steps):
        raise ConfigError(f"tau must be ({na},) or ({n_steps}, {na}); F (2,) or "
                          f"({n_steps}, 2)", key="tau")
    key = ("rk4", n_steps)
    fn = model._cache.get(key)
    if fn is None:
        fn = model.fn_rk4.mapaccum(f"rk4_{n_steps}", n_steps)
        model._cache[key] = fn
    x0 = np.concatenate([_arr(q0, n, "q0"), _arr(dq0, n, "dq0")])
    X = np.array(fn(x0, tau, F, np.full((1, n_steps), float(dt))))
    return np.vstack([x0, X.T])


# ------------------------------------------------------------------------------- paper rows
def paper_sagittal_parameters(view: SagittalView) -> dict[str, float]:
    """Symbols of the paper's eqs. ddxs/ddzs, read from the view (swing leg = links 1, 2).

    m_b trunk (+ hip links), m_t / m_c swing thigh / calf+foot masses [kg]; a1 thigh COM
    from the hip, l_t thigh length, a2 calf COM from the knee (along the link axes), l_b
    trunk COM above the hip along the trunk axis [m]; M_s = m_b + m_t + m_c [kg].
    """
    m_b, m_t, m_c = view.trunk.mass, view.thigh_swing.mass, view.calf_swing.mass
    return {"m_b": m_b, "m_t": m_t, "m_c": m_c, "M_s": m_b + m_t + m_c,
            "a1": view.thigh_swing.com_along, "l_t": view.thigh_swing.length,
            "a2": view.calf_swing.com_along, "l_b": float(view.trunk_com_from_hip[1]),
            "g": view.gravity}


def paper_sagittal_rows(view: SagittalView, q, dq, ddq) -> np.ndarray:
    """The paper's x_s and z_s rows taken literally (eqs. ddxs, ddzs), as the force they
    say the ground exerts: returns (F_x, F_z) [N] with::

        F_x = M_s ẍ_s + g5 + g1 + g2
        F_z = M_s z̈_s + h5 + h1 + h2 + M_s g
        g1 = (m_t a1 + m_c l_t)(−cos q1 q̈1 + sin q1 q̇1²),  g2 = m_c a2 (−cos q2 q̈2 + sin q2 q̇2²)
        g5 = m_b l_b (cos q5 q̈5 − sin q5 q̇5²)
        h1 = (m_t a1 + m_c l_t)(sin q1 q̈1 + cos q1 q̇1²),   h2 = m_c a2 (sin q2 q̈2 + cos q2 q̇2²)
        h5 = −m_b l_b (sin q5 q̈5 + cos q5 q̇5²)

    with q1, q2 our swing thigh / calf angles, q5 the trunk (see
    :func:`paper_sagittal_parameters`).
    """
    p = paper_sagittal_parameters(view)
    q, dq, ddq = (_arr(v, 7, n) for v, n in ((q, "q"), (dq, "dq"), (ddq, "ddq")))
    k1 = p["m_t"] * p["a1"] + p["m_c"] * p["l_t"]
    k2 = p["m_c"] * p["a2"]
    k5 = p["m_b"] * p["l_b"]
    c, s = np.cos(q), np.sin(q)
    g1 = k1 * (-c[0] * ddq[0] + s[0] * dq[0] ** 2)
    g2 = k2 * (-c[1] * ddq[1] + s[1] * dq[1] ** 2)
    g5 = k5 * c[4] * ddq[4] - k5 * s[4] * dq[4] ** 2
    h1 = k1 * (s[0] * ddq[0] + c[0] * dq[0] ** 2)
    h2 = k2 * (s[1] * ddq[1] + c[1] * dq[1] ** 2)
    h5 = -k5 * s[4] * ddq[4] - k5 * c[4] * dq[4] ** 2
    M = p["M_s"]
    return np.array([M * ddq[5] + g5 + g1 + g2, M * ddq[6] + h5 + h1 + h2 + M * p["g"]])


def paper_frontal_parameters(view: FrontalView) -> dict[str, float]:
    """Symbols of the paper's eq. ddys: m_b trunk, m1 / m2 stance / swing leg [kg];
    l1 stance leg length (arc centre → abduction axis), d1 its COM from the arc centre,
    d2 swing leg COM from its abduction axis (along the leg lines), b hip width [m];
    M_f = m_b + m1 + m2."""
    ls, lw = view.leg_stance, view.leg_swing
    return {"m_b": view.trunk.mass, "m1": ls.mass, "m2": lw.mass,
            "M_f": view.trunk.mass + ls.mass + lw.mass, "l1": ls.length,
            "d1": ls.length - ls.com_along, "d2": lw.com_along, "b": view.hip_width}


def paper_frontal_y_row(view: FrontalView, q, dq, ddq) -> float:
    """The paper's y_s row taken literally (eq. ddys), as F_y [N]::

        F_y = M_f ÿ_s + f1 + f2 + f3
        f1 = −(m1 d1 + m_b l1 + m2 l1)(cos q1f q̈1f − sin q1f q̇1f²)
        f2 = (½ m_b b + m2 b)(cos q2f q̈2f − sin q2f q̇2f²)
        f3 = m2 d2 (cos q3f q̈3f − sin q3f q̇3f²)
    """
    p = paper_frontal_parameters(view)
    q, dq, ddq = (_arr(v, 5, n) for v, n in ((q, "q"), (dq, "dq"), (ddq, "ddq")))
    c, s = np.cos(q), np.sin(q)
    f1 = -(p["m1"] * p["d1"] + (p["m_b"] + p["m2"]) * p["l1"]) * (c[0] * ddq[0] - s[0] * dq[0] ** 2)
    f2 = (0.5 * p["m_b"] + p["m2"]) * p["b"] * (c[1] * ddq[1] - s[1] * dq[1] ** 2)
    f3 = p["m2"] * p["d2"] * (c[2] * ddq[2] - s[2] * dq[2] ** 2)
    return float(p["M_f"] * ddq[3] + f1 + f2 + f3)


__all__ = [
    "PlanarModel", "SAGITTAL_COORDINATES", "FRONTAL_COORDINATES", "sagittal_model",
    "frontal_model", "build_planar_models", "mass_matrix", "coriolis_matrix",
    "gravity_vector", "contact_jacobian", "swing_contact_jacobian", "forward_dynamics",
    "inverse_dynamics", "energy", "points", "simulate_rk4", "sagittal_from_actuated",
    "actuated_from_sagittal", "sagittal_torques", "frontal_from_actuated",
    "actuated_from_frontal", "frontal_jacobian", "frontal_torques", "stance_foot_pitch",
    "contact_on_sole", "paper_sagittal_parameters", "paper_sagittal_rows",
    "paper_frontal_parameters", "paper_frontal_y_row", "sagittal_selection", "check_side",
]
