"""Brute-force RFT: sum Li et al.'s stresses over a finely discretised foot + wedge contour.

This is the independent reference for :mod:`.closed_form`: the contour is built here from
points (arc samples, tangent points, the apex by line intersection), every element gets
its own normal, attack angle and the *folded* α(β, γ) of :func:`.rft.alpha` — no mirroring,
no analytic integration. It is slow by design; the plant uses the closed form.
"""

from __future__ import annotations

import math

import numpy as np

from .closed_form import FootShape
from .rft import GENERIC, Coefficients, N_PER_CM3, alpha


def effective_contour(shape: FootShape, phi: float, depth: float, psi_c: float,
                      n: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """Closed polyline of the effective intruder in (h, z_up) coordinates, surface z = 0.

    Returns:
        points (N, 2) ordered clockwise in the (h, z) plane when viewed with +y toward the
        viewer (back arc → wedge → front arc → chord), and a boolean mask marking which
        segments belong to the *bottom* (sole + wedge), as opposed to the flat top.
    """
    R, pm = shape.radius, shape.half_angle
    lo, hi = psi_c - pm, psi_c + pm
    low = min(max(0.0, lo), hi)
    centre = np.array([0.0, -(depth - R * math.cos(low))])   # z_up of the centre

    def P(psi):
        return centre + R * np.array([math.sin(psi), -math.cos(psi)])

    pf = max(min(phi, hi), lo)
    pb = min(max(-phi, lo), hi)
    Sf, Sb = P(pf), P(pb)
    # faces: from Sf going down-back at slope φ, from Sb going down-forward
    uf = np.array([-math.cos(phi), -math.sin(phi)])
    ub = np.array([math.cos(phi), -math.sin(phi)])
    st = np.linalg.solve(np.column_stack([uf, -ub]), Sb - Sf)
    apex = Sf + st[0] * uf
    m = max(n // 4, 50)
    back_arc = [P(p) for p in np.linspace(lo, pb, m)] if pb > lo else [P(lo)]
    back_face = [Sb + s * (apex - Sb) for s in np.linspace(0.0, 1.0, m)[1:]]
    front_face = [apex + s * (Sf - apex) for s in np.linspace(0.0, 1.0, m)[1:]]
    front_arc = [P(p) for p in np.linspace(pf, hi, m)[1:]] if hi > pf else []
    bottom = back_arc + back_face + front_face + front_arc
    top = [P(hi) + s * (P(lo) - P(hi)) for s in np.linspace(0.0, 1.0, m)[1:]]
    pts = np.array(bottom + top)
    is_bottom = np.zeros(len(pts) - 1, dtype=bool)
    is_bottom[: len(bottom) - 1] = True
    return pts, is_bottom


def sagittal_forces_numeric(shape: FootShape, phi: float, depth: float, psi_c: float,
                            v_h: float, v_z: float, *, coeffs: Coefficients = GENERIC,
                            zeta: float = 1.0, n: int = 4000) -> dict:
    """RFT force [N] on one slice by direct summation over contour elements.

    Same arguments as :func:`.closed_form.sagittal_forces`; returns a dict with
    ``f_h, f_z, shear_moment, side_moment``.
    """
    pts, is_bottom = effective_contour(shape, phi, depth, psi_c, n)
    a, b = pts[:-1], pts[1:]
    mid = 0.5 * (a + b)
    seg = b - a
    ds = np.hypot(seg[:, 0], seg[:, 1])
    keep = ds > 0
    # The polyline runs back → bottom → front → top, i.e. counter-clockwise in (h, z_up):
    # the outward normal is the tangent turned clockwise, (t_z, −t_h).
    t = seg[keep] / ds[keep, None]
    normal = np.column_stack([t[:, 1], -t[:, 0]])
    depth_el = -mid[keep, 1]
    vel = np.array([v_h, v_z], dtype=float)
    gamma = math.atan2(-v_z, v_h)
    fh = fz = 0.0
    shear = 0.0
    for k in range(len(t)):
        d = depth_el[k]
        if d <= 0.0:
            continue
        if is_bottom[keep][k]:
            shear += d * ds[keep][k]
        if normal[k] @ vel <= 0.0:
            continue
        beta = math.atan2(t[k, 1], t[k, 0])
        ax, az = alpha(beta, gamma, coeffs)
        fh -= ax * d * ds[keep][k]
        fz += az * d * ds[keep][k]
    scale = zeta * N_PER_CM3 * shape.width
    side = side_moment_numeric(pts, n_grid=int(math.sqrt(n)) * 8)
    return {"f_h": scale * fh, "f_z": scale * fz,
            "shear_moment": shape.width * shear, "side_moment": side}


def side_moment_numeric(pts: np.ndarray, n_grid: int = 500) -> float:
    """∫ depth dA over the part of the closed polygon below z = 0, by a 2-D midpoint grid."""
    from matplotlib.path import Path

    h0, h1 = pts[:, 0].min(), pts[:, 0].max()
    z0 = pts[:, 1].min()
    if z0 >= 0.0:
        return 0.0
    hs = np.linspace(h0, h1, n_grid + 1)
    zs = np.linspace(z0, 0.0, n_grid + 1)
    hc, zc = 0.5 * (hs[1:] + hs[:-1]), 0.5 * (zs[1:] + zs[:-1])
    H, Z = np.meshgrid(hc, zc)
    inside = Path(pts).contains_points(np.column_stack([H.ravel(), Z.ravel()]))
    cell = (hs[1] - hs[0]) * (zs[1] - zs[0])
    return float(np.sum(-Z.ravel()[inside]) * cell)


__all__ = ["effective_contour", "sagittal_forces_numeric", "side_moment_numeric"]
