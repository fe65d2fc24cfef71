"""Structure left in the foot-force equation error after the additions
(``docs/validation.md`` §3.7, "The force the foot meets while it sinks").

The replays judge an addition by the channels it moves, and a term can pass them as a
proxy: a rebound of the sand while the sole rises (``elastic_unloading``) stiffens the
stance much as a harder layer below 20 mm does, its replays improve every credited channel
and the localised structure goes — while the force the foot meets *while it sinks* is not
one it produces (it acts only once the sole has risen from its deepest point). The
foot-force equation error at the measured state (§3.6: measured force − the calibrated
closed-form law at the measured depth, pitch and direction of motion, ζ free) shows that
force directly, free of the replay's drift. After the additions it is asked again, with
the added terrain-force effects' own force at the measured state as free columns beside
ζ: if the feature library of §3.6 still explains at least
:data:`~.proposal.MIN_EXPLAINED_FORCE` of it on an axis — the threshold of the proposal's
evidence rule, above what data without a missing foot force explain — the additions have
not explained the foot force, whatever the replays say, and the verdict says so.

The added effects are evaluated on each sinking sample as the contact law evaluates them on
one of the foot's patches, from the foot-level measured state: the patch's share of the
law's force (``f_terrain``, also taken as the yield force ``f_yield_z``: the medium yields
while the sole sinks), the sole arc's submerged horizontal area at the measured depth
(pitch ignored), the velocity from the measured forward, lateral and vertical components,
the vertical acceleration only, the deepest depth so far from the measured rise, and the
touchdown point under the sole (``intrusion`` = (0, 0, depth)); the foot's force is the
patch force times the number of patches. Each effect's column has a free scale, so only
its shape over the samples matters. A term that changes what the equation error reads — a
sensor effect on the foot force or on the kinematics, or a geometry term (the surface the
depth is measured from) — makes the test inapplicable, and it is skipped.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from ...effects import EffectInfo
from ...effects.state import PatchState
from ...effects.tracing import trace_terrain_force
from .features import AXES, ForceSamples, force_samples, sample_columns
from .problem import Problem
from .proposal import (LAW_FEATURES, MIN_EXPLAINED_FORCE, MIN_LAW_FORCE, MIN_SAMPLES,
                       PER_FOOT_FEATURES, explained_rms, law_fit)
from .acceptance_records import ForceLeftover
from .sparse import sparse_fit

#: the proposal's stages (§3.6): name → (least explained force per axis [N], the laws
#: fitted alone or None for the whole feature library, whether a law must be dissipative)
STAGES = {"library": (MIN_EXPLAINED_FORCE, None, False),
          "law": (MIN_LAW_FORCE, LAW_FEATURES, True),
          "per_foot": (MIN_LAW_FORCE, PER_FOOT_FEATURES, False)}
#: data columns whose change by a sensor effect changes what the equation error reads
#: (the foot force, and the kinematics the depth, pitch and velocity come from)
READ_BY_THE_EQUATION = ("grf_", "q_", "dq_", "base_", "intrusion_")


def inapplicable(added: Sequence[EffectInfo],
                 sensor_outputs: Mapping[str, frozenset[str]]) -> tuple[str, ...]:
    """The added effects that change what the equation error reads (geometry terms, and
    sensor effects changing a column of :data:`READ_BY_THE_EQUATION`)."""
    out = []
    for info in added:
        if info.kind == "geometry":
            out.append(info.name)
        elif info.kind == "sensor" and any(c.startswith(READ_BY_THE_EQUATION)
                                           for c in sensor_outputs.get(info.name, ())):
            out.append(info.name)
    return tuple(out)


def submerged_area(depth: np.ndarray, radius: float, chord: float, width: float) -> np.ndarray:
    """Horizontal area [m²] of a level sole arc of ``radius`` and ``chord``, ``width``
    wide, submerged to ``depth`` [m]: the arc's chord at that depth times the width."""
    d = np.clip(np.asarray(depth, float), 0.0, None)
    half = np.sqrt(np.clip(2.0 * radius * d - d * d, 0.0, None))
    return np.minimum(2.0 * half, chord) * width


def effect_force_columns(effects: Sequence[tuple[EffectInfo, Mapping[str, float]]],
                         cols: Mapping[str, np.ndarray], law_h: np.ndarray,
                         law_z: np.ndarray, *, n_slices: int, radius: float, chord: float,
                         width: float, density: float, dt: float
                         ) -> dict[str, dict[str, np.ndarray]]:
    """Each terrain-force effect's force on the foot at the sinking samples (the module
    docstring's patch state): effect → axis (``h`` forward, ``z`` vertical) → column [N].

    Args:
        effects: (effect, its parameter values).
        cols: :func:`.features.sample_columns` of the samples.
        law_h, law_z: the law's forward and vertical force on the foot at each sample [N].
        n_slices: patches per foot; radius, chord, width: the sole [m]; density [kg/m³];
            dt: the sample interval [s].
    """
    import casadi as ca

    from ...terrain.closed_form import casadi_ops

    n = int(np.asarray(cols["depth"]).size)
    hx, hy = np.asarray(cols["heading_x"], float), np.asarray(cols["heading_y"], float)
    v_h, v_l, v_z = (np.asarray(cols[k], float) for k in ("v_h", "v_l", "v_z"))
    depth = np.asarray(cols["depth"], float)
    share = 1.0 / n_slices
    rows = {
        "depth": depth, "v_x": v_h * hx - v_l * hy, "v_y": v_h * hy + v_l * hx, "v_z": v_z,
        "a_z": np.asarray(cols["a_z"], float), "hx": hx, "hy": hy,
        "f_x": law_h * hx * share, "f_y": law_h * hy * share, "f_z": law_z * share,
        "area": submerged_area(depth, radius, chord, width * share),
        "depth_max": depth + np.clip(np.asarray(cols["rise"], float), 0.0, None),
        "t_stance": np.asarray(cols["t_stance"], float),
        "foot": np.asarray(cols["foot"], float),
        "depth_rate": np.asarray(cols["depth_rate"], float),
    }
    names = list(rows)
    x = ca.SX.sym("x", len(names))
    sx = dict(zip(names, (x[i] for i in range(len(names)))))
    zero = 0.0
    state = PatchState(
        depth=sx["depth"], in_contact=1.0, p_c=(zero, zero, -sx["depth"]),
        v_c=(sx["v_x"], sx["v_y"], sx["v_z"]), a_c=(zero, zero, sx["a_z"]),
        intrusion=(zero, zero, sx["depth"]), heading=(sx["hx"], sx["hy"], zero),
        lateral=(-sx["hy"], sx["hx"], zero), f_terrain=(sx["f_x"], sx["f_y"], sx["f_z"]),
        f_yield_z=sx["f_z"], area_h=sx["area"], width=width * share, density=density, dt=dt,
        depth_max=sx["depth_max"], t_stance=sx["t_stance"], foot=sx["foot"],
        depth_rate=sx["depth_rate"])
    X = np.vstack([rows[k] for k in names])
    out = {}
    o = casadi_ops()
    for info, values in effects:
        p = {k: float(values[k]) for k in info.params}
        f = trace_terrain_force(info, o, state, p)
        fn = ca.Function("effect", [x], [ca.vertcat(*[ca.SX(fi) for fi in f])])
        F = np.asarray(fn.map(n)(X)) * n_slices if n else np.zeros((3, 0))
        out[info.name] = {"h": F[0] * hx + F[1] * hy, "z": F[2]}
    return out


def force_leftover(problem: Problem, theta: Mapping[str, float],
                   added: Sequence[tuple[EffectInfo, Mapping[str, float]]], *,
                   seed: int = 0) -> tuple[ForceLeftover, ...]:
    """The force axes on which the feature library still explains ≥
    :data:`~.proposal.MIN_EXPLAINED_FORCE` of the equation error with the added effects
    (the module docstring); () when fewer than :data:`~.proposal.MIN_SAMPLES` sinking
    samples. The caller leaves out the effects :func:`inapplicable` names.

    Args:
        problem: the diagnosis problem; theta: the calibrated parameters (ζ).
        added: the added effects with their fitted parameters.
        seed: seed of the sparse fits' stability resamples.
    """
    biped = problem.biped
    n_slices = int(biped.config.foot.slices)
    terrain = problem.replay_model.terrain
    fs = force_samples(problem.windows, terrain, theta, n_slices=n_slices)
    if fs.n < MIN_SAMPLES:
        return ()
    cols = sample_columns(problem.windows)
    foot = biped.config.foot
    forces = [(i, v) for i, v in added if i.kind == "terrain_force"]
    dt = 1.0 / float(problem.sample_rate_hz)
    cfg = terrain.config
    cols_f = effect_force_columns(
        forces, cols, cols["f_h"] - fs.target["h"], cols["f_z"] - fs.target["z"],
        n_slices=n_slices, radius=foot.radius, chord=foot.chord, width=foot.width,
        density=float(cfg.density), dt=dt)
    names = tuple(i.name for i, _ in added if i.kind in ("terrain_force", "joint", "sensor"))
    out = []
    for ax in AXES:
        base = fs.nuisance[ax][:, None]
        extra = [c[ax] for c in cols_f.values() if np.any(np.abs(c[ax]) > 1e-9)]
        with_effects = np.column_stack([base, *extra]) if extra else base
        stages = [(s, explained_by(fs, ax, s, base, seed), explained_by(fs, ax, s, with_effects,
                                                                         seed))
                  for s in STAGES]
        left = [(s, e0, e1) for s, e0, e1 in stages if e1 >= STAGES[s][0][ax]]
        if left:
            s, _, e1 = max(left, key=lambda t: t[2] / STAGES[t[0]][0][ax])
            e0 = max(t[1] for t in stages)
            out.append(ForceLeftover(ax, e0, e1, STAGES[s][0][ax], names, fs.n, s))
    return tuple(out)


def explained_by(fs: ForceSamples, axis: str, stage: str, nuisance: np.ndarray,
                 seed: int) -> float:
    """RMS [N] of the equation error of ``axis`` that one stage of the proposal
    (:data:`STAGES`) explains beyond the unpenalised ``nuisance`` columns, in sample."""
    _, laws, dissipative = STAGES[stage]
    if laws is None:
        fit = sparse_fit(fs.features, nuisance, fs.target[axis], fs.trial, fs.window,
                         seed=seed)
    else:
        fit = law_fit(fs, axis, seed=seed, laws=laws, dissipative=dissipative,
                      nuisance=nuisance)
    if fit is None or not fit.selected.any():
        return 0.0
    return explained_rms(fit.rmse_before, fit.rmse_after)


__all__ = ["ForceLeftover", "force_leftover", "explained_by", "STAGES", "effect_force_columns", "inapplicable",
           "submerged_area", "READ_BY_THE_EQUATION"]
