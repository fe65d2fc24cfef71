"""Validation workbench: measurement data format v1 (loader, checks, writer).

See ``docs/data-format.md`` for the format and :mod:`granular_mpc.validation.dataformat`
for the API.
"""
from .dataformat import (BASE_COLUMNS, GRF_COLUMNS, INTRUSION_COLUMNS, META_FILE,
                         SCHEMA_VERSION, STANCE_LABELS, Dataset, DatasetMeta, FormatTolerances,
                         GeneratorMeta, StancePhase, TrialMeta, check_dataset, check_trials,
                         format_columns, joint_columns, load_dataset, stance_phases,
                         write_dataset)

__all__ = [
    "SCHEMA_VERSION", "META_FILE", "STANCE_LABELS", "BASE_COLUMNS", "GRF_COLUMNS",
    "INTRUSION_COLUMNS", "TrialMeta", "GeneratorMeta", "DatasetMeta", "FormatTolerances",
    "Dataset", "StancePhase", "stance_phases", "format_columns", "joint_columns",
    "load_dataset", "check_dataset", "check_trials", "write_dataset",
]
