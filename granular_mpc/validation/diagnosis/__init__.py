"""Calibrate, then diagnose: which physical effect is the model missing, and where?

A staged pipeline (``docs/validation.md`` §3); each stage is a function in its own module
returning a frozen result:

1. :mod:`.calibration` — the model's own terrain parameters (ζ, φ_s) on equation-error
   residuals (:mod:`granular_mpc.validation.calibrate`); they stay in every regression as
   nuisance columns, so a parameter that is merely off is never reported as an effect.
2. :mod:`.candidates` / :mod:`.residuals` — every candidate effect's magnitude columns;
   replays of the calibrated model and of each column at its nominal step give the
   binned residual and the sensitivity columns (:mod:`.cubes`, :mod:`.design`).
3. :mod:`.screen` — bounded least squares (:mod:`.regression`): held-out error reduction
   under trial-grouped CV, ΔAICc, bootstrap inclusion, effect size; indistinguishable pairs.
4. :mod:`.refine` — contenders refined by Gauss–Newton replays (:mod:`.gauss_newton`),
   the best that passes honest acceptance (:mod:`.acceptance`: its replays improve its
   credited channels, its coefficients are physical) added, the others re-tested
   conditionally; a user's or proposed terrain force is also refined from its fit with ζ
   on the foot-force equation error (:mod:`.force_start`, :mod:`.sample_forces`).
5. :mod:`.localise` — where, when and with what the residual is structured, before and
   after.
6. :mod:`.verdict` — ordered verdict rules (``partially_explained`` when the structure
   that flagged the effect remains after the additions).
7. :mod:`.report` — ``diagnosis.json`` (:class:`~.result.Diagnosis`), ``report.md``,
   figures.

:func:`~.pipeline.diagnose` calls them in order. ``diagnosis.json`` is read back with
:func:`~.result.load_diagnosis`.
"""

# the records first: granular_mpc.validation.replay reads diagnosis files through them
from .result import Diagnosis, FittedParameters, Verdict, load_diagnosis  # noqa: I001
from .acceptance import coefficient_checks, judge, remaining_cells
from .acceptance_records import Acceptance, CoefficientCheck
from .candidates import (CandidateSet, Column, build_candidates, candidate_columns,
                         dead_candidates, diverged_candidates)
from .design import Design, GeometryRows, build_design
from .localise import localize, where_summary
from .localization_records import Localization
from .ranking_records import CandidateStats, ParamEstimate, Ranked
from .regression import Regression, aicc, fit_bounded, forward_selection
from .residuals import guard_jumps
from .report import coefficient_text
from .screen import candidate_stats, inclusion_ties, practically_large, share_inclusion
from .thresholds import (LARGE_HELDOUT_REDUCTION, MAX_DELTA_AICC, MIN_EFFECT_SIZE,
                         MIN_HELDOUT_REDUCTION, MIN_INCLUSION, MIN_STANCE_REDUCTION, T_CELL)
from .verdict import VerdictInputs, decide, error_change
from .pipeline import diagnose

__all__ = ["diagnose", "Diagnosis", "Verdict", "FittedParameters", "load_diagnosis", "localize",
           "where_summary", "Localization", "candidate_columns", "Column", "CandidateSet",
           "build_candidates", "Design", "GeometryRows", "build_design", "Regression", "aicc",
           "fit_bounded", "forward_selection", "guard_jumps", "candidate_stats",
           "practically_large", "CandidateStats", "ParamEstimate", "Ranked",
           "MIN_HELDOUT_REDUCTION", "MAX_DELTA_AICC", "MIN_INCLUSION", "MIN_STANCE_REDUCTION",
           "T_CELL", "MIN_EFFECT_SIZE", "LARGE_HELDOUT_REDUCTION", "Acceptance",
           "CoefficientCheck", "coefficient_checks", "judge", "remaining_cells",
           "dead_candidates", "diverged_candidates", "coefficient_text", "inclusion_ties", "share_inclusion",
           "VerdictInputs", "decide", "error_change"]
