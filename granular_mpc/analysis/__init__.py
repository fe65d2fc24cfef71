"""Analysis of run logs and data sets: cost of transport, foot rolling, stance-phase metrics.

Definitions: ``docs/analysis.md``; the paper's decoupled (sagittal + frontal) CoT:
``docs/planar-models.md`` §6. Note: ``granular_mpc.analysis.cot_decoupled`` is the
*function* once this package is imported; import its module's other names with
``from granular_mpc.analysis.cot_decoupled import ...`` (works as before).
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
from .cot_decoupled import DecoupledEnergy, cot_decoupled, decoupled_energy, decoupled_power
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
    # decoupled CoT (sagittal + frontal planar models)
    "cot_decoupled", "decoupled_energy", "decoupled_power", "DecoupledEnergy",
    # rolling
    "rolling_from_arrays", "rolling_from_log", "PlateauResult", "detect_plateau",
    "plateau_by_stance",
    # metrics
    "segment_stances", "stance_phase", "role_column", "leg_joint_roles", "phase_grid",
    "resample_by_phase", "resample_stances", "phase_bands", "rmse_table",
]
