"""Compatibility module: ``from granular_mpc.validation.diagnose import diagnose`` (and the
other names below) keeps working; the pipeline lives in :mod:`granular_mpc.validation.diagnosis`
(one stage per module, typed stage results, ``docs/validation.md`` §3)."""

from .diagnosis import (LARGE_HELDOUT_REDUCTION, MAX_DELTA_AICC, MIN_EFFECT_SIZE,
                        MIN_HELDOUT_REDUCTION, MIN_INCLUSION, MIN_STANCE_REDUCTION, T_CELL,
                        CandidateStats, Column, Design, Diagnosis, Ranked, Regression, aicc,
                        candidate_columns, candidate_stats, diagnose, guard_jumps,
                        load_diagnosis, localize)

__all__ = ["diagnose", "Diagnosis", "load_diagnosis", "localize", "candidate_columns", "Column",
           "Design", "Regression", "aicc", "candidate_stats", "guard_jumps", "CandidateStats",
           "Ranked", "MIN_HELDOUT_REDUCTION", "MAX_DELTA_AICC", "MIN_INCLUSION",
           "MIN_STANCE_REDUCTION", "T_CELL", "MIN_EFFECT_SIZE", "LARGE_HELDOUT_REDUCTION"]
