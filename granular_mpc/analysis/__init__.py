"""Analysis of run logs and data sets: cost of transport, foot rolling, stance-phase metrics.

Stances run from touchdown to lift-off (``analysis.stances``: contact state, else force,
else the plan); the CoT comes under three readings of the paper's E (``analysis.cot``,
default ``abs_per_joint``), all at once from a log with ``cot_readings_report``.

Definitions: ``docs/analysis.md``; the paper's decoupled (sagittal + frontal) CoT:
``docs/planar-models.md`` §6. Note: ``granular_mpc.analysis.cot_decoupled`` is the
*function* once this package is imported; import its module's other names with
``from granular_mpc.analysis.cot_decoupled import ...`` (works as before).
"""
from .cot import (
    COT_READINGS,
    DEFAULT_COT_READING,
    POWER_MODES,
    READING_POWER_MODES,
    CotReadings,
    CotResult,
    combine_joint_powers,
    cot_readings_from_arrays,
    cot_readings_from_log,
    reading_mode,
    resolve_weight,
    cot_from_arrays,
    cot_from_log,
    cumulative_cot,
    estimate_weight_from_grf,
    log_power,
    mechanical_power,
    stance_cumulative_cot,
)
from .cot_decoupled import (
    DecoupledCotReadings,
    DecoupledEnergy,
    cot_decoupled,
    cot_decoupled_readings,
    decoupled_energy,
    decoupled_joint_power,
    decoupled_power,
)
from .cot_readings import RunCot, cot_readings_report
from .metrics import (
    StancePeaks,
    contact_segments,
    leg_joint_roles,
    phase_bands,
    phase_grid,
    resample_by_phase,
    resample_stances,
    rmse_table,
    role_column,
    segment_stances,
    stance_column,
    stance_peaks,
    stance_phase,
)
from .rolling import (
    PlateauResult,
    detect_plateau,
    plateau_by_stance,
    rolling_from_arrays,
    rolling_from_log,
)
from .stances import (
    STANCE_SOURCES,
    Stance,
    debounce,
    find_stances,
    planned_column,
    resolve_source,
    stance_table,
    true_runs,
)

__all__ = [
    # cot
    "POWER_MODES", "CotResult", "mechanical_power", "cot_from_arrays", "cot_from_log",
    "cumulative_cot", "stance_cumulative_cot", "log_power", "estimate_weight_from_grf",
    "COT_READINGS", "DEFAULT_COT_READING", "READING_POWER_MODES", "reading_mode",
    "combine_joint_powers", "CotReadings", "cot_readings_from_arrays", "cot_readings_from_log",
    "resolve_weight",
    # decoupled CoT (sagittal + frontal planar models)
    "cot_decoupled", "decoupled_energy", "decoupled_power", "DecoupledEnergy",
    "decoupled_joint_power", "DecoupledCotReadings", "cot_decoupled_readings",
    # all readings of a log at once
    "RunCot", "cot_readings_report",
    # stances
    "Stance", "STANCE_SOURCES", "find_stances", "stance_table", "debounce", "true_runs",
    "resolve_source", "planned_column",
    # rolling
    "rolling_from_arrays", "rolling_from_log", "PlateauResult", "detect_plateau",
    "plateau_by_stance",
    # metrics
    "segment_stances", "contact_segments", "stance_column", "StancePeaks", "stance_peaks",
    "stance_phase", "role_column", "leg_joint_roles", "phase_grid",
    "resample_by_phase", "resample_stances", "phase_bands", "rmse_table",
]
