"""Rigid ground: non-sinking, non-slipping up to Coulomb friction.

Normal: a stiff unilateral spring–damper on the penetration below the surface (≈ W/K, a
fraction of a millimetre). Tangential: an elastic displacement (stick) clipped to the
Coulomb disc |F_t| ≤ μ F_n; beyond it the sole slides (slip).
"""

from __future__ import annotations

from .contact import LawOutput, elastic_trial, from_basis, to_basis

RIGID_PARAMS = ("surface_height", "surface_slope_x", "surface_slope_y", "friction", "contact_stiffness", "contact_damping")


def rigid_param_values(cfg) -> list[float]:
    return [cfg.surface_height, cfg.surface_slope[0], cfg.surface_slope[1], cfg.friction, cfg.contact_stiffness, cfg.contact_damping]


def make_rigid_law(cfg):
    def law(o, g, e_prev, c0, th, dt) -> LawOutput:
        K, D, mu = th["contact_stiffness"], th["contact_damping"], th["friction"]
        f_tr, e = elastic_trial(K, D, g, e_prev, dt)
        h, l = g.heading, g.lateral
        t_h, t_l, _ = to_basis(f_tr, h, l)
        f_n = o.fmax(K * g.depth - D * g.v_c[2], 0.0)
        t_norm = o.sqrt(t_h * t_h + t_l * t_l + 1e-18)
        limit = mu * f_n
        slide = t_norm > limit
        ratio = o.if_else(slide, limit / t_norm, 1.0)
        f_h, f_l = ratio * t_h, ratio * t_l
        e_h, e_l, _ = to_basis(e, h, l)
        e_h = o.if_else(slide, -f_h / K, e_h)
        e_l = o.if_else(slide, -f_l / K, e_l)
        e_new = from_basis((e_h, e_l, 0.0), h, l)
        force = from_basis((f_h, f_l, f_n), h, l)
        return LawOutput(force, e_new, f_n, 0.0)

    return law


__all__ = ["RIGID_PARAMS", "rigid_param_values", "make_rigid_law"]
