"""What a data set can show: measured and missing channels, and the candidate effects that
cannot be assessed without the missing ones (``docs/import.md``, ``docs/validation.md``).

A data set declares the channel groups it measured (``meta.yaml`` ``channels``;
:class:`~granular_mpc.validation.dataformat.channels.ChannelSet`). ``validate`` and
``diagnose`` score only the channels of measured groups (joint angles; ``grf_*`` with
``foot_force``; ``intrusion_*`` with ``intrusion``) and never stand in for an absent one.

**Which candidates can be assessed** (:func:`assess_candidates`), decided from the
candidate columns' own sensitivities on the channels that are there, not from a list:

* a sensor effect that *reads* a column of a missing group (``force_sensor_bias`` reads
  ``grf_*``) cannot be evaluated at all (:func:`drop_unreadable_sensor_candidates`);
* otherwise a candidate's **detectable size** is the largest change its column makes, at
  the library's nominal magnitude (the column's finite-difference step: the effect's
  default, "a magnitude the robot notices"), in the stance-averaged prediction of any
  measured channel × phase cell, in units of that channel's stance-to-stance scatter σ_c
  — the quantity of the diagnosis's practical-size test
  (:meth:`~.regression.Regression.practical_size`); the touchdown heights (geometry
  candidates) count only when the trunk position was measured (leg odometry carries the
  stance foot's height forward: its touchdown heights are not measurements);
* when channel groups are missing, a candidate whose detectable size is below
  :data:`MIN_ASSESSABLE_SIZE` = :data:`~.thresholds.MIN_EFFECT_SIZE` (1 σ) is **not
  assessable**: at the magnitude the library calls noticeable it moves nothing that was
  measured by as much as the diagnosis requires of an effect it adds; it is taken out of
  the ranking and reported with the missing groups. The threshold is the practical-size
  threshold itself, so that "cannot be assessed" means "could not pass the size test at
  its nominal magnitude"; ``bench/channels.py`` keeps the sizes per case (on joint data
  + IMU, quick run: cohesion 5–18 σ, elastic unloading 1.5–14 σ, joint friction 4–6 σ,
  inertial drag 0.9–5.5 σ, depth hardening 0.4–1.7 σ — it falls on either side from one
  data set to the next —, terrain slope 0.3–0.5 σ);
* size alone is not enough: a candidate whose signature another candidate reproduces
  cannot be told from it. Its **identifiable part** (:mod:`.identifiability`) is what of
  its signature on the regression's own rows (per trial and side, channel and phase bin,
  in σ_c) the least-squares fit of the calibration's free parameters, and of them plus any
  one other assessable candidate, leaves; with missing groups a candidate whose
  identifiable part is below the same threshold is **not assessable** either — "the
  calibration explains it", or "indistinguishable with the measured channels from B" —,
  and an addition of B is reported as *ambiguous* (the verdict names both).

With every group measured nothing is taken out (an effect that is small everywhere is a
matter for the ranking, not of missing sensors; collinear fitted contributions are the
screening's indistinguishable pairs); the sizes and identifiable parts are reported.

Without foot force or intrusion the equation-error calibration of ζ (measured vertical
force against the terrain law at the measured depth) cannot run: the terrain file's values
are kept (:func:`fixed_calibration`) and ζ stays a free nuisance column of the regression.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ...exceptions import ConfigError
from ...output import json_safe
from ..calibrate import Calibration
from ..dataformat import Dataset
from ..dataformat.channels import ChannelGroup, group_of_column
from ..channel_coverage import (MIN_ASSESSABLE_SIZE, Coverage, EffectCoverage,
                                channel_coverage, trunk_state_source)
from ..prepare import StanceWindow, channel_names
from ..replay.measurement import check_sensor_specs
from ..replay.model import build_replay_model
from .calibration import CalibrationStage, nuisance_columns
from .candidates import CandidateSet, Column
from .cubes import group_keys
from .identifiability import Signature, identifiability
from .problem import Problem
from .thresholds import MIN_EFFECT_SIZE

if MIN_ASSESSABLE_SIZE != MIN_EFFECT_SIZE:          # one threshold, two places
    raise ImportError("channel_coverage.MIN_ASSESSABLE_SIZE must equal MIN_EFFECT_SIZE")
#: upper bound of the ``touchdown_depth`` nuisance [m] when the free surface comes from
#: the leg kinematics (no intrusion; :func:`~granular_mpc.validation.estimation.landing`):
#: the landing foot's stop height lies below the surface by what it sank before the sand
#: stopped it, ≈ ½ × 0.5 m/s × 8 ms = 2 mm on top of the 2 mm the default bound allows
KINEMATIC_SURFACE_MAX_DEPTH_M = 4e-3
#: file written next to ``diagnosis.json``
COVERAGE_FILE = "coverage.json"
#: the pseudo channel of the geometry rows
TOUCHDOWN_CHANNEL = "touchdown_z"


def measured_problem(problem: Problem, ds: Dataset) -> Problem:
    """``problem`` scored on the measured channels only."""
    return replace(problem, channels=tuple(channel_names(list(ds.joint_names), ds.channels)))


def can_calibrate(ds: Dataset) -> bool:
    """Whether the equation-error calibration can run (needs foot force and intrusion)."""
    return ds.has(ChannelGroup.FOOT_FORCE, ChannelGroup.INTRUSION)


def fixed_calibration(problem: Problem, candidates: CandidateSet,
                      params: Sequence[str] = ("zeta",), *,
                      intrusion: bool = False) -> CalibrationStage:
    """The calibration stage without the equation-error fit: the terrain file's values of
    ``params`` kept (they stay free nuisance columns of the regression). Without measured
    ``intrusion`` the touchdown depth may reach :data:`KINEMATIC_SURFACE_MAX_DEPTH_M`."""
    names4 = ("zeta", "phi_s", "bulldozing_length", "sole_shear_alpha")
    theta0 = problem.replay_model.terrain.casadi_theta
    initial = {p: float(theta0[names4.index(p)]) for p in params}
    note = ("not calibrated by equation error (needs foot force and intrusion, not both "
            "measured): the terrain file's values are kept; they stay free in the regression")
    cal = Calibration(dict(initial), dict(initial), identified={p: False for p in params},
                      note=note)
    rm = build_replay_model(problem.biped, problem.terrain_cfg,
                            sample_rate_hz=problem.sample_rate_hz, sim=problem.sim,
                            terrain_effects=candidates.terrain_force_names)
    theta = dict(initial)
    theta["touchdown_depth"] = 0.0
    cols = tuple(replace(c, upper=max(c.upper, KINEMATIC_SURFACE_MAX_DEPTH_M))
                 if c.param == "touchdown_depth" and not intrusion else c
                 for c in nuisance_columns(theta))
    return CalibrationStage(cal, cal, theta, cols, rm)


def drop_unreadable_sensor_candidates(candidates: CandidateSet, window: StanceWindow,
                                      joint_names: Sequence[str], ds: Dataset
                                      ) -> tuple[CandidateSet, tuple[EffectCoverage, ...]]:
    """Sensor candidates that read a column of a group the data set did not measure,
    taken out of ``candidates`` (other errors are left for
    :func:`~.candidates.check_sensor_candidates` to raise)."""
    if not ds.channels.missing:
        return candidates, ()
    out = []
    for n, info in candidates.infos.items():
        if info.kind != "sensor":
            continue
        try:
            check_sensor_specs([(info, info.resolve_params({}))], window, joint_names)
        except ConfigError as exc:
            col = str(getattr(exc, "value", "") or "")
            g = group_of_column(col)
            if g is None or ds.has(g):
                continue
            out.append(EffectCoverage(n, info.kind, False, float("nan"), "",
                                      f"it reads {col} ({g.value}), which was not measured"))
    return candidates.without([e.name for e in out]), tuple(out)


def detectable_size(S: np.ndarray, step: float, channels: Sequence[str],
                    sigma: Mapping[str, float]) -> tuple[float, str]:
    """Largest |stance-mean change| of a (W, C, B) sensitivity cube at ``step`` over the
    channel × phase cells, in units of each channel's σ; and that channel."""
    with np.errstate(invalid="ignore"):
        mean = np.nanmean(np.asarray(S, dtype=float) * step, axis=0)       # (C, B)
    best, where = 0.0, ""
    for c, ch in enumerate(channels):
        row = np.abs(mean[c])
        if not np.isfinite(row).any():
            continue
        v = float(np.nanmax(row)) / float(sigma.get(ch, 1.0))
        if v > best:
            best, where = v, ch
    return best, where


def group_signature(S: np.ndarray, step: float, channels: Sequence[str],
                    sigma: Mapping[str, float], groups: np.ndarray) -> np.ndarray:
    """The regression's systematic rows of a (W, C, B) sensitivity cube at ``step``: per
    trial-and-side group (``groups``, one key per window), channel and phase bin, the mean
    over the group's stances in units of the channel's σ, flattened (G·C·B; NaN: empty)."""
    S = np.asarray(S, dtype=float) * step
    sd = np.array([float(sigma.get(ch, 1.0)) for ch in channels])[:, None]
    with np.errstate(invalid="ignore"):
        out = [np.nanmean(S[groups == g], axis=0) / sd for g in np.unique(groups)]
    return np.array(out).ravel()


def column_signatures(cols, res, channels: Sequence[str], groups: np.ndarray,
                      touchdown: bool) -> Signature:
    """The :class:`~.identifiability.Signature` of ``cols`` (candidate or nuisance
    columns) on the regression's systematic rows (:func:`group_signature`, weights
    √n_group as in :mod:`.design`); touchdown rows only with a measured trunk position."""
    cells = [group_signature(res.sens[c.key], c.step, channels, res.sigma, groups)
             for c in cols]
    keys, counts = np.unique(groups, return_counts=True)
    per_group = len(channels) * (cells[0].size // max(len(channels) * len(keys), 1)) \
        if cells else 0
    weights = np.repeat(np.sqrt(counts.astype(float)), per_group)
    n_rows = 0
    if touchdown:
        n_rows = max((np.asarray(g).size for g in res.geometry.sens.values()), default=0)
    rows = []
    for c in cols:
        g = res.geometry.sens.get(c.key) if touchdown else None
        rows.append(np.zeros(n_rows) if g is None
                    else np.asarray(g, float).ravel() * c.step / res.geometry.sigma)
    return Signature(np.array(cells).T.reshape(weights.size, len(cols)),
                     np.array(rows).T.reshape(n_rows, len(cols)), weights)


def assess_candidates(problem: Problem, ds: Dataset, candidates: CandidateSet, res,
                      unreadable: Sequence[EffectCoverage] = (),
                      calibration: str = "", nuisance: Sequence[Column] = ()
                      ) -> tuple[CandidateSet, Coverage]:
    """Every candidate's detectable size and identifiable part on the measured channels;
    with missing groups, those below :data:`MIN_ASSESSABLE_SIZE` or indistinguishable from
    another candidate are taken out (module docstring, :mod:`.identifiability`).

    Args:
        problem: the problem (its channels: the measured ones).
        ds: the data set.
        candidates: the candidates that were replayed.
        res: the :class:`~.residuals.Residuals` (sensitivities, σ, geometry rows).
        unreadable: from :func:`drop_unreadable_sensor_candidates`.
        calibration: how ζ was set, in words.
        nuisance: the calibration's columns, fitted on every data set (their sensitivities
            in ``res.sens``).

    Returns:
        The assessable candidates and the :class:`Coverage`.
    """
    missing = bool(ds.channels.missing)
    touchdown = ds.has(ChannelGroup.TRUNK_POSITION)
    sizes: dict[str, tuple[float, str]] = {}
    for n, cols in candidates.columns.items():
        size, where = 0.0, ""
        for col in cols:
            S = res.sens.get(col.key)
            if S is not None:
                v, ch = detectable_size(S, col.step, problem.channels, res.sigma)
                if v > size:
                    size, where = v, ch
            g = res.geometry.sens.get(col.key)
            if touchdown and g is not None:
                v = float(np.sqrt(np.mean((np.asarray(g) * col.step) ** 2))) / res.geometry.sigma
                if v > size:
                    size, where = v, TOUCHDOWN_CHANNEL
        sizes[n] = (size, where)
    big = [n for n, (v, _) in sizes.items() if v >= MIN_ASSESSABLE_SIZE]
    groups = np.asarray(group_keys(problem.windows))
    sigs = {n: column_signatures(cols, res, problem.channels, groups, touchdown)
            for n, cols in candidates.columns.items()
            if cols and all(c.key in res.sens for c in cols)}
    nuis = [c for c in nuisance if c.key in res.sens]
    ident = identifiability(sigs, column_signatures(nuis, res, problem.channels, groups,
                                                    touchdown)
                            if nuis else None, among=big, threshold=MIN_ASSESSABLE_SIZE)
    effects = list(unreadable)
    drop = []
    for n in candidates.columns:
        info = candidates.infos[n]
        size, where = sizes[n]
        idf = ident.get(n)
        part = (min([idf.size, *idf.given.values()]) if idf is not None else float("nan"))
        twins = idf.absorbed_by if idf is not None and size >= MIN_ASSESSABLE_SIZE else ()
        reason = ""
        if size < MIN_ASSESSABLE_SIZE:
            reason = (f"at its nominal magnitude it moves the measured channels by at most "
                      f"{size:.2f} σ ({where or 'none'}) < {MIN_ASSESSABLE_SIZE:g} σ")
        elif twins:
            reason = (f"indistinguishable with the measured channels from {', '.join(twins)}: "
                      f"{'; '.join(f'{b} explains all but {idf.given[b]:.2f} σ' for b in twins)}"
                      f" of its signature (< {MIN_ASSESSABLE_SIZE:g} σ)")
        elif idf is not None and idf.size < MIN_ASSESSABLE_SIZE:
            reason = (f"the calibration's free parameters explain all but {idf.size:.2f} σ of "
                      f"its signature (< {MIN_ASSESSABLE_SIZE:g} σ)")
        ok = not (missing and reason)
        effects.append(EffectCoverage(n, info.kind, ok, size, where, "" if ok else reason,
                                      part, twins if missing else ()))
        if not ok:
            drop.append(n)
    cov = replace(channel_coverage(ds), calibration=calibration, effects=tuple(effects))
    return candidates.without(drop), cov


def calibration_text(ds: Dataset) -> str:
    """How ζ is set for ``ds``, in words."""
    return ("equation error on the measured force and intrusion" if can_calibrate(ds) else
            "kept at the terrain file's value (no foot force and intrusion to calibrate on); "
            "free in the regression")


def write_coverage(out: Path | None, cov: Coverage) -> Path | None:
    """``coverage.json`` in ``out`` (nothing when ``out`` is None)."""
    if out is None:
        return None
    p = Path(out) / COVERAGE_FILE
    p.write_text(json.dumps(json_safe(cov.to_dict()), indent=1), encoding="utf-8")
    return p


def coverage_section(out: Path | str | None) -> list[str]:
    """The report's channel section from ``coverage.json`` in ``out`` (empty if none)."""
    if out is None or not (Path(out) / COVERAGE_FILE).is_file():
        return []
    d = json.loads((Path(out) / COVERAGE_FILE).read_text(encoding="utf-8"))
    return Coverage.from_dict(d).markdown()


__all__ = ["Coverage", "EffectCoverage", "MIN_ASSESSABLE_SIZE", "COVERAGE_FILE",
           "channel_coverage", "measured_problem", "can_calibrate", "fixed_calibration",
           "KINEMATIC_SURFACE_MAX_DEPTH_M",
           "drop_unreadable_sensor_candidates", "detectable_size", "assess_candidates",
           "group_signature", "column_signatures",
           "calibration_text", "write_coverage", "coverage_section", "trunk_state_source"]
