"""Granular terrain: RFT closed form with solidified wedge, bulldozing and added mass.

The patch law (see :mod:`.contact`) clips a stiff elastic trial force to the RFT flow
force of the current direction of motion:

* direction of motion ``u = v_c + e/τ`` (velocity plus elastic displacement over a short
  time constant, so a resting foot still has a direction: the way it is pressed);
* vertical and heading components within ``[min(0, F_RFT), max(0, F_RFT)]`` of the closed
  form of :mod:`.closed_form` (sagittal slice, mirrored to the direction of motion); the
  heading bound also covers the static interior of the yield curve at the present depth
  (``|F_h| ≤ min(μ_s F_z, κ_s(F_cap − F_z))``, :func:`.closed_form.yield_polygon`), so a
  resting loaded foot holds shear without creeping;
* lateral component within ``ζ[α_sh S₁ + (1 − e^{−|y_s|/λ}) α_y Q]`` (shear + bulldozing);
* extraction: the closed form's sole elements do not lead when the foot rises, so the
  only pull-down is RFT's own α_z < 0 on buried rear / top elements — no invented suction;
* a finite layer: below ``layer_depth`` the foot meets rigid ground (stiff normal spring);
* the solidified wedge's grains move with the foot: added mass m_a(z) and its momentum
  flux ṁ_a v (Aguilar & Goldman 2016), added by :class:`.contact.CompiledContact`.
"""

from __future__ import annotations

import math

from .closed_form import FootShape, lateral_capacity, sagittal_forces, wedge_area, yield_polygon
from .contact import LawOutput, clip, elastic_trial, from_basis, to_basis
from .rft import Coefficients

#: calibratable / tunable parameters of the granular law, in θ order
GRANULAR_PARAMS = ("surface_height", "surface_slope_x", "surface_slope_y", "zeta", "phi_s", "bulldozing_length", "sole_shear_alpha",
                   "added_mass_scale", "layer_depth", "contact_stiffness", "contact_damping",
                   "direction_time_constant")


def granular_param_values(cfg) -> list[float]:
    return [cfg.surface_height, cfg.surface_slope[0], cfg.surface_slope[1], cfg.zeta, math.radians(cfg.phi_s_deg), cfg.bulldozing_length,
            cfg.sole_shear_alpha, cfg.added_mass_scale, cfg.layer_depth, cfg.contact_stiffness,
            cfg.contact_damping, cfg.direction_time_constant]


def make_granular_law(cfg, slice_shape: FootShape, full_width: float):
    """Return the patch law for a granular medium described by ``cfg``."""
    coeffs = Coefficients.from_config(cfg.rft)
    density = cfg.density  # bulk density: grains × packing fraction
    area_w, height_w = wedge_area(slice_shape, math.radians(cfg.phi_s_deg))
    floor_k = 2.0 * cfg.contact_stiffness
    # the static part of the yield curve (shape ratios at a walking depth; see yield_polygon)
    mu_s, kappa_s, _ = yield_polygon(slice_shape, math.radians(cfg.phi_s_deg), 0.02,
                                     coeffs=coeffs, zeta=cfg.zeta)

    def law(o, g, e_prev, c0, th, dt) -> LawOutput:
        K, D = th["contact_stiffness"], th["contact_damping"]
        phi, zeta = th["phi_s"], th["zeta"]
        f_tr, e = elastic_trial(K, D, g, e_prev, dt)
        h, l = g.heading, g.lateral
        tau = th["direction_time_constant"]
        u = tuple(g.v_c[i] + e[i] / tau for i in range(3))
        u_h, u_l, u_z = to_basis(u, h, l)
        u_z = u_z - 1e-7          # at exact rest the medium is pressed, not pulled
        sag = sagittal_forces(o, slice_shape, phi, g.depth, g.psi_c, u_h, u_z,
                              coeffs=coeffs, zeta=zeta)
        y_slip = (g.p_c[0] - c0[0]) * l[0] + (g.p_c[1] - c0[1]) * l[1]
        cap_l = lateral_capacity(o, slice_shape, sag, u_l, u_z, y_slip, zeta=zeta,
                                 bulldozing_length=th["bulldozing_length"],
                                 shear_alpha=th["sole_shear_alpha"], full_width=full_width,
                                 coeffs=coeffs)
        t_h, t_l, t_z = to_basis(f_tr, h, l)
        # pure-penetration capacity at this depth (also reported as f_cap_z)
        cap_z = sagittal_forces(o, slice_shape, phi, g.depth, g.psi_c, 0.0, -1.0,
                                coeffs=coeffs, zeta=zeta).f_z
        # Heading bounds: the flow force of the current direction, widened by the static
        # part of the yield curve at this depth — a force strictly inside the curve is held
        # without flow, so a resting loaded foot resists shear up to
        # min(μ_s F_z, κ_s (F_cap − F_z)); at the vertical yield point this is zero and only
        # the flow force remains (slip-sink coupling of RFT).
        t_zp = o.fmax(t_z, 0.0)
        static_h = o.fmax(o.fmin(mu_s * t_zp, kappa_s * (o.fmax(cap_z, 0.0) - t_zp)), 0.0)
        f_h = clip(o, t_h, o.fmin(o.fmin(0.0, sag.f_h), -static_h),
                   o.fmax(o.fmax(0.0, sag.f_h), static_h))
        # Vertical bounds. Sinking (u_z < 0): [min(0, F_z(u)), max(0, F_z(u))], the flow
        # force of the current direction. Rising (u_z > 0) a compressed spring unloads
        # elastically: the upper bound stays at the penetration capacity instead of
        # dropping to max(0, F_z(up)) = 0, which would let go of a loaded foot on any
        # rebound faster than |e|/τ and make it ratchet down (creep) under vibration.
        f_z_hi = o.if_else(u_z > 0.0, o.fmax(cap_z, 0.0), o.fmax(0.0, sag.f_z))
        f_z = clip(o, t_z, o.fmin(0.0, sag.f_z), f_z_hi)
        f_l = clip(o, t_l, -cap_l, cap_l)
        e_h, e_l, e_z = to_basis(e, h, l)
        tol = 1e-9

        def settle(f, t, e_i):
            return o.if_else(o.fabs(f - t) > tol * (1.0 + o.fabs(t)), -f / K, e_i)

        e_new = from_basis((settle(f_h, t_h, e_h), settle(f_l, t_l, e_l), settle(f_z, t_z, e_z)),
                           h, l)
        # rigid floor under the layer
        below = g.depth - th["layer_depth"]
        f_floor = o.if_else(below > 0.0, o.fmax(floor_k * below - D * g.v_c[2], 0.0), 0.0)
        force = from_basis((f_h, f_l, f_z + f_floor), h, l)
        # submerged horizontal extent: where the free surface cuts the arc or the wedge
        R = slice_shape.radius
        dc = g.depth - R
        cut_arc = R * o.sqrt(o.fmax(1.0 - (dc / R) ** 2, 0.0))
        cut_wedge = o.fmax(sag.apex_depth, 0.0) / o.tan(phi)
        half = o.if_else(-dc / R < o.cos(phi), cut_arc, cut_wedge)
        area_h = 2.0 * half * slice_shape.width
        # added mass of the solidified wedge, growing as its submerged part (∝ apex depth²)
        frac = o.fmin(o.fmax(sag.apex_depth, 0.0) / height_w, 1.0)
        m_full = th["added_mass_scale"] * density * slice_shape.width * area_w
        m_a = m_full * frac * frac
        dfrac = o.if_else(frac < 1.0, 1.0 / height_w, 0.0)
        m_rate = m_full * 2.0 * frac * dfrac * (-g.v_c[2])
        return LawOutput(force, e_new, cap_z, area_h, m_a, m_rate)

    return law


__all__ = ["GRANULAR_PARAMS", "granular_param_values", "make_granular_law"]
