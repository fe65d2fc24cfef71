"""Closed-form RFT forces on the semi-cylindrical sole and its solidified wedge.

The derivation is written out in ``docs/model.md`` (section "Foot forces"); in short:

*Geometry* (one vertical slice of the foot, coordinates h forward along the foot heading,
depth positive down). The sole is an arc of radius R about the centre c; a point of the
circle is named by its world angle ψ from straight down (positive toward +h):
``P(ψ) = c + R (sin ψ, cos ψ)`` in (h, depth). The arc spans ``[ψ_c − ψ_max, ψ_c + ψ_max]``,
ψ_c being the foot's pitch in the slice (angle of its −z axis from world down). Under the
sole a solidified wedge forms whose faces slope at ±φ_s from the horizontal; each face is
tangent to the arc at ψ = ±φ_s (or starts at the arc end when the arc does not reach
that angle). The *effective intruder* is the back arc above the wedge, the two wedge faces
meeting at the apex A, the front arc, and the flat top (chord) of the foot.

*Forces*. RFT gives each element the stress ``(−α_x, α_z)(β, γ)·depth`` per area when it
moves into the medium (outward normal · velocity > 0). With the velocity mirrored so that
it points to +h, γ ∈ [−π/2, π/2] and:

* a wedge face (β = ±φ_s, linear depth) integrates to ``α/(2 sin φ_s)·W·(d_bot⁺² − d_top⁺²)``,
  i.e. the paper's ``F = α(n(φ_s), v)/(2 tan φ_s) · W · I(z_s)`` with
  ``I = (d_bot⁺² − d_top⁺²)/cos φ_s`` [m²] (the paper integrates over the horizontal
  projection; the 1/cos φ_s makes the area the true face area of Li et al.'s stresses);
* an arc element has β = ψ, depth ``d_c + R cos ψ`` and ds = R dψ; α is the trig polynomial
  ``a0 + a1 cos 2ψ + a2 sin 2ψ`` so the integral over the leading, submerged part
  ``ψ ∈ [max(ψ_a, −ψ_w, −γ), min(ψ_b, ψ_w)]`` (cos ψ_w = −d_c/R) is elementary;
* the chord (flat top) contributes only when buried and moving up into sand.

*Lateral*. Bulldozing of the side wall: ``F_y = (1 − e^{−|y_s|/λ}) α_y(π/2, γ_f) Q(z_s)``,
Q being the first moment of area (∫ depth dA) of the submerged side silhouette of foot and
wedge [m³]. In the paper's notation ``F_y = λ(1 − e^{−y_s/λ}) α_y g(z_s)`` with
``g = Q/λ`` [m²]: the fully developed pile resists with the RFT force on the side wall.
The sole also shears in-plane with ``α_sh · S₁``, S₁ = ∫ depth dA over the submerged sole.

The functions take an *ops* backend so the same source builds float values (plant loop)
and CasADi expressions (exact derivatives for the MPC and for calibration).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

from .rft import GENERIC, Coefficients, N_PER_CM3


class _FloatOps:
    sin = staticmethod(math.sin)
    cos = staticmethod(math.cos)
    tan = staticmethod(math.tan)
    sqrt = staticmethod(math.sqrt)
    atan2 = staticmethod(math.atan2)
    fmax = staticmethod(max)
    fmin = staticmethod(min)
    exp = staticmethod(math.exp)
    fabs = staticmethod(abs)

    @staticmethod
    def acos(x):
        return math.acos(min(1.0, max(-1.0, x)))

    @staticmethod
    def if_else(cond, a, b):
        return a if cond else b


FLOAT = _FloatOps()


def casadi_ops():
    """The CasADi backend (imported lazily: the plant loop never needs it)."""
    import casadi as ca

    class _CasadiOps:
        sin = staticmethod(ca.sin)
        cos = staticmethod(ca.cos)
        tan = staticmethod(ca.tan)
        sqrt = staticmethod(ca.sqrt)
        atan2 = staticmethod(ca.atan2)
        fmax = staticmethod(ca.fmax)
        fmin = staticmethod(ca.fmin)
        exp = staticmethod(ca.exp)
        fabs = staticmethod(ca.fabs)

        @staticmethod
        def acos(x):
            return ca.acos(ca.fmin(1.0, ca.fmax(-1.0, x)))

        @staticmethod
        def if_else(cond, a, b):
            return ca.if_else(cond, a, b)

    return _CasadiOps()


class FootShape(NamedTuple):
    """Sole geometry of one slice: radius R [m], arc half-angle ψ_max [rad], width W [m]."""

    radius: float
    half_angle: float
    width: float

    @classmethod
    def from_geometry(cls, geom, width: float | None = None) -> "FootShape":
        return cls(geom.radius, geom.half_angle, geom.width if width is None else width)


class SagittalForces(NamedTuple):
    """Closed-form results for one slice (SI units)."""

    f_h: Any        # force along +h (foot heading) [N]
    f_z: Any        # vertical force, + up [N]
    shear_moment: Any   # S₁ = W ∫ depth ds over the submerged sole and wedge [m³]
    side_moment: Any    # Q = ∫ depth dA over the submerged side silhouette [m³]
    apex_depth: Any     # depth of the wedge apex [m]


# ------------------------------------------------------------------------------ helpers

def _arc_moments(o, dc, R, a, b):
    """∫_a^b {1, cos2ψ, sin2ψ} · (d_c + R cos ψ) · R dψ, zero when b ≤ a."""
    b = o.fmax(a, b)

    def prim(p):
        s, c = o.sin(p), o.cos(p)
        s2, c2 = 2.0 * s * c, c * c - s * s
        s3, c3 = 3.0 * s - 4.0 * s * s * s, 4.0 * c * c * c - 3.0 * c
        i0 = dc * p + R * s
        ic = dc * s2 / 2.0 + R * (s3 / 3.0 + s) / 2.0
        is_ = -dc * c2 / 2.0 + R * (-c3 / 3.0 - c) / 2.0
        return i0, ic, is_

    pa, pb = prim(a), prim(b)
    return tuple(R * (vb - va) for va, vb in zip(pa, pb))


def _alpha_z_coeffs(o, c: Coefficients, gamma):
    sg, cg = o.sin(gamma), o.cos(gamma)
    return (c.A00 + c.B01 * sg, c.A10 + (c.B11 + c.Bm11) * sg, (c.B11 - c.Bm11) * cg)


def _alpha_x_coeffs(o, c: Coefficients, gamma):
    sg, cg = o.sin(gamma), o.cos(gamma)
    return (c.C01 * cg, (c.C11 + c.Cm11) * cg, (c.Cm11 - c.C11) * sg + c.D10)


def _alpha_at(o, coeffs3, beta):
    a0, a1, a2 = coeffs3
    return a0 + a1 * o.cos(2.0 * beta) + a2 * o.sin(2.0 * beta)


def _pos(o, x):
    return o.fmax(x, 0.0)


def _segment_depth_integral(o, d1, d2, length):
    """∫ depth⁺ ds along a straight segment whose depth goes linearly from d1 to d2."""
    p1, p2 = _pos(o, d1), _pos(o, d2)
    diff = d1 - d2
    safe = o.if_else(o.fabs(diff) > 1e-12, diff, 1.0)
    general = length * (p1 * p1 - p2 * p2) / (2.0 * safe)
    # level segment: the mean depth (same value as the limit of ``general``, and — unlike
    # ``length * p1`` — the right derivative with respect to both end depths)
    return o.if_else(o.fabs(diff) > 1e-12, general, length * 0.5 * (p1 + p2))


def _segment_depth_sq_integral(o, d1, d2, length):
    """∫ (depth⁺)² dh along a straight segment, depth linear from d1 to d2 over ``length``."""
    p1, p2 = _pos(o, d1), _pos(o, d2)
    diff = d1 - d2
    safe = o.if_else(o.fabs(diff) > 1e-12, diff, 1.0)
    general = length * (p1 ** 3 - p2 ** 3) / (3.0 * safe)
    # level segment: limit of ``general`` written symmetrically (right derivatives)
    return o.if_else(o.fabs(diff) > 1e-12, general, length * (p1 * p1 + p1 * p2 + p2 * p2) / 3.0)


def _arc_depth_sq_prim(o, dc, R, p):
    """Primitive in ψ of ∫ (d_c + R cos ψ)² dh with h = R sin ψ."""
    s, c = o.sin(p), o.cos(p)
    return (dc * dc + R * R) * R * s - R ** 3 * s ** 3 / 3.0 + dc * R * R * (s * c + p)


# ------------------------------------------------------------------------------ geometry

class WedgeGeometry(NamedTuple):
    dc: Any        # depth of the arc centre
    psi_lo: Any
    psi_hi: Any
    psi_b: Any     # back support angle (tangent point or arc end)
    psi_f: Any     # front support angle
    sb: tuple      # back support point (h, depth)
    sf: tuple      # front support point (h, depth)
    apex: tuple    # apex (h, depth)


def wedge_geometry(o, shape: FootShape, phi, depth, psi_c) -> WedgeGeometry:
    """Effective-intruder geometry for a sole whose lowest point is at ``depth`` [m]."""
    R, pm = shape.radius, shape.half_angle
    lo, hi = psi_c - pm, psi_c + pm
    low = o.fmin(o.fmax(0.0, lo), hi)           # angle of the lowest arc point
    dc = depth - R * o.cos(low)
    pf = o.fmax(o.fmin(phi, hi), lo)
    pb = o.fmin(o.fmax(-phi, lo), hi)
    sf = (R * o.sin(pf), dc + R * o.cos(pf))
    sb = (R * o.sin(pb), dc + R * o.cos(pb))
    cphi, sphi = o.cos(phi), o.sin(phi)
    s = ((sf[0] - sb[0]) / cphi + (sb[1] - sf[1]) / sphi) / 2.0
    apex = (sf[0] - s * cphi, sf[1] + s * sphi)
    return WedgeGeometry(dc, lo, hi, pb, pf, sb, sf, apex)


# ------------------------------------------------------------------------------ forces

def sagittal_forces(o, shape: FootShape, phi, depth, psi_c, v_h, v_z, *,
                    coeffs: Coefficients = GENERIC, zeta=1.0) -> SagittalForces:
    """Closed-form RFT force on one slice of the sole + solidified wedge.

    Args:
        o: ops backend (:data:`FLOAT` or :func:`casadi_ops`).
        shape: sole radius, arc half-angle and slice width.
        phi: solidified-zone angle φ_s [rad].
        depth: depth of the lowest sole point below the free surface [m] (> 0 in sand).
        psi_c: foot pitch in the slice: angle of the foot's −z axis from world down,
            positive toward +h [rad].
        v_h, v_z: direction of motion of the sole (only the direction matters) along the
            heading and vertically (+ up) [any consistent unit].
        coeffs: RFT Fourier coefficients (generic units); ``zeta``: the medium's scale.

    Returns:
        :class:`SagittalForces` (forces in N on the foot, h along the heading, z up).
    """
    R, W = shape.radius, shape.width
    # Mirror so that the motion points to +h (Li's convention); un-mirror f_h at the end.
    mirror = v_h < 0.0
    sgn = o.if_else(mirror, -1.0, 1.0)
    vh_m = sgn * v_h
    psi_m = sgn * psi_c
    gamma = o.atan2(-v_z, vh_m)
    g = wedge_geometry(o, shape, phi, depth, psi_m)
    dc = g.dc
    # submerged half-angle of the circle: cos ψ_w = −d_c / R
    psi_w = o.acos(-dc / R)
    az = _alpha_z_coeffs(o, coeffs, gamma)
    ax = _alpha_x_coeffs(o, coeffs, gamma)
    pi = math.pi

    fz = 0.0
    fx = 0.0   # α_x-weighted (resistive, mirrored frame)
    s1 = 0.0
    # arcs: back [lo, ψ_b] and front [ψ_f, hi]
    for a, b in ((g.psi_lo, g.psi_b), (g.psi_f, g.psi_hi)):
        lo_l = o.fmax(o.fmax(a, -psi_w), -gamma)
        hi_l = o.fmin(o.fmin(b, psi_w), pi - gamma)
        i0, ic, is_ = _arc_moments(o, dc, R, lo_l, hi_l)
        fz = fz + az[0] * i0 + az[1] * ic + az[2] * is_
        fx = fx + ax[0] * i0 + ax[1] * ic + ax[2] * is_
        j0, _, _ = _arc_moments(o, dc, R, o.fmax(a, -psi_w), o.fmin(b, psi_w))
        s1 = s1 + j0
    # wedge faces: depth integral (d_bot⁺² − d_top⁺²)/(2 sin φ)
    sphi = o.sin(phi)
    dA = g.apex[1]
    for top_depth, beta, leading in ((g.sf[1], phi, gamma > -phi),
                                     (g.sb[1], -phi, gamma > phi)):
        integral = (_pos(o, dA) ** 2 - _pos(o, top_depth) ** 2) / (2.0 * sphi)
        lead = o.if_else(leading, 1.0, 0.0)
        fz = fz + lead * _alpha_at(o, az, beta) * integral
        fx = fx + lead * _alpha_at(o, ax, beta) * integral
        s1 = s1 + integral
    # flat top (chord) between the arc ends; outward normal is the foot's +z axis
    d_lo = dc + R * o.cos(g.psi_lo)
    d_hi = dc + R * o.cos(g.psi_hi)
    chord = 2.0 * R * o.sin(shape.half_angle)
    top_int = _segment_depth_integral(o, d_lo, d_hi, chord)
    lead_top = o.if_else(o.sin(psi_m + gamma) < 0.0, 1.0, 0.0)
    fz = fz + lead_top * _alpha_at(o, az, psi_m) * top_int
    fx = fx + lead_top * _alpha_at(o, ax, psi_m) * top_int

    scale = zeta * N_PER_CM3 * W
    f_h = -sgn * scale * fx
    f_z = scale * fz
    # side silhouette first moment Q = ∫ (D_bot⁺² − D_top⁺²)/2 dh
    q_bot = 0.0
    for a, b in ((g.psi_lo, g.psi_b), (g.psi_f, g.psi_hi)):
        lo_l = o.fmax(a, -psi_w)
        hi_l = o.fmax(lo_l, o.fmin(b, psi_w))
        q_bot = q_bot + (_arc_depth_sq_prim(o, dc, R, hi_l) - _arc_depth_sq_prim(o, dc, R, lo_l))
    tphi = o.tan(phi)
    for top_depth in (g.sf[1], g.sb[1]):
        q_bot = q_bot + (_pos(o, dA) ** 3 - _pos(o, top_depth) ** 3) / (3.0 * tphi)
    span = R * (o.sin(g.psi_hi) - o.sin(g.psi_lo))
    q_top = _segment_depth_sq_integral(o, d_lo, d_hi, span)
    side = o.fmax(0.5 * (q_bot - q_top), 0.0)
    return SagittalForces(f_h, f_z, W * s1, side, dA)


def lateral_capacity(o, shape: FootShape, forces: SagittalForces, v_l, v_z, y_slip, *,
                     zeta, bulldozing_length, shear_alpha, full_width: float,
                     coeffs: Coefficients = GENERIC):
    """Largest lateral resistance [N] of one slice: sole shear + bulldozing of the side wall.

    ``F = ζ[α_sh S₁ + (1 − e^{−|y_s|/λ}) α_y(π/2, γ_f) Q · W_slice/W]`` with
    γ_f = atan2(−v_z, |v_l|) and α_y(π/2, γ) = (C01 − C11 − C₋₁₁) cos γ.
    """
    gamma_f = o.atan2(-v_z, o.fabs(v_l))
    alpha_y = (coeffs.C01 - coeffs.C11 - coeffs.Cm11) * o.cos(gamma_f)
    pile = 1.0 - o.exp(-o.fabs(y_slip) / bulldozing_length)
    share = shape.width / full_width
    return zeta * N_PER_CM3 * (shear_alpha * forces.shear_moment
                               + pile * o.fmax(alpha_y, 0.0) * forces.side_moment * share)


def yield_polygon(shape: FootShape, phi: float, depth: float, *,
                  coeffs: Coefficients = GENERIC, zeta: float = 1.0) -> tuple[float, float, float]:
    """Inner polygon of the sagittal RFT yield curve of a level foot at ``depth`` [m].

    The curve is the force ``(F_h(γ), F_z(γ))`` the medium exerts while the foot flows in
    direction γ; forces strictly inside it are held without flow. Returns ``(μ_h, κ_h,
    F_cap)`` of the polygon ``|F_h| ≤ min(μ_h F_z, κ_h (F_cap − F_z))``, ``0 ≤ F_z ≤ F_cap``:
    μ_h is the shear/normal ratio of the 45° flow (still penetrating), κ_h the steepest
    chord from the vertical yield point that stays inside the curve for flows at 45°–89°.
    Normalised by F_cap the curve barely changes with depth, so the ratios serve any depth.
    """
    cap = sagittal_forces(FLOAT, shape, phi, depth, 0.0, 0.0, -1.0, coeffs=coeffs,
                          zeta=zeta).f_z
    pts = []
    for g_deg in [45.0 + 44.0 * k / 11.0 for k in range(12)]:
        g = math.radians(g_deg)
        r = sagittal_forces(FLOAT, shape, phi, depth, 0.0, math.cos(g), -math.sin(g),
                            coeffs=coeffs, zeta=zeta)
        pts.append((abs(float(r.f_h)), float(r.f_z)))
    mu_h = pts[0][0] / pts[0][1]
    kappa_h = min(fh / max(cap - fz, 1e-9) for fh, fz in pts)
    return float(mu_h), float(kappa_h), float(cap)


def wedge_area(shape: FootShape, phi: float, psi_c: float = 0.0) -> tuple[float, float]:
    """Area of the solidified wedge cross-section [m²] and its height (apex to support) [m]."""
    g = wedge_geometry(FLOAT, shape, phi, 0.0, psi_c)
    (bh, bd), (fh, fd), (ah, ad) = g.sb, g.sf, g.apex
    tri = 0.5 * abs((fh - bh) * (ad - bd) - (ah - bh) * (fd - bd))
    dpsi = g.psi_f - g.psi_b
    segment = 0.5 * shape.radius ** 2 * (dpsi - math.sin(dpsi))
    return max(tri - segment, 0.0), ad - min(bd, fd)


__all__ = ["FLOAT", "casadi_ops", "FootShape", "SagittalForces", "sagittal_forces",
           "lateral_capacity", "wedge_geometry", "wedge_area", "yield_polygon"]
