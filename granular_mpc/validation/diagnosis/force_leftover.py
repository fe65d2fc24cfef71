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

The added effects are evaluated on each sinking sample as the contact law evaluates them
on one of the foot's patches (:mod:`.sample_forces`). Joint effects and torque sensors
produce no foot force. A term that changes what the equation error reads — a sensor effect on the foot
force or on the kinematics, or a geometry term (the surface the depth is measured from) —
makes the test inapplicable, and it is skipped.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ...effects import EffectInfo
from .acceptance_records import ForceLeftover
from .candidates import CandidateSet
from .features import AXES, ForceSamples
from .problem import Problem
from .proposal import (LAW_FEATURES, MIN_EXPLAINED_FORCE, MIN_LAW_FORCE, MIN_SAMPLES,
                       PER_FOOT_FEATURES, explained_rms, law_fit, library_fit)
from .sample_forces import equation_states, force_function

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
    fs, states = equation_states(problem, theta)
    if fs.n < MIN_SAMPLES:
        return ()
    cols_f = {i.name: force_function(states, i, v)(None)
              for i, v in added if i.kind == "terrain_force"}
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
           "FOOTPRINT_SHARE", "EVIDENCE_MARGIN", "inapplicable", "READ_BY_THE_EQUATION"]
