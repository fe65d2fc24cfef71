"""Per-foot and depth-layered variants of the terrain law, as terrain-force effects.

Sand is not always the same under both feet or at every depth: a left and a right track
of different sand, one worn sole, a loose top layer over a harder one. A terrain-force
effect sees which foot a patch belongs to (:attr:`PatchState.foot`, 0 left / 1 right, with
:attr:`~PatchState.is_left` / :attr:`~PatchState.is_right` to multiply by) and the
patch's depth below the free surface (:attr:`PatchState.depth`), so such terms are
ordinary effects. This module offers

* :func:`per_foot_variant` — any registered terrain force acting on one foot only, as a
  new effect ``<base>_<side>`` with the base's parameters (``cohesion_right``: the wet
  sand of the right track);
* ``stress_scale`` — the terrain's own force on the patch scaled by (1 + g) (sand that
  bears more or less than the law says); with :func:`per_foot_variant`, ``stress_scale_left``
  / ``stress_scale_right``: one foot's track of different sand, or one worn sole;
* ``hard_layer`` — a harder (ratio > 1) or looser (ratio < 1) layer of sand below the
  interface depth d_L (not the terrain's ``layer_depth``: the sand's thickness over a
  rigid floor, which the law itself models).

**Opt-in.** Importing this module defines the functions; :func:`register_variants`
(idempotent) registers ``stress_scale``, ``stress_scale_left``, ``stress_scale_right``
and ``hard_layer``. :mod:`granular_mpc.effects` does not call it, so the default
candidates of ``diagnose`` (every registered effect) stay the library's. The effects are
then named like any other (``effects: ["hard_layer:ratio=3,interface_depth=0.012"]`` in
a terrain file, ``--effect hard_layer:ratio=3``). They must be registered before the terrain
that uses them is built (the contact law is compiled with its effects).
"""

from __future__ import annotations

from typing import Callable

from ..columns import FOOT_SIDES
from ..exceptions import ConfigError
from .api import register_effect
from .params import Param
from .registry import effect_info, get_effect, registered_names
from .state import PatchState

#: tag of the per-foot variants
PER_FOOT_TAG = "per_foot"
#: tag of the depth-profile terms
LAYERED_TAG = "layered"
#: the effects :func:`register_variants` registers
VARIANTS = ("stress_scale", "stress_scale_left", "stress_scale_right", "hard_layer")


def stress_scale(o, s: PatchState, p):
    """The sand bears (1 + g) times the terrain law's stress on the patch.

    f = g · f_terrain while in contact: while the medium yields this is a (1 + g) times
    stronger (g > 0) or weaker (g < 0) yield capacity; while the sole rests it only rescales
    the elastic regularisation, so it never chatters. On its own it mimics a different ζ;
    as ``stress_scale_left`` / ``stress_scale_right`` it is one foot's track of other sand
    (or one worn sole). g = 0: off.
    """
    k = p["gain"] * s.in_contact
    return (k * s.f_terrain[0], k * s.f_terrain[1], k * s.f_terrain[2])


def hard_layer(o, s: PatchState, p):
    """A layer of harder (ratio > 1) or looser (ratio < 1) sand below the depth d_L.

    RFT's stress grows linearly with depth; below the interface at d_L it grows ``ratio``
    times as fast: capacity(d) = k d + (r − 1) k (d − d_L)⁺. The terrain force of the patch
    is scaled accordingly, f = f_terrain (r − 1) (d − d_L)⁺ / d, exactly zero above the
    interface (the top layer is the terrain's own law) and continuous across it. A loose
    top layer of thickness d_L over a harder bed is r > 1. r = 1: off.
    """
    d = o.fmax(s.depth, 1e-4)
    below = o.fmax(s.depth - p["interface_depth"], 0.0)
    k = (p["ratio"] - 1.0) * below / d * s.in_contact
    return (k * s.f_terrain[0], k * s.f_terrain[1], k * s.f_terrain[2])


def _one_foot(fn: Callable, side: str) -> Callable:
    """``fn`` multiplied by the 0/1 indicator of ``side`` (works on floats and CasADi)."""
    right = side == FOOT_SIDES[1]

    def on_one_foot(o, s: PatchState, p):
        mask = s.is_right if right else s.is_left
        f = fn(o, s, p)
        return (mask * f[0], mask * f[1], mask * f[2])

    on_one_foot.__wrapped__ = fn      # errors name the base's source file
    return on_one_foot


def per_foot_variant(base: str, side: str, *, name: str | None = None) -> str:
    """Register the terrain force ``base`` acting on the ``side`` foot only.

    The variant has the base's parameters, main coefficient and neutral values, its
    ``depends_on`` plus the foot, and the tag :data:`PER_FOOT_TAG`. Registering the same
    variant again returns its name (idempotent).

    Args:
        base: a registered terrain-force effect.
        side: ``left`` or ``right``.
        name: the variant's name (default ``<base>_<side>``).

    Returns:
        The variant's name.

    Raises:
        ConfigError: ``base`` is not a registered terrain force, or ``side`` is not a foot.
    """
    if side not in FOOT_SIDES:
        raise ConfigError(f"unknown foot side {side!r}", key="effects", value=side,
                          allowed=", ".join(FOOT_SIDES))
    info = get_effect(base)
    name = name or f"{base}_{side}"
    if name in registered_names():
        existing = effect_info(name)
        if existing.kind == "terrain_force" and PER_FOOT_TAG in existing.tags:
            return name
    fn = _one_foot(info.fn, side)
    fn.__doc__ = (f"``{base}`` on the {side} foot only (zero on the other foot).\n\n"
                  f"{info.doc}")
    register_effect(name, params=dict(info.params), main=info.main,
                    neutral=dict(info.neutral),
                    depends_on=tuple(info.depends_on) + (f"{side} foot only",),
                    tags=tuple(t for t in info.tags if t != PER_FOOT_TAG) + (PER_FOOT_TAG,)
                    )(fn)
    return name


def register_variants() -> tuple[str, ...]:
    """Register :data:`VARIANTS` (idempotent); returns their names."""
    known = set(registered_names())
    if "stress_scale" not in known:
        register_effect("stress_scale", params={
            "gain": Param(0.3, -0.8, 3.0, "-",
                          "relative change of the stress the sand bears (0: the law's)"),
        }, main="gain", depends_on=("the terrain law's own force",))(stress_scale)
    for side in FOOT_SIDES:
        per_foot_variant("stress_scale", side)
    if "hard_layer" not in known:
        register_effect("hard_layer", params={
            "ratio": Param(3.0, 0.2, 20.0, "-",
                           "stress gradient below the interface over that above it (1: none)"),
            "interface_depth": Param(0.015, 0.002, 0.08, "m",
                                 "depth of the interface below the free surface"),
        }, main="ratio", neutral={"ratio": 1.0}, depends_on=("depth below the layer interface",),
            tags=(LAYERED_TAG,))(hard_layer)
    return VARIANTS


__all__ = ["PER_FOOT_TAG", "LAYERED_TAG", "VARIANTS", "stress_scale", "hard_layer",
           "per_foot_variant", "register_variants"]
