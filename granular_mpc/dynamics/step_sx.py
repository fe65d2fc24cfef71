"""The plant step of :class:`~granular_mpc.dynamics.plant.Plant` as CasADi SX functions.

Builds, for one plant model (robot + terrain + step settings + joint effects), the
symbolic functions that :mod:`granular_mpc.dynamics.compiled` compiles to C:

* ``step(x, u, θ, w) -> (x⁺, aux)``: one step ``dt`` of the reference plant — the joint PD
  law, the Verlet velocity correction ``Δa = M⁻¹Δτ``, the drift, forward kinematics of
  both feet, the terrain law of every patch (the terrain model's own compiled contact
  expression, effects included, told which foot it serves), joint end stops, joint
  damping, the joint-effect hook, the trunk wrench and the articulated-body algorithm
  (:mod:`.rigid_body_sx`), then the kick; the semi-implicit Euler integrator likewise;
* ``start(x, u, θ, w) -> x``: what the reference does at its very first Verlet step
  (evaluate and commit the acceleration and the contact once before stepping).

Vector layouts (all SI, frames as in :class:`~granular_mpc.dynamics.plant.Plant`) are
described by :class:`StepLayout`. The control input ``u = [τ_ff, q_ref, k_p, k_d]`` (each
actuator order) gives the held torque ``τ = τ_ff + k_p (q_ref − q_a) − k_d q̇_a`` evaluated at
the state at the start of the step — a plain torque command is ``k_p = k_d = 0``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..columns import AXES
from ..exceptions import ConfigError
from ..robot.model import SIDES
from ..terrain.contact import DIAG_NAMES, N_KIN
from . import rigid_body_sx as rb

#: per-foot part of the auxiliary output of a step (all in W, SI): the terrain force on the
#: foot [N], the mean contact point of its patches [m], its contact flag (committed), the
#: mean over its patches of the terrain diagnostics (``DIAG_NAMES``: depth, f_cap_z,
#: x_s, y_s, z_s, ψ_c) and whether its contact law was evaluated this step (0 when the
#: foot was clear of the surface and skipped, as in the reference plant)
AUX_FOOT = (("force", slice(0, 3)), ("point", slice(3, 6)), ("contact", slice(6, 7)),
            ("diag", slice(7, 7 + len(DIAG_NAMES))),
            ("evaluated", slice(7 + len(DIAG_NAMES), 8 + len(DIAG_NAMES))))
#: size of the per-foot part
AUX_PER_FOOT = 8 + len(DIAG_NAMES)
#: names of the auxiliary output: both feet (left first), then the largest |v| of the call
_FOOT_NAMES = (tuple(f"force_{a}" for a in AXES) + tuple(f"point_{a}" for a in AXES)
               + ("contact",) + DIAG_NAMES + ("evaluated",))
AUX_NAMES = tuple(f"{side}_{name}" for side in SIDES for name in _FOOT_NAMES) + ("speed_max",)


#: (foot, part) → slice of that part in an aux vector
AUX_SLICES = {(foot, part): slice(foot * AUX_PER_FOOT + sl.start, foot * AUX_PER_FOOT + sl.stop)
              for foot in (0, 1) for part, sl in AUX_FOOT}


def aux_foot(aux, foot: int, part: str):
    """The ``part`` (see :data:`AUX_FOOT`) of foot ``foot`` in an aux vector or rows (…, n)."""
    return aux[..., AUX_SLICES[foot, part]]


@dataclass(frozen=True)
class StepLayout:
    """Sizes and slices of the flat state ``x`` and control ``u`` of one robot.

    ``x = [q (nq) | v (nv) | a (nv) | τ_prev (na) | patch states (2 feet × n × S)]``:
    configuration [m, quaternion x y z w, rad], velocity (base twist in the trunk frame)
    [m/s, rad/s], last acceleration, the torque held during the last step [N·m], and the
    terrain's per-patch state (:mod:`granular_mpc.terrain.contact`, left foot first).
    ``u = [τ_ff | q_ref | k_p | k_d]`` (na each) [N·m, rad, N·m/rad, N·m·s/rad].
    The parameter input ``θ`` (``n_theta``) is ``[terrain θ (n_terrain) | joint-effect
    parameters]`` — with ``per_foot`` ``[terrain θ of the left foot | of the right foot |
    joint-effect parameters]`` (e.g. a replay's per-foot free surface).
    """

    nq: int
    nv: int
    na: int
    n_patches: int
    patch_state: int
    n_theta: int
    per_foot: bool = False
    n_terrain: int = -1          # terrain θ size (−1: all of ``n_theta``)

    def terrain_theta(self, foot: int) -> slice:
        """The slice of ``θ`` that foot ``foot``'s terrain law reads."""
        n = self.n_theta if self.n_terrain < 0 else self.n_terrain
        k = foot if self.per_foot else 0
        return slice(k * n, (k + 1) * n)

    @property
    def joint_theta(self) -> slice:
        """The slice of ``θ`` holding the joint-effect parameters."""
        return slice(self.terrain_theta(1).stop, self.n_theta)

    @property
    def nx(self) -> int:
        return self.nq + 2 * self.nv + self.na + 2 * self.n_patches * self.patch_state

    @property
    def nu(self) -> int:
        return 4 * self.na

    @property
    def q(self) -> slice:
        return slice(0, self.nq)

    @property
    def v(self) -> slice:
        return slice(self.nq, self.nq + self.nv)

    @property
    def a(self) -> slice:
        return slice(self.nq + self.nv, self.nq + 2 * self.nv)

    @property
    def tau_prev(self) -> slice:
        return slice(self.nq + 2 * self.nv, self.nq + 2 * self.nv + self.na)

    @property
    def contact(self) -> slice:
        return slice(self.nq + 2 * self.nv + self.na, self.nx)


def symbolic_contact(terrain) -> ca.Function:
    """The terrain model's per-foot contact law as a CasADi SX function
    (``terrain.contact.symbolic``, the function the terrain compiles for the plant; input
    ``[kin | patch states | dt | foot | θ]``, see
    :class:`~granular_mpc.terrain.contact.CompiledContact`)."""
    return terrain.contact.symbolic


def _checked_trace(label: str, name: str, build, float_fn, param_sets, na: int) -> ca.Function:
    """Trace a joint-effect hook with SX and check it against its float form.

    Args:
        label: the effect as named in errors; name: the CasADi function's name.
        build: ``(q_a, dq_a, p) -> τ_a`` on SX symbols (``p``: the parameter symbols).
        float_fn: ``(q_a, dq_a, p) -> τ_a`` on floats (``p``: one of ``param_sets``).
        param_sets: ``[(values (n_p,), p for float_fn), …]`` checked at random q_a, dq_a.
        na: number of actuated joints.

    Raises:
        ConfigError: the hook cannot be traced with CasADi or gives other values.
    """
    n_p = len(param_sets[0][0])
    qa, va, ps = ca.SX.sym("q_a", na), ca.SX.sym("dq_a", na), ca.SX.sym("p", n_p)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            out = ca.SX(build(qa, va, ps))
        traced = ca.Function(name, [qa, va, ps], [ca.reshape(out, na, 1)])
        rng = np.random.default_rng(0)
        qn, vn = rng.normal(size=na), rng.normal(size=na)
        ok = all(np.allclose(np.array(traced(qn, vn, pv)).ravel(),
                             np.asarray(float_fn(qn, vn, p), float), rtol=1e-12, atol=1e-12)
                 for pv, p in param_sets)
    except Exception as exc:  # noqa: BLE001 - any failure means "not traceable"
        raise ConfigError(f"joint effect {label} cannot be compiled ({exc}); use the "
                          "reference Plant", key="joint_effects") from exc
    if not ok:
        raise ConfigError(f"joint effect {label} traced with CasADi gives other values "
                          "than on floats; use the reference Plant", key="joint_effects")
    return traced


def trace_joint_effect_params(info, na: int) -> ca.Function:
    """Trace a registered joint effect ``info.fn(q_a, dq_a, p)`` with its parameters
    symbolic: ``joint_effect(q_a, dq_a, p) -> τ_a`` (``p`` in ``info.params`` order),
    checked numerically at its default and neutral parameters.

    Raises:
        ConfigError: the effect cannot be traced with CasADi or gives other values.
    """
    names = list(info.params)
    sets = [(np.array([p[k] for k in names], dtype=float), dict(p))
            for p in (info.resolve_params({}), info.neutral_params())]
    return _checked_trace(repr(info.name), f"joint_{info.name}",
                          lambda q, v, ps: info.fn(q, v, {k: ps[i] for i, k in enumerate(names)}),
                          info.fn, sets, na)


def _trace_joint_effect(fn, na: int) -> ca.Function:
    """Trace a joint-effect hook ``(q_a, dq_a) -> τ_a`` with SX and check it numerically."""
    traced = _checked_trace(repr(fn), "joint_effect_p", lambda q, v, ps: fn(q, v),
                            lambda q, v, p: fn(q, v), [(np.zeros(0), None)], na)
    qa, va = ca.SX.sym("q_a", na), ca.SX.sym("dq_a", na)
    return ca.Function("joint_effect", [qa, va], [traced(qa, va, ca.SX(0, 1))])


class StepBuilder:
    """Builds the symbolic ``step`` and ``start`` functions of one plant model.

    Args:
        plant: a :class:`~granular_mpc.dynamics.plant.Plant` (its biped, terrain, sim
            settings and joint effects are read; it is not modified).
        per_foot_theta: each foot's terrain law reads its own terrain θ (see
            :class:`StepLayout`).
        joint_params: registered joint effects (``EffectInfo``) compiled with their
            parameters as inputs (appended to ``θ`` in ``info.params`` order), added after
            the plant's own joint effects; their neutral values switch them off.
    """

    def __init__(self, plant, *, per_foot_theta: bool = False, joint_params: tuple = ()) -> None:
        biped, terrain = plant.biped, plant.terrain
        model = biped.model
        actuators = getattr(plant, "actuators", None)
        if actuators is not None and actuators.active:
            raise ConfigError("the compiled plant does not model sim.actuators (joint "
                              "friction, motor envelope, rotor inertia) yet; use the "
                              "reference Plant", key="sim.actuators")
        self.plant = plant
        self.tree = rb.tree_from_model(model)
        self.contact_fn = symbolic_contact(terrain)
        cm = terrain.contact
        n_terrain = len(terrain.param_names)
        self.joint_params = tuple(joint_params)
        n_joint = sum(len(info.params) for info in self.joint_params)
        self.layout = StepLayout(model.nq, model.nv, len(biped.idx_v), cm.n_slices,
                                 cm.state_size, (2 if per_foot_theta else 1) * n_terrain + n_joint,
                                 bool(per_foot_theta), n_terrain)
        self.gravity = np.array(model.gravity.linear)
        self.iq, self.iv = list(map(int, biped.idx_q)), list(map(int, biped.idx_v))
        self.q_lo, self.q_hi = biped.position_limits
        self.feet = []
        for side in SIDES:
            fid, jid = biped.foot_frame[side], biped.foot_joint[side]
            M = model.frames[fid].placement
            self.feet.append((jid, np.array(M.rotation), np.array(M.translation),
                              np.array(M.toDualActionMatrix())))
        self.i_surface = list(terrain.param_names).index("surface_height")
        self.clear_offset = biped.config.foot.radius + 0.005
        self.joint_effects = [_trace_joint_effect(fn, self.layout.na)
                              for fn in plant.joint_effects]
        self.joint_param_fns = [trace_joint_effect_params(info, self.layout.na)
                                for info in self.joint_params]
        self.dt = float(plant.sim.dt)
        self.integrator = plant.sim.integrator

    # ------------------------------------------------------------------ pieces
    def _torque(self, q, v, u):
        """Full-size generalised torque held during the step (PD law at the step start)."""
        na, L = self.layout.na, self.layout
        tau_ff, q_ref, kp, kd = (u[k * na:(k + 1) * na] for k in range(4))
        qa = ca.vertcat(*[q[i] for i in self.iq])
        va = ca.vertcat(*[v[i] for i in self.iv])
        tau_a = tau_ff + kp * (q_ref - qa) - kd * va
        full = [0.0] * L.nv
        for k, i in enumerate(self.iv):
            full[i] = tau_a[k]
        return tau_a, ca.vertcat(*full)

    def forward(self, q, v, v_dyn, tau_full, states, theta, wrench):
        """Acceleration and the evaluated (uncommitted) patch states at (q, v).

        Mirrors :meth:`Plant.forward`. Returns ``(a, new_states, aux_feet)`` with
        ``aux_feet`` the per-foot parts of :data:`AUX_FOOT`, in order.
        """
        L = self.layout
        n, S = L.n_patches, L.patch_state
        pl = rb.placements(self.tree, q)
        vel = rb.velocities(self.tree, pl, v)
        fext = [None] * len(self.tree)
        new_states, aux = [], []
        per_patch = 3 + 3 + S + len(DIAG_NAMES)
        for foot, (jid, R_f, p_f, dual) in enumerate(self.feet):
            theta_f = theta[L.terrain_theta(foot)]
            clear = theta_f[self.i_surface] + self.clear_offset
            st = states[foot * n * S:(foot + 1) * n * S]
            p, R, vW, wW = rb.frame_kinematics(pl, vel, jid, R_f, p_f)
            kin = ca.vertcat(p, ca.vec(R), vW, wW)
            assert kin.shape[0] == N_KIN
            # the terrain law's input [kin | states | dt | foot | θ] (foot: 0 left, 1 right)
            out = self.contact_fn(ca.vertcat(kin, st, self.dt, float(foot), theta_f))
            in_contact = ca.mmax(ca.vertcat(*[st[k * S + 6] for k in range(n)])) > 0.5
            # a swing foot whose sole cannot reach the surface: zero force, state reset
            live = ca.if_else(ca.logic_and(p[2] > clear, ca.logic_not(in_contact)), 0.0, 1.0)
            wrench_local = live * out[n * per_patch: n * per_patch + 6]
            fext[jid - 1] = ca.SX(ca.DM(dual)) @ wrench_local
            f_sum, p_sum, flag = ca.SX.zeros(3, 1), ca.SX.zeros(3, 1), 0.0
            d_sum = ca.SX.zeros(len(DIAG_NAMES), 1)
            for k in range(n):
                b = k * per_patch
                f_sum = f_sum + live * out[b:b + 3]
                p_sum = p_sum + out[b + 3:b + 6] / n
                new_states.append(live * out[b + 6:b + 6 + S])
                flag = ca.fmax(flag, live * out[b + 6 + 6])
                d_sum = d_sum + live * out[b + 6 + S:b + 6 + S + len(DIAG_NAMES)] / n
            aux += [f_sum, p_sum, flag, d_sum, live]
        # joint end stops, joint damping and the joint-effect hook (actuated joints)
        qa = ca.vertcat(*[q[i] for i in self.iq])
        va = ca.vertcat(*[v[i] for i in self.iv])
        over = ca.fmax(qa - ca.DM(self.q_hi), 0.0) + ca.fmin(qa - ca.DM(self.q_lo), 0.0)
        terms = [ca.if_else(over != 0.0, -self.plant.STOP_K * over - self.plant.STOP_D * va, 0.0)]
        damping = self.plant.biped.config.joint_damping
        if damping > 0.0:
            terms.append(-damping * va)
        terms += [fn(qa, va) for fn in self.joint_effects]
        k0 = L.joint_theta.start
        for info, fn in zip(self.joint_params, self.joint_param_fns):
            terms.append(fn(qa, va, theta[k0:k0 + len(info.params)]))
            k0 += len(info.params)
        tau = [tau_full[i] for i in range(L.nv)]
        for term in terms:                     # in the reference's order of summation
            for k, i in enumerate(self.iv):
                tau[i] = tau[i] + term[k]
        # the trunk wrench, given in W at the trunk origin → trunk frame
        R_B = pl.R_o[0]
        fext[0] = ca.vertcat(R_B.T @ wrench[0:3], R_B.T @ wrench[3:6])
        a = rb.aba(self.tree, pl, L.nv, ca.vertcat(*tau), v=v_dyn, fext=fext,
                   gravity=self.gravity)
        return a, ca.vertcat(*new_states), aux

    # ------------------------------------------------------------------ functions
    def _symbols(self):
        L = self.layout
        return (ca.SX.sym("x", L.nx), ca.SX.sym("u", L.nu), ca.SX.sym("theta", L.n_theta),
                ca.SX.sym("wrench", 6))

    def step_function(self) -> ca.Function:
        """``step(x, u, θ, w) -> (x⁺, aux)``: one plant step (see the module docstring)."""
        L, dt = self.layout, self.dt
        x, u, theta, wrench = self._symbols()
        q, v, a, tau_prev, states = (x[L.q], x[L.v], x[L.a], x[L.tau_prev], x[L.contact])
        tau_a, tau_full = self._torque(q, v, u)
        if self.integrator == "verlet":
            dtau = [0.0] * L.nv
            for k, i in enumerate(self.iv):
                dtau[i] = tau_a[k] - tau_prev[k]
            # acceleration is affine in τ: correct the reused one exactly (Δa = M⁻¹ Δτ)
            a = a + rb.aba(self.tree, rb.placements(self.tree, q), L.nv, ca.vertcat(*dtau))
            v_half = v + 0.5 * dt * a
            q_new = rb.integrate(self.tree, q, v_half * dt)
            a_new, new_states, aux = self.forward(q_new, v_half, v_half + 0.5 * dt * a,
                                                  tau_full, states, theta, wrench)
            v_new = v_half + 0.5 * dt * a_new
        else:
            a_new, new_states, aux = self.forward(q, v, v, tau_full, states, theta, wrench)
            v_new = v + dt * a_new
            q_new = rb.integrate(self.tree, q, v_new * dt)
        x_next = ca.vertcat(q_new, v_new, a_new, tau_a, new_states)
        aux_out = ca.vertcat(*aux, ca.mmax(ca.fabs(v_new)))
        # merge identical subexpressions (exact: the same operations, computed once)
        x_next, aux_out = ca.cse([x_next, aux_out])
        return ca.Function("plant_step", [x, u, theta, wrench], [x_next, aux_out],
                           ["x", "u", "theta", "wrench"], ["x_next", "aux"])

    def start_function(self) -> ca.Function:
        """``start(x, u, θ, w) -> x``: first evaluation of a Verlet run (a and contact committed)."""
        L = self.layout
        x, u, theta, wrench = self._symbols()
        q, v, states = x[L.q], x[L.v], x[L.contact]
        tau_a, tau_full = self._torque(q, v, u)
        a, new_states, _ = self.forward(q, v, v, tau_full, states, theta, wrench)
        x_next = ca.cse(ca.vertcat(q, v, a, tau_a, new_states))
        return ca.Function("plant_start", [x, u, theta, wrench], [x_next],
                           ["x", "u", "theta", "wrench"], ["x_next"])


__all__ = ["AUX_FOOT", "AUX_NAMES", "AUX_PER_FOOT", "AUX_SLICES", "aux_foot", "StepLayout",
           "StepBuilder", "symbolic_contact", "trace_joint_effect_params"]
