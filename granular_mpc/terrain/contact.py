"""Contact patches and the compiled contact function shared by every terrain model.

Each foot is cut into ``n`` slices across its width; each slice is a *patch* with its own
contact point (the lowest point of its sole arc), its own elastic displacement and
touchdown point. Several patches per foot give the roll and yaw moments a line-like sole produces.

Every terrain model is an *elastic–plastic* contact: the force is that of a stiff spring
(stiffness K, damping D) stretched by the elastic displacement e, clipped component-wise
(along the foot heading h, its lateral l and the vertical z) to what the medium can bear;
when clipped, e is reset to the clipped force (plastic flow, i.e. sinkage and slip). The
displacement integrates the velocity of the *material* point of the sole at the contact,
ė = v_c, so a sole that rolls without slipping loads no spring (its lowest point moves,
the material there does not). The
terrain model only supplies the clipping bounds (granular: RFT; rigid: Coulomb). The
stiff spring is a numerical regularisation of the rigid-plastic law: it lets a foot rest
in sand without creeping, and its deflection (W/K ≈ 0.3 mm) is far below the sinkage.

The law for the patches of one foot is one CasADi SX function, compiled to C when a
compiler is available and evaluated through CasADi's buffer interface on pre-allocated
NumPy arrays (a few µs per foot). Both feet use the same function; the foot's identity
(0 left, 1 right) is one of its inputs, so terrain-force effects can act on one foot only
(:attr:`~granular_mpc.effects.PatchState.foot`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from ..codegen import compile_functions
from ..effects import Effect, PatchState
from ..effects.tracing import trace_terrain_force

#: per-foot kinematic input: p_W_F (3), R_W_F column-major (9), v_W_F (3), ω_W (3)
N_KIN = 18
#: per-patch state: elastic displacement e (3), c0 (3), in-contact flag, v_prev (3),
#: depth_max, t_stance
N_BASE_STATE = 12
#: per-patch diagnostics: depth, vertical capacity, intrusion (3), foot pitch ψ_c
DIAG_NAMES = ("depth", "f_cap_z", "x_s", "y_s", "z_s", "psi_c")


@dataclass
class SliceGeometry:
    """Kinematics of one slice, as expressions or floats (world frame)."""

    p_c: tuple         # lowest point of the slice's sole arc
    v_c: tuple         # its velocity
    depth: Any         # depth below the surface (+ down)
    psi_c: Any         # foot pitch in the slice plane, for the closed form
    heading: tuple     # unit horizontal foot heading h
    lateral: tuple     # unit horizontal left of h
    e_x: tuple
    e_z: tuple


def _v(vec):
    return tuple(vec[i] for i in range(3))


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def _scale(k, a):
    return (k * a[0], k * a[1], k * a[2])


def slice_geometry(o, kin, y_k: float, radius: float, half_angle: float,
                   surface: Any, slope: tuple = (0.0, 0.0)) -> SliceGeometry:
    """Lowest point, depth, pitch and heading of the slice at lateral offset ``y_k``.

    The free surface is the plane ``z = surface + slope_x·x + slope_y·y`` (W); the depth
    is measured vertically below it at the contact point (small slopes)."""
    p = _v(kin[0:3])
    R = kin[3:12]
    e_x = (R[0], R[1], R[2])
    e_y = (R[3], R[4], R[5])
    e_z = (R[6], R[7], R[8])
    v_f = _v(kin[12:15])
    w = _v(kin[15:18])
    centre = _add(p, _scale(y_k, e_y))
    # world-down direction seen in the slice plane: angle from the foot's −z toward +x
    gx, gz = -e_x[2], -e_z[2]
    psi_low = o.atan2(gx, -gz)
    psi_arc = o.fmin(o.fmax(psi_low, -half_angle), half_angle)
    sp, cp = o.sin(psi_arc), o.cos(psi_arc)
    p_c = _add(centre, _add(_scale(radius * sp, e_x), _scale(-radius * cp, e_z)))
    v_c = _add(v_f, _cross(w, _add(p_c, _scale(-1.0, p))))
    hn = o.sqrt(e_x[0] * e_x[0] + e_x[1] * e_x[1] + 1e-12)
    heading = (e_x[0] / hn, e_x[1] / hn, 0.0)
    lateral = (-heading[1], heading[0], 0.0)
    z_surf = surface + slope[0] * p_c[0] + slope[1] * p_c[1]
    return SliceGeometry(p_c, v_c, z_surf - p_c[2], -psi_low, heading, lateral, e_x, e_z)


@dataclass
class LawOutput:
    """What a terrain law returns for one patch (all in the world frame)."""

    force: tuple            # terrain force on the foot before effects [N]
    displacement: tuple     # elastic displacement after clipping
    f_cap_z: Any            # vertical capacity for pure penetration at this depth [N]
    area_h: Any             # horizontal area of the submerged sole [m²]
    extra_mass: Any = 0.0   # added mass moving with the patch [kg]
    extra_mass_rate: Any = 0.0  # its rate of change [kg/s]


#: signature of a terrain law: (o, geometry, e_prev, c0, theta, dt) -> LawOutput
LawFn = Callable[..., LawOutput]


def elastic_trial(K, D, geom: SliceGeometry, e_prev, dt) -> tuple:
    """Trial displacement e = e_prev + v_c dt and force −K e − D v_c in W."""
    e = tuple(e_prev[i] + geom.v_c[i] * dt for i in range(3))
    return tuple(-K * e[i] - D * geom.v_c[i] for i in range(3)), e


def to_basis(vec, h, l) -> tuple:
    return (_dot(vec, h), _dot(vec, l), vec[2])


def from_basis(c, h, l) -> tuple:
    return (c[0] * h[0] + c[1] * l[0], c[0] * h[1] + c[1] * l[1], c[2])


def clip(o, x, lo, hi):
    return o.fmin(o.fmax(x, lo), hi)


class CompiledContact:
    """The patches of one foot as one compiled function (the same function serves both feet).

    The model part (immutable): the CasADi function, layout, parameter names. Call
    :meth:`new_data` for the changing part (state, buffers). Input layout::

        [foot kinematics (N_KIN) | patch states (n × S) | dt | foot | θ]

    with ``foot`` 0 for the left foot and 1 for the right (what effects read as
    ``PatchState.foot``); :attr:`dt_index`, :attr:`foot_index` and :attr:`theta_start`
    give the positions.

    Output per patch: force (3), contact point (3), new state (S), diagnostics (DIAG_NAMES).
    """

    def __init__(self, law: LawFn, *, slice_offsets: Sequence[float], radius: float,
                 half_angle: float, param_names: Sequence[str], param_values: Sequence[float],
                 effects: Sequence[tuple[Effect, dict]] = (), density: float = 0.0,
                 slice_width: float) -> None:
        import casadi as ca

        from .closed_form import casadi_ops

        o = casadi_ops()
        self.n_slices = len(slice_offsets)
        self.n_patches = 2 * self.n_slices
        self.param_names = tuple(param_names)
        self.param_values = np.array(param_values, dtype=float)
        self.effect_names = tuple(e.name for e, _ in effects)
        n_theta = len(self.param_names)
        S = N_BASE_STATE
        self.state_size = S
        n = self.n_slices
        self.dt_index = N_KIN + n * S
        self.foot_index = self.dt_index + 1
        self.theta_start = self.foot_index + 1
        self.n_in = self.theta_start + n_theta
        x = ca.SX.sym("x", self.n_in)
        kin = x[0:N_KIN]
        states = [x[N_KIN + k * S: N_KIN + (k + 1) * S] for k in range(n)]
        dt = x[self.dt_index]
        foot = x[self.foot_index]
        theta = x[self.theta_start:]
        th = {name: theta[i] for i, name in enumerate(self.param_names)}
        outs = []
        for k in range(n):
            y_k = float(slice_offsets[k])
            st = states[k]
            e_prev, c0 = _v(st[0:3]), _v(st[3:6])
            flag, v_prev = st[6], _v(st[7:10])
            depth_max, t_stance = st[10], st[11]
            geom = slice_geometry(o, kin, y_k, radius, half_angle, th["surface_height"],
                                  (th["surface_slope_x"], th["surface_slope_y"]))
            touching = geom.depth > 0.0
            was = flag > 0.5
            # touchdown: C0 is the first contact point, the spring starts relaxed
            c0_new = tuple(ca.if_else(was, c0[i], geom.p_c[i]) for i in range(3))
            e_in = tuple(ca.if_else(was, e_prev[i], 0.0) for i in range(3))
            law_out = law(o, geom, e_in, c0_new, th, dt)
            on = ca.if_else(touching, 1.0, 0.0)
            a_c = tuple(ca.if_else(was, (geom.v_c[i] - v_prev[i]) / dt, 0.0) for i in range(3))
            # solidified zone as added mass, momentum form: −m_a a − ṁ_a⁺ v
            f_am = tuple(-law_out.extra_mass * a_c[i]
                         - o.fmax(law_out.extra_mass_rate, 0.0) * geom.v_c[i] for i in range(3))
            force = tuple(on * (law_out.force[i] + f_am[i]) for i in range(3))
            intrusion = (geom.p_c[0] - c0_new[0], geom.p_c[1] - c0_new[1], c0_new[2] - geom.p_c[2])
            new_dmax = ca.if_else(was, o.fmax(depth_max, geom.depth), geom.depth)
            new_ts = ca.if_else(was, t_stance + dt, 0.0)
            slope = (th["surface_slope_x"], th["surface_slope_y"])
            depth_rate = slope[0] * geom.v_c[0] + slope[1] * geom.v_c[1] - geom.v_c[2]
            pstate = PatchState(depth=geom.depth, in_contact=on, p_c=geom.p_c, v_c=geom.v_c,
                                a_c=a_c, intrusion=intrusion, heading=geom.heading,
                                lateral=geom.lateral, f_terrain=force,
                                f_yield_z=law_out.f_cap_z, area_h=law_out.area_h,
                                width=slice_width, density=density, dt=dt,
                                depth_max=new_dmax, t_stance=new_ts, foot=foot,
                                depth_rate=depth_rate)
            for eff, _values in effects:
                p = {name: th[f"{eff.name}.{name}"] for name in eff.params}
                fe = trace_terrain_force(eff, o, pstate, p)
                force = tuple(force[i] + on * fe[i] for i in range(3))
            new_e = tuple(ca.if_else(touching, law_out.displacement[i], 0.0) for i in range(3))
            new_c0 = tuple(ca.if_else(touching, c0_new[i], c0[i]) for i in range(3))
            new_state = (list(new_e) + list(new_c0) + [on] + list(geom.v_c)
                         + [ca.if_else(touching, new_dmax, 0.0), ca.if_else(touching, new_ts, 0.0)])
            diag = [geom.depth, on * law_out.f_cap_z, on * intrusion[0], on * intrusion[1],
                    on * intrusion[2], geom.psi_c]
            outs += list(force) + list(geom.p_c) + new_state + diag
        # the foot's total wrench about its frame origin, in the foot frame (for the plant)
        p_f = _v(kin[0:3])
        Rm = ca.reshape(kin[3:12], 3, 3)
        f_sum = [0.0, 0.0, 0.0]
        m_sum = [0.0, 0.0, 0.0]
        n_out_patch = 3 + 3 + S + len(DIAG_NAMES)
        for k in range(n):
            base = k * n_out_patch
            fk = tuple(outs[base + i] for i in range(3))
            rk = tuple(outs[base + 3 + i] - p_f[i] for i in range(3))
            mk = _cross(rk, fk)
            f_sum = [f_sum[i] + fk[i] for i in range(3)]
            m_sum = [m_sum[i] + mk[i] for i in range(3)]
        f_local = Rm.T @ ca.vertcat(*f_sum)
        m_local = Rm.T @ ca.vertcat(*m_sum)
        outs += [f_local[i] for i in range(3)] + [m_local[i] for i in range(3)]
        self.n_out_patch = n_out_patch
        self.n_out = self.n_out_patch * n + 6
        self.symbolic = ca.Function("contact", [x], [ca.vertcat(*outs)])
        # compiled once per law (cached by source hash); -O2 keeps the results of earlier
        # releases bit for bit; the virtual machine if there is no compiler
        self.function = compile_functions("contact", [self.symbolic], fallback=True,
                                          optimisation="-O2")["contact"]

    # ------------------------------------------------------------------ data part
    def new_data(self) -> "ContactData":
        return ContactData(self)


class _FootBuffers:
    """Input/output arrays of one foot (``foot`` 0 left, 1 right: fixed in its input),
    bound to the compiled function's buffers."""

    def __init__(self, model: CompiledContact, params: np.ndarray, foot: int) -> None:
        n, S = model.n_slices, model.state_size
        self.inp = np.zeros(model.n_in)
        self.out = np.zeros(model.n_out)
        self.inp[model.theta_start:] = params
        self.inp[model.foot_index] = float(foot)
        self._buf, self._call = model.function.buffer()
        self._buf.set_arg(0, memoryview(self.inp))
        self._buf.set_res(0, memoryview(self.out))
        self.kin = self.inp[0:N_KIN]
        self.state = self.inp[N_KIN: N_KIN + n * S].reshape(n, S)
        self.params = self.inp[model.theta_start:]
        out = self.out[: n * model.n_out_patch].reshape(n, model.n_out_patch)
        self.wrench_local = self.out[n * model.n_out_patch:]   # (f, m) in the foot frame
        self.force = out[:, 0:3]
        self.point = out[:, 3:6]
        self.new_state = out[:, 6:6 + S]
        self.diag = out[:, 6 + S:]
        self.dt_index = model.dt_index


class ContactData:
    """Changing part of the contact of both feet: patch states, buffers, last outputs.

    ``feet[i].kin`` takes foot i's kinematics (0 = left, 1 = right); after
    :meth:`evaluate`, ``feet[i].force`` / ``.point`` / ``.diag`` hold the per-patch results
    and :meth:`commit` makes the new patch states current.
    """

    def __init__(self, model: CompiledContact) -> None:
        self.model = model
        self.feet = tuple(_FootBuffers(model, model.param_values, foot) for foot in (0, 1))
        self.active = [False, False]

    def set_dt(self, dt: float) -> None:
        for f in self.feet:
            f.inp[f.dt_index] = dt

    def evaluate(self, foot: int) -> None:
        """Compute foot ``foot``'s patch forces (the state is not committed)."""
        self.feet[foot]._call()
        self.active[foot] = True

    def skip(self, foot: int) -> None:
        """Foot ``foot`` is clear of the terrain: zero force, contact state reset."""
        f = self.feet[foot]
        f.force[:] = 0.0
        f.diag[:] = 0.0
        f.new_state[:] = 0.0
        f.wrench_local[:] = 0.0
        self.active[foot] = False

    def commit(self) -> None:
        """Accept the evaluated step: the new patch states become the current ones."""
        for f in self.feet:
            f.state[:] = f.new_state

    def reset(self) -> None:
        for f in self.feet:
            f.state[:] = 0.0
            f.new_state[:] = 0.0

    def in_contact(self, foot: int) -> bool:
        return bool(self.feet[foot].state[:, 6].max() > 0.5)

    def set_param(self, name: str, value: float) -> None:
        i = self.model.param_names.index(name)
        for f in self.feet:
            f.params[i] = value

    def param(self, name: str) -> float:
        return float(self.feet[0].params[self.model.param_names.index(name)])


__all__ = ["CompiledContact", "ContactData", "SliceGeometry", "LawOutput", "slice_geometry",
           "elastic_trial", "to_basis", "from_basis", "clip", "N_KIN", "N_BASE_STATE",
           "DIAG_NAMES"]
