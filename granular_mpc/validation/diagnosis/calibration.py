"""Stage 1, calibrate: the model's own terrain parameters on equation-error residuals
(:func:`~granular_mpc.validation.calibrate.calibrate`), and the calibration's nuisance
columns that stay in every regression (``docs/validation.md`` §3.1)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

from ..calibrate import CAL_PARAMS, Calibration, calibrate
from ..replay.model import ReplayModel, build_replay_model
from .candidates import CALIBRATION, CandidateSet, Column
from .problem import Problem

#: finite-difference steps and bounds of the nuisance columns
ZETA_REL_STEP = 0.08
PHI_S_STEP_RAD = math.radians(3.0)
TOUCHDOWN_DEPTH_STEP_M = 5e-4
TOUCHDOWN_DEPTH_BOUNDS_M = (-1e-3, 2e-3)
#: the candidate name of the terrain-file columns tested against (keys ``strength.<param>``)
STRENGTH = "strength"
#: the contact regime's terrain-file parameters tested against (:func:`strength_columns`):
#: relative finite-difference step, upper bound as a multiple of the file's value, unit
CONTACT_PARAMS = {"contact_damping": (0.5, 10.0, "N·s/m"), "added_mass_scale": (0.5, 5.0, "-")}
#: the value the step and bound scale with when the file's value is zero
CONTACT_FLOOR = {"contact_damping": 100.0, "added_mass_scale": 1.0}


def nuisance_columns(theta: Mapping[str, float]) -> tuple[Column, ...]:
    """The calibration's columns at θ: ζ and φ_s [rad] (those in ``theta``) and the
    touchdown depth [m], each neutral at its current value."""
    cols = []
    if "zeta" in theta:
        lo, hi = CAL_PARAMS["zeta"]
        cols.append(Column(CALIBRATION, "zeta", theta["zeta"], ZETA_REL_STEP * theta["zeta"],
                           lo, hi))
    if "phi_s" in theta:
        plo, phi = CAL_PARAMS["phi_s"]
        cols.append(Column(CALIBRATION, "phi_s", theta["phi_s"], PHI_S_STEP_RAD, plo, phi, "rad"))
    cols.append(Column(CALIBRATION, "touchdown_depth", theta.get("touchdown_depth", 0.0),
                       TOUCHDOWN_DEPTH_STEP_M, *TOUCHDOWN_DEPTH_BOUNDS_M, "m"))
    return tuple(cols)


def strength_columns(theta: Mapping[str, float], phi_s_rad: float,
                     contact: Mapping[str, float] | None = None) -> tuple[Column, ...]:
    """The terrain-file parameters a candidate is tested against, not fitted
    (:mod:`.strength`): φ_s [rad] at the terrain file's value ``phi_s_rad`` when the
    calibration keeps it fixed (when φ_s is calibrated it is a nuisance column instead),
    and the contact regime ``contact`` (:data:`CONTACT_PARAMS` → the file's values:
    ``contact_damping`` [N·s/m], ``added_mass_scale`` [-]).

    The contact regime's columns answer the nulls of ``docs/validation.md`` §5.3.18: a
    plant whose elastic-regime damping is 3× the file's pulls on the rising sole the way
    ``cohesion`` does, and one whose added mass is 2× pushes as ``inertial_drag`` does."""
    cols = []
    if "phi_s" not in theta:
        plo, phi = CAL_PARAMS["phi_s"]
        cols.append(Column(STRENGTH, "phi_s", phi_s_rad, PHI_S_STEP_RAD, plo, phi, "rad"))
    for param, value in (contact or {}).items():
        rel_step, upper, unit = CONTACT_PARAMS[param]
        scale = max(value, CONTACT_FLOOR[param])
        cols.append(Column(STRENGTH, param, value, rel_step * scale, 0.0, upper * scale, unit))
    return tuple(cols)


@dataclass(frozen=True, eq=False)
class CalibrationStage:
    """What calibration hands on.

    Attributes:
        calibration: equation-error fit of ``calibrate_params``.
        free_phi_s: the same with ζ and φ_s free (reported only).
        theta: the calibrated θ plus ``touchdown_depth = 0`` [m].
        nuisance: the calibration's columns at ``theta``.
        replay_model: the model with every terrain-force candidate compiled in (neutral).
        strength: the terrain-file columns tested against, not fitted: φ_s when it is
            not calibrated, and the contact regime (:func:`strength_columns`).
    """

    calibration: Calibration
    free_phi_s: Calibration
    theta: Mapping[str, float]
    nuisance: tuple[Column, ...]
    replay_model: ReplayModel
    strength: tuple[Column, ...] = ()

    @property
    def nuisance_keys(self) -> list[str]:
        return [c.key for c in self.nuisance]


def calibrate_model(problem: Problem, candidates: CandidateSet, *,
                    params: Sequence[str] = ("zeta",), seed: int = 0) -> CalibrationStage:
    """Calibrate ``params`` (and, for the report, ζ with φ_s free) and build the replay
    model with the terrain-force candidates."""
    terrain = problem.replay_model.terrain
    n_slices = problem.biped.config.foot.slices
    cal = calibrate(problem.windows, terrain, n_slices=n_slices, seed=seed, params=tuple(params))
    cal_free = (calibrate(problem.windows, terrain, n_slices=n_slices, seed=seed,
                          params=("zeta", "phi_s"))
                if "phi_s" not in params else cal)
    rm = build_replay_model(problem.biped, problem.terrain_cfg,
                            sample_rate_hz=problem.sample_rate_hz, sim=problem.sim,
                            terrain_effects=candidates.terrain_force_names)
    theta = dict(cal.values)
    theta["touchdown_depth"] = 0.0
    cfg = problem.terrain_cfg
    contact = {p: float(getattr(cfg, p)) for p in CONTACT_PARAMS if hasattr(cfg, p)}
    return CalibrationStage(cal, cal_free, theta, nuisance_columns(theta), rm,
                            strength_columns(theta, math.radians(cfg.phi_s_deg), contact))


__all__ = ["CalibrationStage", "calibrate_model", "nuisance_columns", "strength_columns",
           "STRENGTH", "CONTACT_PARAMS", "CONTACT_FLOOR"]
