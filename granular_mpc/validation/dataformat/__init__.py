"""Measurement data format v1: typed ``meta.yaml``, a loader that checks everything, a writer.

A data set is a folder holding ``meta.yaml`` and one file per trial (``*.csv`` or
``*.parquet``); the full specification is ``docs/data-format.md``. In short, every trial
file has the columns (SI units, world frame ``W``: x forward = walking direction, y left,
z up; see ``docs/notation.md``)::

    time                                   s, strictly increasing
    stance                                 "left" | "right" | "none"
    q_<joint>, dq_<joint>, tau_<joint>     rad, rad/s, N·m — one per actuated joint of the robot
    base_x, base_y, base_z                 trunk position p_W_B [m]
    base_qw, base_qx, base_qy, base_qz     trunk orientation, unit quaternion (w, x, y, z) of B in W
    base_vx, base_vy, base_vz              trunk linear velocity in W [m/s]
    base_wx, base_wy, base_wz              trunk angular velocity in B [rad/s]
    grf_x, grf_y, grf_z                    force of the ground on the stance foot, W [N]
    intrusion_x, intrusion_y, intrusion_z  stance-foot contact point minus its touchdown point [m],
                                           z positive = deeper

``meta.yaml`` may declare which **channel groups** were measured (``channels:``, see
:mod:`.channels`); the columns of the other groups are then absent, and a missing
``stance`` column is derived from foot force or leg kinematics (:mod:`.stance_derive`;
``Dataset.stance_source`` says how). Without ``channels`` every column above is required.

Extra columns are kept and ignored. :func:`load_dataset` checks the meta file, every
trial file and every value, and reports **all** problems at once in one
:class:`~granular_mpc.exceptions.DataFormatError` whose ``problems`` each name the file,
the column and the first offending row. Rows are 1-based *data* row numbers: row 1 is the
first row after the header, so in a CSV file data row ``n`` is on text line ``n + 1``.
Repeated problems of one kind in one column are grouped into one problem that lists the
runs of rows (``"rows 12–40, 57 (30 rows)"``). Nothing is dropped, repaired or guessed.

Public API: :class:`DatasetMeta` (+ :class:`TrialMeta`, :class:`GeneratorMeta`),
:class:`FormatTolerances`, :class:`Dataset`, :func:`load_dataset`, :func:`check_dataset`,
:func:`check_trials`, :func:`write_dataset`, :func:`stance_phases` /
:class:`StancePhase`, :func:`format_columns`, :class:`ChannelGroup` / :class:`ChannelSet`,
:class:`StanceDerivation` / :func:`derive_stance`, :func:`drop_channels`,
:func:`merge_datasets`.

Modules, one job each: :mod:`.meta` (the ``meta.yaml`` schema), :mod:`.tolerances`,
:mod:`.dataset` (the loaded data set, stance phases), :mod:`.readers` (one CSV/Parquet
file), :mod:`.load` (a data set folder), :mod:`.write` (writing, and checking in-memory
trials), :mod:`.checks` (every check of one trial, each in a ``checks_<what>.py``) with
:mod:`.trial_check` (their working state and wording), :mod:`.robot_facts` (joint limits
and weight from the URDF) and :mod:`.checks_meta`, :mod:`.channels` (channel groups) and :mod:`.stance_derive`
(stance labels of unlabelled trials). The column names are
:mod:`granular_mpc.columns`'s, re-exported here.
"""

from ...columns import (BASE_ANGULAR_VELOCITY, BASE_COLUMNS, BASE_LINEAR_VELOCITY, BASE_POSITION,
                        BASE_QUATERNION, GRF_COLUMNS, INTRUSION_COLUMNS, JOINT_PREFIXES, META_FILE,
                        STANCE_LABELS, format_columns, joint_columns)
from .channels import ChannelGroup, ChannelSet, group_of_column
from .dataset import Dataset, StancePhase, stance_phases
from .drop import drop_channels
from .load import check_dataset, load_dataset
from .merge import merge_datasets
from .meta import SCHEMA_VERSION, SUFFIXES, DatasetMeta, GeneratorMeta, TrialMeta, TrialName
from .stance_derive import StanceDerivation, StanceSource, derive_stance
from .tolerances import FormatTolerances
from .write import check_trials, write_dataset

__all__ = [
    "SCHEMA_VERSION", "META_FILE", "STANCE_LABELS", "BASE_COLUMNS", "GRF_COLUMNS",
    "INTRUSION_COLUMNS", "TrialMeta", "GeneratorMeta", "DatasetMeta", "FormatTolerances",
    "Dataset", "StancePhase", "stance_phases", "format_columns", "joint_columns",
    "load_dataset", "check_dataset", "check_trials", "write_dataset",
    "ChannelGroup", "ChannelSet", "group_of_column", "StanceDerivation", "StanceSource",
    "derive_stance", "drop_channels", "merge_datasets",
    # also importable from here, as before the split
    "SUFFIXES", "TrialName", "JOINT_PREFIXES", "BASE_POSITION", "BASE_QUATERNION",
    "BASE_LINEAR_VELOCITY", "BASE_ANGULAR_VELOCITY",
]
