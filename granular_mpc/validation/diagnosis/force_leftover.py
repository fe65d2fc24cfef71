"""A missing foot force the additions do not produce (``docs/validation.md`` §3.7, "The
force the foot meets while it sinks").

The replays judge an addition by the channels it moves, and a term can pass them as a
proxy: a rebound of the sand while the sole rises (``elastic_unloading``) stiffens the
stance much as a harder layer below 20 mm does; its replays improve every credited channel
and the localised structure goes. The foot-force equation error (§3.6: measured foot force
− the calibrated closed-form law at the measured depth, pitch and direction of motion, ζ
free) is taken at the measured state, on the samples where the sole sinks: when a stage of
the proposal explains at least its threshold there (the thresholds of the proposal's
evidence rule, above what data without a missing foot force explain), the foot meets a
force the model lacks while it sinks. An addition that produces (almost) no force on
those samples — less than :data:`FOOTPRINT_SHARE` of the force the stage explains, both
axes together — cannot be that force, whatever the replays say; the verdict says so.

(What the equation error holds is not the missing force alone: a force missing on one axis
leaves structure on both, and the true term, given as a free column beside ζ, took away
little of it on the benchmark's hard-layer and sole-Coulomb data — so the test asks whether
the additions act at all where the force is missing, not whether they fit it.)

The added effects are evaluated on each sinking sample as the contact law evaluates them on
one of the foot's patches, from the foot-level measured state: the patch's share of the
law's force (``f_terrain``, also taken as the yield force ``f_yield_z``: the medium yields
while the sole sinks), the sole arc's submerged horizontal area at the measured depth
(pitch ignored), the velocity from the measured forward, lateral and vertical components,
the vertical acceleration only, the deepest depth so far from the measured rise, and the
touchdown point under the sole (``intrusion`` = (0, 0, depth)); the foot's force is the
patch force times the number of patches. Joint effects and torque sensors produce no foot
force. A term that changes what the equation error reads — a sensor effect on the foot
force or on the kinematics, or a geometry term (the surface the depth is measured from) —
makes the test inapplicable, and it is skipped.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ...effects import EffectInfo
from ...effects.state import PatchState
from ...effects.tracing import trace_terrain_force
from .acceptance_records import ForceLeftover
from .candidates import CandidateSet
from .features import AXES, ForceSamples, force_samples, sample_columns
from .problem import Problem
from .proposal import (LAW_FEATURES, MIN_EXPLAINED_FORCE, MIN_LAW_FORCE, MIN_SAMPLES,
                       PER_FOOT_FEATURES, explained_rms, law_fit, library_fit)

#: the proposal's stages (§3.6): name → (least explained force per axis [N], the laws
#: fitted alone or None for the whole feature library, whether a law must be dissipative)
STAGES = {"library": (MIN_EXPLAINED_FORCE, None, False),
          "law": (MIN_LAW_FORCE, LAW_FEATURES, True),
          "per_foot": (MIN_LAW_FORCE, PER_FOOT_FEATURES, False)}
#: the additions explain a missing force on the sinking samples only if they produce there
#: at least this share of it (RMS over the samples, both axes together). Chosen on seed 1 of
#: the out-of-library benchmark (session 28), on the cases where a stage explains at least
#: its threshold: the true terms (the user's, or a proposal fed back) produce 0.77–1.79
#: times the force the stage explains (quadratic drag 0.77 and 0.91, the rest ≥ 1.13), the
#: proxies 0–0.19 (elastic unloading on the hard layer 0.08, cohesion on vertical damping
#: 0.04–0.19, joint friction 0); ½ lies between. Held out, seeds 2–3: true terms
#: 0.69–3.07, proxies 0–0.11 (docs/validation.md §3.7)
FOOTPRINT_SHARE = 0.5
#: ... and the stage must explain this multiple of its threshold: the thresholds are the
#: proposal's, whose evidence rule also asks for a held-out reduction, and in sample alone
#: data without a missing foot force reach them (a null at 5.05 N against z's 5 N, §3.6;
#: the recovery study's strong elastic unloading, a force that acts only while the sole
#: rises, at 5.6 N). The proxies caught explain 1.5–3.0 times theirs (docs/validation.md
#: §3.7: chosen after that held-out false flag, then checked on fresh seeds)
EVIDENCE_MARGIN = 1.5
#: data columns whose change by a sensor effect changes what the equation error reads
#: (the foot force, and the kinematics the depth, pitch and velocity come from)
READ_BY_THE_EQUATION = ("grf_", "q_", "dq_", "base_", "intrusion_")


def inapplicable(added: Sequence[str], candidates: CandidateSet) -> tuple[str, ...]:
    """The added effects that change what the equation error reads (geometry terms, and
    sensor effects changing a column of :data:`READ_BY_THE_EQUATION`)."""
    sensors = candidates.sensors_changing(READ_BY_THE_EQUATION)
    return tuple(n for n in added
                 if candidates.kind(n) == "geometry" or n in sensors)


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
    """The force axes whose equation error holds a missing force (a stage of the proposal
    explains :data:`EVIDENCE_MARGIN` times its threshold) that the added effects do not
    produce: their combined force on the sinking samples is less than
    :data:`FOOTPRINT_SHARE` of it (the module docstring); () when fewer than :data:`~.proposal.MIN_SAMPLES` sinking samples.
    The caller leaves out the effects :func:`inapplicable` names.

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
    cols_f = effect_force_columns(
        forces, cols, cols["f_h"] - fs.target["h"], cols["f_z"] - fs.target["z"],
        n_slices=n_slices, radius=foot.radius, chord=foot.chord, width=foot.width,
        density=float(terrain.config.density), dt=1.0 / float(problem.sample_rate_hz))
    total = {ax: sum((c[ax] for c in cols_f.values()), np.zeros(fs.n)) for ax in AXES}
    footprint = float(np.sqrt(np.mean(total["h"] ** 2 + total["z"] ** 2)))
    names = tuple(i.name for i, _ in added if i.kind in ("terrain_force", "joint", "sensor"))
    explained = {ax: {s: explained_by(fs, ax, s, seed) for s in STAGES} for ax in AXES}
    return unproduced(explained, footprint, names, fs.n)


def unproduced(explained: Mapping[str, Mapping[str, float]], footprint: float,
               effects: tuple[str, ...], n_samples: int) -> tuple[ForceLeftover, ...]:
    """The decision of :func:`force_leftover`: per axis, the stage that explains most
    relative to its threshold, if any explains :data:`EVIDENCE_MARGIN` times it, and the
    additions' ``footprint`` [N RMS] below :data:`FOOTPRINT_SHARE` of what it explains.

    Args:
        explained: axis → stage → force it explains beyond ζ [N RMS].
        footprint: the additions' force on the same samples [N RMS].
        effects, n_samples: recorded in each :class:`ForceLeftover`.
    """
    out = []
    for ax, by_stage in explained.items():
        found = [(s, e) for s, e in by_stage.items()
                 if e >= EVIDENCE_MARGIN * STAGES[s][0][ax]]
        if not found:
            continue
        s, e = max(found, key=lambda t: t[1] / STAGES[t[0]][0][ax])
        if footprint < FOOTPRINT_SHARE * e:
            out.append(ForceLeftover(ax, e, footprint, STAGES[s][0][ax], effects, n_samples, s))
    return tuple(out)


def explained_by(fs: ForceSamples, axis: str, stage: str, seed: int) -> float:
    """RMS [N] of the equation error of ``axis`` that one stage of the proposal
    (:data:`STAGES`) explains beyond ζ's column, in sample."""
    _, laws, dissipative = STAGES[stage]
    if laws is None:
        fit = library_fit(fs, axis, seed=seed)
    else:
        fit = law_fit(fs, axis, seed=seed, laws=laws, dissipative=dissipative)
    if fit is None or not fit.selected.any():
        return 0.0
    return explained_rms(fit.rmse_before, fit.rmse_after)


__all__ = ["ForceLeftover", "force_leftover", "unproduced", "explained_by", "STAGES",
           "FOOTPRINT_SHARE", "EVIDENCE_MARGIN", "effect_force_columns", "inapplicable",
           "submerged_area", "READ_BY_THE_EQUATION"]
