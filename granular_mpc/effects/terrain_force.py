"""Library effects of kind ``terrain_force``: forces added to the foot–terrain contact.

Each is ``fn(o, s: PatchState, p) -> (fx, fy, fz)`` [N] in W per contact patch, written
with the ``o`` namespace so it compiles into the plant's CasADi contact function and
evaluates on floats. They depend on displacement (rise from the deepest point) or scale
the law's own force rather than switching on velocity signs, so they never chatter when
the sole rests. Defaults are magnitudes a YoboGo-10S-class robot on sand would notice:

* ``inertial_drag``: −½ c_d ρ A_h |v| v;
* ``cohesion``: suction of wet sand resisting pull-out;
* ``depth_hardening``: stress ∝ depthⁿ instead of depth¹;
* ``elastic_unloading``: compacted sand pushing a rising sole back.
"""

from __future__ import annotations

from .api import register_effect
from .params import Param
from .state import PatchState


@register_effect("inertial_drag", params={
    "c_d": Param(1.0, 0.0, 20.0, "-", "drag coefficient of the submerged sole"),
}, main="c_d", depends_on=("sole speed squared",))
def inertial_drag(o, s: PatchState, p):
    """Inertial (velocity-squared) drag of the grains the sole sets in motion.

    F = −½ c_d ρ A_h |v| v while in contact (Katsuragi & Durian, Nature Physics 2007: the
    v² term of granular impact drag). A_h: horizontal area of the submerged sole.
    """
    vx, vy, vz = s.v_c
    speed = o.sqrt(vx * vx + vy * vy + vz * vz + 1e-12)
    k = -0.5 * p["c_d"] * s.density * s.area_h * speed * s.in_contact
    return (k * vx, k * vy, k * vz)


@register_effect("cohesion", params={
    "suction": Param(3000.0, 0.0, 50000.0, "Pa",
                     "largest suction (pull-out) stress on the submerged sole area"),
    "release": Param(0.003, 0.0005, 0.05, "m",
                     "rise from the deepest point over which the suction builds up"),
}, main="suction", depends_on=("rise of the sole from its deepest point (pull-out)",))
def cohesion(o, s: PatchState, p):
    """Suction of wet (cohesive) sand resisting the pull-out of a buried sole.

    f_z = −σ_c A_h (1 − e^{−δ/δ_c}),  δ = depth_max − depth ≥ 0 (rise since the deepest
    point of this stance), A_h the submerged horizontal sole area. The capillary bridges
    hold the sole once it starts to rise; the pull grows over ``release`` δ_c and acts
    until the sole leaves the sand. Depends on displacement, not velocity, so it never
    chatters when the sole rests. Dry sand: σ_c = 0; wet sand: a few kPa.
    """
    rise = o.fmax(s.depth_max - s.depth, 0.0)
    k = -p["suction"] * s.area_h * (1.0 - o.exp(-rise / p["release"])) * s.in_contact
    return (0.0, 0.0, k)


@register_effect("depth_hardening", params={
    "n": Param(1.5, 0.3, 3.0, "-", "exponent of depth in the stress law (1: RFT, no effect)",
               physical=(1.0, 3.0)),
    "d_ref": Param(0.02, 0.002, 0.1, "m", "depth at which the stress equals the RFT value"),
}, main="n", neutral={"n": 1.0},
    depends_on=("depth (relative to d_ref)", "load during penetration"))
def depth_hardening(o, s: PatchState, p):
    """Stress ∝ depthⁿ instead of RFT's depth¹ (compaction: deeper sand is stiffer).

    The terrain force of the patch is scaled by (d/d_ref)^{n−1}: f = f_terrain ·
    ((d/d_ref)^{n−1} − 1), depth d clamped to [1 mm, 10 d_ref]. While the medium yields
    (penetration) this is the hardened capacity F_yield (d/d_ref)^{n−1}; while the sole
    rests it only rescales the elastic regularisation, so it never chatters. n = 1: off.
    """
    d = o.fmin(o.fmax(s.depth, 1e-3), 10.0 * p["d_ref"])
    factor = (d / p["d_ref"]) ** (p["n"] - 1.0) - 1.0
    k = factor * s.in_contact
    return (k * s.f_terrain[0], k * s.f_terrain[1], k * s.f_terrain[2])


@register_effect("elastic_unloading", params={
    "pressure": Param(4000.0, 0.0, 50000.0, "Pa",
                      "peak rebound pressure of the compacted sand on the submerged sole"),
    "recovery": Param(0.002, 0.0003, 0.02, "m", "rise at which the rebound peaks"),
}, main="pressure", depends_on=("rise of the sole from its deepest point (unloading)",))
def elastic_unloading(o, s: PatchState, p):
    """Compacted sand springing back under a sole that rises from its deepest point.

    f_z = p_r A_h (δ/δ_r) e^{1 − δ/δ_r},  δ = depth_max − depth ≥ 0: zero while the sole
    penetrates (δ = 0), the largest push-back p_r A_h at δ = δ_r, fading as the sole leaves
    the compacted zone. Depends on the rise, not on velocity.
    """
    rise = o.fmax(s.depth_max - s.depth, 0.0)
    x = rise / p["recovery"]
    k = p["pressure"] * s.area_h * x * o.exp(1.0 - x) * s.in_contact
    return (0.0, 0.0, k)


__all__ = ["inertial_drag", "cohesion", "depth_hardening", "elastic_unloading"]
