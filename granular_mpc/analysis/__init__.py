"""Analysis of run logs and data sets: cost of transport, foot rolling, stance-phase metrics.

Definitions: ``docs/analysis.md``.
"""
from .cot import (
    POWER_MODES,
    CotResult,
    cot_from_arrays,
    cot_from_log,
    cumulative_cot,
    estimate_weight_from_grf,
    log_power,
    mechanical_power,
    stance_cumulative_cot,
)
from .metrics import (
    leg_joint_roles,
    phase_bands,
    phase_grid,
    resample_by_phase,
    resample_stances,
    rmse_table,
    role_column,
    segment_stances,
    stance_phase,
)
from .rolling import PlateauResult, detect_plateau, plateau_by_stance, rolling_from_arrays, rolling_from_log

__all__ = [
    # cot
    "POWER_MODES", "CotResult", "mechanical_power", "cot_from_arrays", "cot_from_log",
    "cumulative_cot", "stance_cumulative_cot", "log_power", "estimate_weight_from_grf",
    # rolling
    "rolling_from_arrays", "rolling_from_log", "PlateauResult", "detect_plateau",
    "plateau_by_stance",
    # metrics
    "segment_stances", "stance_phase", "role_column", "leg_joint_roles", "phase_grid",
    "resample_by_phase", "resample_stances", "phase_bands", "rmse_table",
]
