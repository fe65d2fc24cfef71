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
:class:`StancePhase`, :func:`format_columns`.
"""

from __future__ import annotations

import difflib
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Annotated, Any, Iterable, Literal, Mapping, NamedTuple, Sequence

import numpy as np
import pandas as pd
import yaml
from pydantic import Field, StringConstraints, ValidationError, field_validator, model_validator

from ..config import (EffectSpec, FiniteFloat, NonNegFloat, PositiveFloat, StrictModel,
                      _fmt_loc, _model_fields_at, validate)
from ..exceptions import ConfigError, DataFormatError, DataProblem, GranularMpcError, OutputError

# --------------------------------------------------------------------------------------
# Column names and constants
# --------------------------------------------------------------------------------------

SCHEMA_VERSION = 1
META_FILE = "meta.yaml"
STANCE_LABELS = ("left", "right", "none")
SUFFIXES = {"csv": ".csv", "parquet": ".parquet"}
JOINT_PREFIXES = ("q_", "dq_", "tau_")
BASE_POSITION = ("base_x", "base_y", "base_z")
BASE_QUATERNION = ("base_qw", "base_qx", "base_qy", "base_qz")
BASE_LINEAR_VELOCITY = ("base_vx", "base_vy", "base_vz")
BASE_ANGULAR_VELOCITY = ("base_wx", "base_wy", "base_wz")
GRF_COLUMNS = ("grf_x", "grf_y", "grf_z")
INTRUSION_COLUMNS = ("intrusion_x", "intrusion_y", "intrusion_z")
BASE_COLUMNS = BASE_POSITION + BASE_QUATERNION + BASE_LINEAR_VELOCITY + BASE_ANGULAR_VELOCITY

_DEG = math.pi / 180.0
#: Cell texts that the CSV reader turns into "missing" (pyarrow's default null values).
_NULL_WORDS = frozenset({"", "#n/a", "#n/a n/a", "#na", "-1.#ind", "-1.#qnan", "-nan", "1.#ind",
                         "1.#qnan", "n/a", "na", "null", "nan"})
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)     # libyaml when available
_MAX_RUNS = 10        # runs of rows spelled out per problem
_MAX_LABELS = 5       # distinct bad stance labels reported one by one


def joint_columns(joint_names: Sequence[str], kind: Literal["q", "dq", "tau"] = "q") -> list[str]:
    """Column names ``<kind>_<joint>`` in actuator order.

    Args:
        joint_names: actuated joints of the robot (``load_robot(name).joints``).
        kind: ``"q"`` (angle, rad), ``"dq"`` (velocity, rad/s) or ``"tau"`` (torque, N·m).
    """
    if kind not in ("q", "dq", "tau"):
        raise ValueError(f"kind must be 'q', 'dq' or 'tau', got {kind!r}")
    return [f"{kind}_{j}" for j in joint_names]


def format_columns(joint_names: Sequence[str]) -> list[str]:
    """Every column format v1 requires, in the recommended order.

    Args:
        joint_names: actuated joints of the robot, actuator order.

    Returns:
        ``time, stance, q_*, dq_*, tau_*, base_*, grf_*, intrusion_*``.
    """
    cols = ["time", "stance"]
    for kind in ("q", "dq", "tau"):
        cols += joint_columns(joint_names, kind)  # type: ignore[arg-type]
    return cols + list(BASE_COLUMNS) + list(GRF_COLUMNS) + list(INTRUSION_COLUMNS)


# --------------------------------------------------------------------------------------
# meta.yaml
# --------------------------------------------------------------------------------------

TrialName = Annotated[str, StringConstraints(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$",
                                             max_length=200)]


def _file_name_error(name: str) -> str:
    """Why ``name`` is not a valid trial file name, or ``""``."""
    if not name or name in (".", "..") or "/" in name or "\\" in name:
        return (f"{name!r} must be a file name inside the data set folder, "
                "without a directory part")
    if Path(name).suffix.lower() not in SUFFIXES.values():
        return f"{name!r} must end in .csv or .parquet"
    return ""


class TrialMeta(StrictModel):
    """One trial: its file and what the robot was asked to do."""

    file: str = Field(description="Trial file name in the data set folder, *.csv or *.parquet.")
    commanded_speed_mps: FiniteFloat = Field(
        description="Commanded forward walking speed along world x [m/s].")
    description: str = Field("", description="Free-form notes on this trial.")

    @field_validator("file")
    @classmethod
    def _plain_file_name(cls, value: str) -> str:
        problem = _file_name_error(value)
        if problem:
            raise ValueError(problem)
        return value


class GeneratorMeta(StrictModel):
    """Provenance of a synthetic data set (written by ``granular-mpc synth``)."""

    scenario: str = Field("", description="Scenario file the plant was configured from.")
    seed: int | None = Field(None, description="Random seed of the noise and of the plant.")
    effects: list[EffectSpec] = Field(default_factory=list,
                                      description="Extra physical effects injected in the plant.")
    noise: dict[str, NonNegFloat] = Field(
        default_factory=dict,
        description="Standard deviation of the additive Gaussian noise per column or column "
                    "prefix (e.g. 'grf_', 'q_'), in that column's unit.")
    settings: dict[str, Any] = Field(default_factory=dict,
                                     description="Any further generator settings (free-form).")


class DatasetMeta(StrictModel):
    """Contents of ``meta.yaml`` (format v1). Unknown keys are errors.

    Example::

        schema_version: 1
        robot: yobogo10s
        terrain: dry play sand, 12 cm layer, loosened between trials
        sample_rate_hz: 500
        trials:
          trial_001: {file: trial_001.csv, commanded_speed_mps: 0.2}
          trial_002: {file: trial_002.csv, commanded_speed_mps: 0.3}
    """

    schema_version: Literal[1] = Field(description="Format version; this loader reads 1.")
    robot: str = Field(min_length=1, description="Robot model name in models/ (or a path).")
    terrain: str = Field(description="Free-form description of the ground.")
    sample_rate_hz: PositiveFloat = Field(description="Nominal sample rate of every trial [Hz].")
    trials: dict[TrialName, TrialMeta] = Field(min_length=1,
                                               description="Trial name → trial entry.")
    description: str = Field("", description="Free-form notes on the data set.")
    generator: GeneratorMeta | None = Field(None, description="Set for synthetic data.")

    @model_validator(mode="after")
    def _files_unique(self) -> "DatasetMeta":
        shared = _shared_files([(n, t.file) for n, t in self.trials.items()])
        if shared:
            raise ValueError("; ".join(shared))
        return self


def _shared_files(pairs: Iterable[tuple[str, str]]) -> list[str]:
    """Messages for trials that name the same file (compared case-insensitively)."""
    seen: dict[str, str] = {}
    out = []
    for name, file in pairs:
        key = file.lower()                    # case-insensitive file systems
        if key in seen:
            out.append(f"trials {seen[key]!r} and {name!r} use the same file {file!r}")
        else:
            seen[key] = name
    return out


class FormatTolerances(StrictModel):
    """Thresholds of the loader's checks. The defaults suit a YoboGo-10S-class biped.

    Every threshold is on a physical quantity, so it can be reasoned about: change one
    when your data legitimately exceeds it, never to silence a real unit problem.
    """

    quaternion_norm: PositiveFloat = Field(1e-3, description="Allowed | ‖q‖ − 1 | of the trunk quaternion [-].")
    sample_rate: PositiveFloat = Field(0.01, description="Allowed relative difference between 1/median(Δt) and sample_rate_hz [-].")
    step_jitter: float = Field(0.5, gt=0.0, lt=1.0, description="Each Δt must lie within (1 ± this)/sample_rate_hz [-].")
    joint_limit_margin: NonNegFloat = Field(0.1, description="Allowed excursion beyond the URDF position limits [rad].")
    velocity_limit_factor: PositiveFloat = Field(2.0, description="|dq| may reach this multiple of the URDF velocity limit [-].")
    torque_limit_factor: PositiveFloat = Field(2.0, description="|tau| may reach this multiple of the URDF effort limit [-].")
    max_base_height: PositiveFloat = Field(5.0, description="Largest plausible median |base_z| [m].")
    max_base_speed: PositiveFloat = Field(20.0, description="Largest plausible trunk speed (95th percentile) [m/s].")
    max_base_rate: PositiveFloat = Field(50.0, description="Largest plausible trunk angular rate (95th percentile) [rad/s].")
    max_intrusion: PositiveFloat = Field(0.5, description="Largest plausible |intrusion_*| [m] (longer than the leg).")
    max_commanded_speed: PositiveFloat = Field(3.0, description="Largest plausible |commanded_speed_mps| [m/s].")
    rate_correlation: float = Field(0.8, gt=0.0, lt=1.0, description="A velocity column is compared with the time derivative of its position column only when they correlate at least this well [-].")
    rate_ratio: float = Field(2.0, gt=1.0, description="Allowed ratio velocity / derivative of position, either way [-].")
    weight_ratio: float = Field(3.0, gt=1.0, description="Mean vertical GRF over a trial must lie within [1/this, this] × robot weight [-].")
    intrusion_sign: PositiveFloat = Field(0.005, description="Stance intrusion_z below −this for most samples means a flipped sign [m].")
    min_travel_duration: PositiveFloat = Field(0.4, description="Shortest trial whose direction of travel and GRF balance are checked [s].")


# --------------------------------------------------------------------------------------
# The loaded data set
# --------------------------------------------------------------------------------------


class StancePhase(NamedTuple):
    """One maximal run of rows with the same ``stance`` label.

    Attributes:
        trial: trial name (``""`` when segmenting a bare DataFrame).
        row_start: positional index of the first row (0-based), ``df.iloc[row_start]``.
        row_stop: positional index one past the last row: ``df.iloc[row_start:row_stop]``.
        side: ``"left"``, ``"right"`` or ``"none"``.
        complete: False if the run touches the first or the last row of the trial, i.e.
            the recording may have cut it (its touchdown or lift-off was not observed).
    """

    trial: str
    row_start: int
    row_stop: int
    side: str
    complete: bool

    @property
    def first_row(self) -> int:
        """1-based data row number of the first row, as in the file and in error messages."""
        return self.row_start + 1

    @property
    def last_row(self) -> int:
        """1-based data row number of the last row."""
        return self.row_stop

    @property
    def n_rows(self) -> int:
        """Number of samples in the phase."""
        return self.row_stop - self.row_start


def stance_phases(df: pd.DataFrame, *, trial: str = "",
                  sides: Iterable[str] = STANCE_LABELS) -> list[StancePhase]:
    """Segment a trial into maximal runs of one stance label.

    Args:
        df: a trial with a ``stance`` column of ``left`` / ``right`` / ``none`` labels.
        trial: name stored in each phase.
        sides: labels to return (default: all three; ``("left", "right")`` for stance only).

    Returns:
        The phases in time order.

    Raises:
        DataFormatError: if ``stance`` is missing or holds another label.
    """
    wanted = set(sides)
    unknown = wanted - set(STANCE_LABELS)
    if unknown:
        raise ValueError(f"sides must be among {STANCE_LABELS}, got {sorted(unknown)}")
    where = trial or "<DataFrame>"
    if "stance" not in df.columns:
        raise DataFormatError([DataProblem(where, "required column is missing", "stance")])
    labels = df["stance"].astype(object).to_numpy()
    problems = _stance_problems(labels, np.arange(1, len(labels) + 1), where)
    if problems:
        raise DataFormatError(problems)
    n = len(labels)
    if n == 0:
        return []
    change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    starts = np.r_[0, change]
    stops = np.r_[change, n]
    return [StancePhase(trial, int(a), int(b), str(labels[a]), bool(a > 0 and b < n))
            for a, b in zip(starts, stops) if labels[a] in wanted]


@dataclass(frozen=True, eq=False)
class Dataset:
    """A loaded, checked data set. Build with :func:`load_dataset`.

    Format columns are float64 (``stance``: strings); extra columns keep the type they
    were read with. The DataFrames are the loader's own; copy one before changing it.

    Attributes:
        path: the data set folder.
        meta: the validated ``meta.yaml``.
        trials: trial name → DataFrame, in ``meta.yaml`` order (read-only mapping).
        joint_names: actuated joints of ``meta.robot``, actuator order.
    """

    path: Path
    meta: DatasetMeta
    trials: Mapping[str, pd.DataFrame]
    joint_names: tuple[str, ...]

    @property
    def trial_names(self) -> tuple[str, ...]:
        """Trial names in ``meta.yaml`` order."""
        return tuple(self.trials)

    def commanded_speed(self, trial: str) -> float:
        """Commanded walking speed of one trial [m/s]."""
        return self.meta.trials[trial].commanded_speed_mps

    def joint_columns(self, kind: Literal["q", "dq", "tau"] = "q") -> list[str]:
        """``q_*`` / ``dq_*`` / ``tau_*`` column names in actuator order."""
        return joint_columns(self.joint_names, kind)

    def stance_phases(self, sides: Iterable[str] = STANCE_LABELS) -> list[StancePhase]:
        """:func:`stance_phases` of every trial, trials in ``meta.yaml`` order."""
        sides = tuple(sides)
        out: list[StancePhase] = []
        for name, df in self.trials.items():
            out += stance_phases(df, trial=name, sides=sides)
        return out

    def to_frame(self) -> pd.DataFrame:
        """All trials stacked in one new DataFrame (e.g. for trial-grouped cross-validation).

        Columns ``trial``, ``row`` (1-based data row in its file) and
        ``commanded_speed_mps`` come first, then the trial columns; columns absent from
        some trials are NaN there.

        Raises:
            ValueError: if a trial already has a column named ``trial``, ``row`` or
                ``commanded_speed_mps``.
        """
        frames = []
        for name, df in self.trials.items():
            clash = {"trial", "row", "commanded_speed_mps"} & set(df.columns)
            if clash:
                raise ValueError(f"trial {name!r} already has column(s) {sorted(clash)}")
            head = pd.DataFrame({"trial": name, "row": np.arange(1, len(df) + 1),
                                 "commanded_speed_mps": self.commanded_speed(name)},
                                index=df.index)
            frames.append(pd.concat([head, df], axis=1))
        return pd.concat(frames, ignore_index=True)

    def write(self, path: str | Path, format: Literal["csv", "parquet"] = "csv", *,
              overwrite: bool = False) -> Path:
        """Write this data set to another folder (e.g. CSV → Parquet); see :func:`write_dataset`."""
        return write_dataset(path, self.meta, self.trials, format, overwrite=overwrite)


# --------------------------------------------------------------------------------------
# Problem reporting helpers
# --------------------------------------------------------------------------------------


def _rows_phrase(rows: np.ndarray) -> str:
    """``"row 7"`` or ``"rows 12–40, 57 (30 rows)"``; long lists end in ``… and N more runs``."""
    rows = np.unique(np.asarray(rows, dtype=np.int64))
    if rows.size == 1:
        return f"row {rows[0]}"
    breaks = np.flatnonzero(np.diff(rows) != 1)
    starts = np.r_[rows[0], rows[breaks + 1]]
    ends = np.r_[rows[breaks], rows[-1]]
    parts = [f"{a}" if a == b else f"{a}–{b}" for a, b in
             zip(starts[:_MAX_RUNS].tolist(), ends[:_MAX_RUNS].tolist())]
    if starts.size > _MAX_RUNS:
        parts.append(f"… and {starts.size - _MAX_RUNS} more runs")
    return f"rows {', '.join(parts)} ({rows.size} rows)"


def _close(name: str, candidates: Iterable[str]) -> str:
    """A did-you-mean hint, or ``""``."""
    candidates = list(candidates)
    for c in candidates:
        if c.strip().lower() == name.lower():
            return f"; column {c!r} differs only in case or spaces"
    match = difflib.get_close_matches(name, candidates, n=1, cutoff=0.75)
    return f"; did you mean {match[0]!r}?" if match else ""


def _scale_hint(ratio: float, angular: bool) -> str:
    """Name the unit mistake suggested by ``ratio`` = velocity / time derivative of position."""
    if not (np.isfinite(ratio) and ratio > 0):
        return ""
    known = ([(1 / _DEG, "velocity in degrees per second"), (_DEG, "angle in degrees")]
             if angular else
             [(1e3, "velocity in mm/s"), (1e2, "velocity in cm/s"), (1e-3, "position in mm"),
              (1e-2, "position in cm")])
    for factor, text in known:
        if abs(math.log(ratio / factor)) < math.log(1.5):
            return f" — a factor of {factor:.4g}: {text}?"
    return ""


@dataclass
class _Trial:
    """Working state of the checks of one trial file."""

    file: str
    df: pd.DataFrame
    rows: np.ndarray                       # 1-based data row number of each frame row
    strict_types: bool                     # Parquet / in-memory: numbers must be numeric dtypes
    problems: list[DataProblem] = field(default_factory=list)
    values: dict[str, np.ndarray] = field(default_factory=dict)   # float64, NaN where bad
    clean: set[str] = field(default_factory=set)                  # columns fully finite
    flagged: set[str] = field(default_factory=set)                # columns with a unit problem
    degrees: set[str] = field(default_factory=set)                # angle columns found in degrees

    def add(self, message: str, column: str = "", row: int | None = None) -> None:
        self.problems.append(DataProblem(self.file, message, column,
                                         None if row is None else int(row)))

    def add_rows(self, column: str, what: str, mask: np.ndarray, detail: str = "") -> None:
        """One problem for every row where ``mask`` is true: ``"<what> in rows …<detail>"``."""
        idx = np.flatnonzero(mask)
        if idx.size:
            rows = self.rows[idx]
            self.add(f"{what} in {_rows_phrase(rows)}{detail}", column, int(rows.min()))

    def ok(self, *columns: str) -> bool:
        """True if every column is present, fully finite and not suspected of a wrong unit."""
        return all(c in self.clean and c not in self.flagged for c in columns)


# --------------------------------------------------------------------------------------
# Robot facts used by the checks
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _RobotFacts:
    name: str
    joints: tuple[str, ...]
    q_lower: dict[str, float]
    q_upper: dict[str, float]
    dq_max: dict[str, float]
    tau_max: dict[str, float]
    weight: float                            # m g [N]


def _file_stamp(path: Path) -> tuple[str, int, int]:
    st = path.stat()
    return str(path), st.st_mtime_ns, st.st_size


# (robot YAML stamp, name) -> (URDF stamp, facts); entries are re-validated on every use
_FACTS_CACHE: dict[tuple[tuple[str, int, int], str], tuple[tuple[str, int, int], _RobotFacts]] = {}


def _robot_facts(name: str, folder: Path | None) -> _RobotFacts:
    """Joint names, limits and weight of robot ``name`` (a models/ name or a path).

    The facts are cached per robot file and reused only while neither the robot YAML
    nor its URDF has changed on disk (loading a data set stays cheap in a loop).

    Raises:
        ConfigError, ModelError: the robot cannot be found, read or built.
    """
    from ..config import load_robot
    from ..paths import resolve_file
    from ..robot.model import Biped

    path = resolve_file("robot", name, relative_to=folder, key="robot")
    key = (_file_stamp(path), name)
    cached = _FACTS_CACHE.get(key)
    if cached is not None:
        urdf_stamp, facts = cached
        try:
            if _file_stamp(Path(urdf_stamp[0])) == urdf_stamp:
                return facts
        except OSError:
            pass
    config = load_robot(str(path))
    biped = Biped.from_config(config, with_visuals=False)
    lo, hi = biped.position_limits
    joints = tuple(biped.joint_names)
    facts = _RobotFacts(
        name=name, joints=joints,
        q_lower=dict(zip(joints, map(float, lo))), q_upper=dict(zip(joints, map(float, hi))),
        dq_max=dict(zip(joints, map(float, biped.velocity_limits))),
        tau_max=dict(zip(joints, map(float, biped.torque_limits))),
        weight=biped.weight)
    _FACTS_CACHE[key] = (_file_stamp(config.urdf_path), facts)
    return facts


# --------------------------------------------------------------------------------------
# Meta checks
# --------------------------------------------------------------------------------------


@dataclass
class _MetaView:
    """What the trial checks need from meta.yaml — also when meta.yaml has problems."""

    meta: DatasetMeta | None
    robot: str | None
    sample_rate_hz: float | None
    trials: list[tuple[str, str, float | None]]      # (name, file, commanded speed)


def _pydantic_problems(exc: ValidationError, file: str) -> list[DataProblem]:
    """One DataProblem per pydantic error, worded like :func:`granular_mpc.config.validate`."""
    out = []
    for err in exc.errors():
        loc = list(err["loc"])
        typ = err["type"]
        if loc and loc[-1] == "[key]":
            key = _fmt_loc(loc[:-2])
            msg = (f"trial name {loc[-2]!r} is not valid: use letters, digits, '_', '-' and "
                   "'.', starting with a letter or a digit")
        else:
            key = _fmt_loc(loc)
            if typ == "extra_forbidden":
                valid = _model_fields_at(DatasetMeta, loc[:-1])
                close = difflib.get_close_matches(str(loc[-1]), valid, n=1, cutoff=0.5)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                msg = f"unknown key '{loc[-1]}'{hint} (valid keys here: {', '.join(valid)})"
            elif typ == "missing":
                msg = "required key is missing"
            elif typ == "value_error":
                msg = str(err["msg"]).removeprefix("Value error, ")
            else:
                msg = f"{err['msg']} (got {err.get('input')!r})"
        out.append(DataProblem(file, f"{key}: {msg}" if key else msg))
    return out


def _finite_number(value: Any) -> float | None:
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def _check_meta(raw: dict[str, Any], tol: FormatTolerances,
                problems: list[DataProblem]) -> _MetaView | None:
    """Validate the meta mapping; salvage what the trial checks need if it is invalid."""
    version = raw.get("schema_version")
    if "schema_version" not in raw:
        problems.append(DataProblem(META_FILE, "schema_version: required key is missing "
                                    f"(this is format v{SCHEMA_VERSION}: write "
                                    f"'schema_version: {SCHEMA_VERSION}')"))
        return None
    if type(version) is not int or version != SCHEMA_VERSION:
        problems.append(DataProblem(META_FILE, f"schema_version: {version!r} is not supported "
                                    f"(this loader reads format v{SCHEMA_VERSION})"))
        return None
    try:
        meta = DatasetMeta.model_validate(raw)
    except ValidationError as exc:
        problems += _pydantic_problems(exc, META_FILE)
        meta = None
    if meta is not None:
        view = _MetaView(meta, meta.robot, meta.sample_rate_hz,
                         [(n, t.file, t.commanded_speed_mps) for n, t in meta.trials.items()])
    else:
        robot = raw.get("robot") if isinstance(raw.get("robot"), str) and raw["robot"] else None
        rate = _finite_number(raw.get("sample_rate_hz"))
        trials = []
        entries = raw.get("trials")
        if isinstance(entries, dict):
            for name, entry in entries.items():
                if isinstance(entry, dict) and isinstance(entry.get("file"), str) \
                        and not _file_name_error(entry["file"]):
                    trials.append((str(name), entry["file"],
                                   _finite_number(entry.get("commanded_speed_mps"))))
        view = _MetaView(None, robot, rate if rate and rate > 0 else None, trials)
        reported = " ".join(p.message for p in problems)
        for text in _shared_files((n, f) for n, f, _ in trials):
            if text not in reported:
                problems.append(DataProblem(META_FILE, f"trials: {text}"))
        first_use: dict[str, tuple[str, str, float | None]] = {}
        for trial in trials:                     # check a shared file once
            first_use.setdefault(trial[1].lower(), trial)
        view.trials = list(first_use.values())
    for name, _, speed in view.trials:
        if speed is not None and abs(speed) > tol.max_commanded_speed:
            problems.append(DataProblem(
                META_FILE, f"trials.{name}.commanded_speed_mps: {speed:g} is implausible for "
                f"m/s (limit {tol.max_commanded_speed:g} m/s): cm/s or mm/s?"))
    return view


# --------------------------------------------------------------------------------------
# Reading trial files
# --------------------------------------------------------------------------------------


def _read_csv(path: Path, file: str) -> tuple[pd.DataFrame | None, np.ndarray, list[DataProblem]]:
    """Read one CSV file with pyarrow; rows with the wrong number of fields are reported.

    Returns:
        (frame or None, data row number of each frame row, problems).
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    problems: list[DataProblem] = []
    invalid: list[Any] = []

    def on_invalid(row: Any) -> str:
        invalid.append(row)
        return "skip"

    try:
        size = path.stat().st_size
        table = pacsv.read_csv(
            path,
            # one block: column types are inferred from the whole file, and row numbers are known
            read_options=pacsv.ReadOptions(use_threads=False,
                                           block_size=int(min(max(size + 1, 1 << 16), 2**31 - 1))),
            parse_options=pacsv.ParseOptions(invalid_row_handler=on_invalid,
                                             ignore_empty_lines=False),
            convert_options=pacsv.ConvertOptions(strings_can_be_null=False,
                                                 column_types={"stance": pa.string()}))
    except (OSError, pa.ArrowException, ValueError) as exc:
        text = str(exc).strip()
        if "Empty CSV file" in text:
            text = "file is empty (not even a header line)"
        problems.append(DataProblem(file, f"cannot read as CSV: {text}"))
        return None, np.zeros(0, dtype=np.int64), problems
    names = table.column_names
    if len(names) == 1 and any(sep in names[0] for sep in (";", "\t", "|")):
        problems.append(DataProblem(file, f"the header is one column {names[0][:60]!r}: fields "
                                    "must be separated by commas"))
        return None, np.zeros(0, dtype=np.int64), problems
    skipped = []
    for row in invalid:
        number = getattr(row, "number", None)
        data_row = None if number is None else int(number) - 1      # line 1 is the header
        if data_row is not None:
            skipped.append(data_row)
        problems.append(DataProblem(
            file, f"malformed CSV line: {row.actual_columns} field(s) where the header has "
            f"{row.expected_columns}", "", data_row))
    n_total = table.num_rows + len(skipped)
    rows = np.setdiff1d(np.arange(1, n_total + 1), np.array(skipped, dtype=np.int64))
    if rows.size != table.num_rows:        # row numbers unknown (quoted line breaks): positions
        rows = np.arange(1, table.num_rows + 1)
    if len(set(names)) != len(names):
        df, rows, problems = _table_to_frame_with_duplicates(table, file, rows, problems)
    else:
        df = table.to_pandas()
    # a blank line reads as a row of empty cells: report it as such, not as 40 empty values
    blank = np.zeros(len(df), dtype=bool)
    if len(df.columns):
        first = df.iloc[:, 0]
        blank = (first.isna() | (first.astype(object) == "")).to_numpy(dtype=bool, copy=True)
        for k in range(1, len(df.columns)):
            if not blank.any():
                break
            cells = df.iloc[:, k]
            blank &= (cells.isna() | (cells.astype(object) == "")).to_numpy(dtype=bool)
    if blank.any():
        r = rows[blank]
        problems.append(DataProblem(file, f"blank line in {_rows_phrase(r)}", "", int(r.min())))
        df = df.loc[~blank].reset_index(drop=True)
        rows = rows[~blank]
    return df, rows, problems


def _table_to_frame_with_duplicates(table: Any, file: str, rows: np.ndarray,
                                    problems: list[DataProblem]):
    names = table.column_names
    for name in sorted({n for n in names if names.count(n) > 1}):
        problems.append(DataProblem(file, f"column name appears {names.count(name)} times in "
                                    "the header", name))
    keep = [i for i, n in enumerate(names) if names.index(n) == i]
    return table.select(keep).to_pandas(), rows, problems


def _read_parquet(path: Path, file: str) -> tuple[pd.DataFrame | None, np.ndarray, list[DataProblem]]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    problems: list[DataProblem] = []
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowException, ValueError) as exc:
        problems.append(DataProblem(file, f"cannot read as Parquet: {str(exc).strip()}"))
        return None, np.zeros(0, dtype=np.int64), problems
    rows = np.arange(1, table.num_rows + 1)
    names = table.column_names
    if len(set(names)) != len(names):
        return _table_to_frame_with_duplicates(table, file, rows, problems)
    df = table.to_pandas()
    if not isinstance(df.index, pd.RangeIndex) or df.index.start != 0 or df.index.step != 1:
        df = df.reset_index()        # a stored pandas index is data: keep it as a column
    return df, rows, problems


# --------------------------------------------------------------------------------------
# Trial checks
# --------------------------------------------------------------------------------------


def _check_header(t: _Trial, facts: _RobotFacts | None) -> list[str]:
    """Column names: non-text or empty names, missing format columns, unknown joints.

    Returns:
        The format columns required of this trial (without the joint columns when the
        robot is unknown).
    """
    cols = list(t.df.columns)
    for i, c in enumerate(cols):
        if not isinstance(c, str):
            t.add(f"column {i + 1} has a non-text name {c!r}", str(c))
        elif not c.strip():
            t.add(f"column {i + 1} has an empty name (a trailing comma in the header?)", c)
    names = [c for c in cols if isinstance(c, str)]
    joints = facts.joints if facts is not None else ()
    required = format_columns(joints)
    present = set(names)
    for col in required:
        if col not in present:
            t.add(f"required column is missing{_close(col, [c for c in names if c not in required])}",
                  col)
    if facts is not None:
        for col in names:
            for prefix in JOINT_PREFIXES:
                if col.startswith(prefix):
                    joint = col[len(prefix):]
                    if joint not in facts.joints:
                        t.add(f"'{joint}' is not an actuated joint of robot {facts.name!r} "
                              f"(joints: {', '.join(facts.joints)}){_close(joint, facts.joints)}",
                              col)
                    break
    return required


def _numeric_values(t: _Trial, col: str) -> None:
    """Convert one numeric column to float64 and report non-numeric, empty/NaN, ±inf cells.

    CSV columns holding text are parsed cell by cell (to name the bad cells); in Parquet
    and in-memory frames a numeric column must have a numeric type.
    """
    s = t.df[col]
    first = int(t.rows[0]) if len(s) else None
    bad_text = np.zeros(len(s), dtype=bool)
    if pd.api.types.is_bool_dtype(s.dtype):
        t.add("holds true/false values; format v1 wants numbers", col, first)
        return
    if pd.api.types.is_numeric_dtype(s.dtype) and not pd.api.types.is_complex_dtype(s.dtype):
        v = s.to_numpy(dtype=np.float64, na_value=np.nan)
    elif t.strict_types:
        cells = s.astype(object).to_numpy()
        if not all(x is None or (isinstance(x, (int, float, np.integer, np.floating))
                                 and not isinstance(x, (bool, np.bool_))) for x in cells):
            t.add(f"has type {s.dtype}; format v1 wants a floating-point column", col, first)
            return
        v = np.array([np.nan if x is None else float(x) for x in cells], dtype=np.float64)
    else:
        text = np.array(["" if x is None or (isinstance(x, float) and math.isnan(x))
                         else str(x).strip() for x in s.astype(object).to_numpy()], dtype=object)
        null_like = np.array([x.lower() in _NULL_WORDS for x in text], dtype=bool)
        parsed = pd.to_numeric(pd.Series(np.where(null_like, None, text), dtype=object),
                               errors="coerce")
        v = parsed.to_numpy(dtype=np.float64, na_value=np.nan)
        bad_text = np.isnan(v) & ~null_like
        if bad_text.any():
            examples = ", ".join(repr(x) for x in list(dict.fromkeys(text[bad_text]))[:3])
            t.add_rows(col, f"non-numeric values (e.g. {examples})", bad_text)
    t.add_rows(col, "empty or NaN values", np.isnan(v) & ~bad_text)
    t.add_rows(col, "infinite values", np.isinf(v))
    t.values[col] = v
    if np.isfinite(v).all():
        t.clean.add(col)


def _stance_problems(labels: np.ndarray, rows: np.ndarray, file: str) -> list[DataProblem]:
    """Bad or missing stance labels, one problem per distinct bad label (up to a few)."""
    out: list[DataProblem] = []
    missing = np.array([x is None or (isinstance(x, float) and math.isnan(x))
                        or (isinstance(x, str) and not x.strip()) for x in labels], dtype=bool)
    if missing.any():
        r = rows[missing]
        out.append(DataProblem(file, f"empty stance label in {_rows_phrase(r)}", "stance", int(r.min())))
    text = np.array([str(x) for x in labels], dtype=object)
    bad = ~missing & ~np.isin(text, STANCE_LABELS)
    distinct = list(dict.fromkeys(text[bad]))
    for k, label in enumerate(distinct):
        mask = bad & (text == label) if k < _MAX_LABELS else bad & ~np.isin(text, distinct[:_MAX_LABELS])
        r = rows[mask]
        if k < _MAX_LABELS:
            hint = (" (labels are lower case)" if label.strip().lower() in STANCE_LABELS
                    else "")
            what = f"stance label {label!r} is not left, right or none{hint}"
        else:
            what = f"{len(distinct) - _MAX_LABELS} more stance labels that are not left, right or none"
        out.append(DataProblem(file, f"{what} in {_rows_phrase(r)}", "stance", int(r.min())))
        if k >= _MAX_LABELS:
            break
    return out


def _check_time(t: _Trial, fs: float | None, tol: FormatTolerances) -> bool:
    """Strictly increasing time and sampling consistent with ``sample_rate_hz``.

    The step-by-step checks (gaps, short steps) run only when time is strictly
    increasing and its median step matches ``sample_rate_hz``; otherwise they would only
    echo the problems already reported.

    Returns:
        True if ``time`` is finite, strictly increasing and consistent with
        ``sample_rate_hz`` (the time-derivative checks need all three).
    """
    if "time" not in t.values:
        return False
    time = t.values["time"]
    idx = np.flatnonzero(np.isfinite(time))
    if idx.size < 2:
        return False
    dt = np.diff(time[idx])
    later = np.zeros(len(time), dtype=bool)
    later[idx[1:][dt == 0]] = True
    t.add_rows("time", "time repeats the value of the previous row", later)
    later[:] = False
    later[idx[1:][dt < 0]] = True
    t.add_rows("time", "time goes backwards (smaller than in the previous row)", later)
    increasing = bool((dt > 0).all()) and "time" in t.clean
    positive = dt[dt > 0]
    if fs is None or positive.size == 0:
        return False
    median = float(np.median(positive))
    ratio = (1.0 / median) / fs
    if abs(ratio - 1.0) > tol.sample_rate:
        hint = ""
        for factor, unit in ((1e-3, "milliseconds"), (1e-6, "microseconds"), (1e-9, "nanoseconds")):
            if abs(math.log(ratio / factor)) < math.log(1.5):
                hint = f" — is time in {unit}?"
        t.add(f"median time step {median:.6g} s ({1 / median:.6g} Hz) does not match "
              f"sample_rate_hz = {fs:g} in {META_FILE} (tolerance {tol.sample_rate:.0%}){hint}",
              "time")
        return False
    if not increasing:
        return False
    lo, hi = (1 - tol.step_jitter) / fs, (1 + tol.step_jitter) / fs
    step = np.full(len(time), np.nan)
    step[idx[1:]] = dt
    # a step across rows already reported (unreadable line, blank line, NaN time) is no news
    across = (np.diff(idx) > 1) | (np.diff(t.rows[idx]) > 1)
    step[idx[1:][across]] = np.nan
    long = step > hi
    if long.any():
        t.add_rows("time", f"time step longer than {hi:.4g} s = {1 + tol.step_jitter:g}/"
                   f"sample_rate_hz (samples missing?)", long,
                   f"; largest step {np.nanmax(step):.4g} s")
    short = (step > 0) & (step < lo)
    if short.any():
        t.add_rows("time", f"time step shorter than {lo:.4g} s = {1 - tol.step_jitter:g}/"
                   f"sample_rate_hz (irregular sampling?)", short,
                   f"; smallest step {np.nanmin(step[short]):.4g} s")
    return increasing


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of (n, 4) arrays of (w, x, y, z) quaternions."""
    w1, v1 = a[:, :1], a[:, 1:]
    w2, v2 = b[:, :1], b[:, 1:]
    return np.hstack([w1 * w2 - np.sum(v1 * v2, axis=1, keepdims=True),
                      w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def _check_orientation(t: _Trial, tol: FormatTolerances) -> bool:
    """Unit quaternion, trunk upright and facing +x. Returns True if the quaternion is usable."""
    cols = BASE_QUATERNION
    if not all(c in t.values for c in cols):
        return False
    quat = np.column_stack([t.values[c] for c in cols])
    fin = np.isfinite(quat).all(axis=1)
    norm = np.linalg.norm(quat, axis=1)
    bad = fin & (np.abs(norm - 1.0) > tol.quaternion_norm)
    name = ",".join(cols)
    if bad.any():
        t.add_rows(name, f"quaternion (base_qw, base_qx, base_qy, base_qz) is not unit "
                   f"(|‖q‖ − 1| > {tol.quaternion_norm:g})", bad,
                   f"; ‖q‖ ranges over [{norm[bad].min():.4g}, {norm[bad].max():.4g}]")
    good = fin & ~bad
    if good.sum() == 0:
        return False
    w, x, y, z = (quat[good] / norm[good, None]).T
    heading = np.median(1 - 2 * (y * y + z * z))      # x-component of the trunk x axis in W
    upright = np.median(1 - 2 * (x * x + y * y))      # z-component of the trunk z axis in W
    if upright < 0.5:
        t.add(f"the trunk is tilted by more than 60° from upright in most rows (median "
              f"z-axis component {upright:.2f}): quaternion order must be (w, x, y, z)", name)
        t.flagged.update(cols)
    elif heading < 0.0:
        t.add(f"the trunk x axis points backwards (toward world −x) in most rows (median "
              f"x-axis component {heading:.2f}): world x must be the walking direction and the "
              "quaternion order (w, x, y, z) — written as (x, y, z, w)?", name)
        t.flagged.update(cols)
    return bool(fin.all()) and not bad.any() and not (t.flagged & set(cols))


def _rate_consistency(t: _Trial, vel_col: str, measured: np.ndarray, derived: np.ndarray,
                      source: str, angular: bool, tol: FormatTolerances) -> None:
    """Compare a velocity column with the time derivative of its position column.

    With m the measured velocity and d the finite-difference derivative (both at the
    mid-points of the samples), ratio = Σm² / Σmd (unbiased by noise in d) and
    corr = Σmd / √(Σm² Σd²). Only well-correlated channels are judged.
    """
    ok = np.isfinite(measured) & np.isfinite(derived)
    if ok.sum() < 10:
        return
    m, d = measured[ok], derived[ok]
    smm, sdd, smd = float(m @ m), float(d @ d), float(m @ d)
    if smm <= 0 or sdd <= 0 or math.sqrt(sdd / m.size) < 1e-6:
        return
    corr = smd / math.sqrt(smm * sdd)
    if corr <= -tol.rate_correlation:
        t.add(f"has the opposite sign of the time derivative of {source} (correlation "
              f"{corr:.2f}): sign convention or frame?", vel_col)
        t.flagged.add(vel_col)
    elif corr >= tol.rate_correlation:
        ratio = smm / smd
        if not 1 / tol.rate_ratio <= ratio <= tol.rate_ratio:
            t.add(f"is {ratio:.4g}× the time derivative of {source} (expected 1; correlation "
                  f"{corr:.2f}){_scale_hint(ratio, angular)}", vel_col)
            t.flagged.add(vel_col)


def _midpoints(v: np.ndarray) -> np.ndarray:
    return 0.5 * (v[1:] + v[:-1])


def _check_joints(t: _Trial, facts: _RobotFacts, time_ok: bool, tol: FormatTolerances) -> None:
    """Joint angles in radians within the URDF limits, velocities and torques plausible."""
    time = t.values.get("time")
    for j in facts.joints:
        qc, dqc, tauc = f"q_{j}", f"dq_{j}", f"tau_{j}"
        if qc in t.values:
            v = t.values[qc]
            fin = np.isfinite(v)
            # a revolute joint without finite URDF limits still turns within ±2π
            lower = facts.q_lower[j] if np.isfinite(facts.q_lower[j]) else -2 * math.pi
            upper = facts.q_upper[j] if np.isfinite(facts.q_upper[j]) else 2 * math.pi
            lo, hi = lower - tol.joint_limit_margin, upper + tol.joint_limit_margin
            out = fin & ((v < lo) | (v > hi))
            if out.any():
                vr = v[fin] * _DEG
                span = f"values in [{np.min(v[fin]):.4g}, {np.max(v[fin]):.4g}]"
                limits = f"[{lower:g}, {upper:g}] rad"
                # degrees only if the angles are far outside the limits as radians (by more
                # than the joint's whole range) and inside them once converted: small angles
                # fit any range containing 0 after conversion, so that alone proves nothing
                excursion = float(max(lo - np.min(v[fin]), np.max(v[fin]) - hi))
                joint_range = upper - lower
                if excursion > joint_range and vr.min() >= lo and vr.max() <= hi:
                    t.add(f"{span} exceed the joint limits {limits} of robot {facts.name!r} but "
                          "fit them after a degree→radian conversion: degrees? (format v1 wants "
                          "radians)",
                          qc, int(t.rows[np.flatnonzero(out)[0]]))
                    t.degrees.add(qc)
                else:
                    extra = (" — beyond ±2π, so not radians" if np.max(np.abs(v[fin])) > 2 * math.pi
                             else " — zero offset, sign convention or unit?")
                    t.add_rows(qc, f"angle outside the joint limits {limits} (± "
                               f"{tol.joint_limit_margin:g} rad) of robot {facts.name!r}", out,
                               f"; {span}{extra}")
                t.flagged.add(qc)
        if dqc in t.values:
            v = t.values[dqc]
            limit = tol.velocity_limit_factor * facts.dq_max[j]
            out = np.isfinite(v) & (np.abs(v) > limit)
            if out.any() and np.isfinite(limit):
                peak = float(np.max(np.abs(v[out])))
                hint = " — degrees per second?" if peak * _DEG <= limit else ""
                t.add_rows(dqc, f"|dq| exceeds {tol.velocity_limit_factor:g}× the URDF velocity "
                           f"limit {facts.dq_max[j]:g} rad/s", out, f"; largest {peak:.4g}{hint}")
                t.flagged.add(dqc)
        if tauc in t.values:
            v = t.values[tauc]
            limit = tol.torque_limit_factor * facts.tau_max[j]
            out = np.isfinite(v) & (np.abs(v) > limit)
            if out.any() and np.isfinite(limit):
                peak = float(np.max(np.abs(v[out])))
                hint = " — N·mm?" if peak / 1000 <= limit else ""
                t.add_rows(tauc, f"|tau| exceeds {tol.torque_limit_factor:g}× the URDF effort "
                           f"limit {facts.tau_max[j]:g} N·m", out, f"; largest {peak:.4g}{hint}")
                t.flagged.add(tauc)
        in_degrees = qc in t.degrees and qc in t.clean
        if time_ok and t.ok(dqc) and (t.ok(qc) or in_degrees):
            # an angle already reported in degrees is compared after conversion, so that a
            # velocity in deg/s is found in the same pass
            angle = t.values[qc] * (_DEG if in_degrees else 1.0)
            source = f"{qc} (converted to radians)" if in_degrees else qc
            _rate_consistency(t, dqc, _midpoints(t.values[dqc]), np.diff(angle) / np.diff(time),
                              source, True, tol)


def _check_base(t: _Trial, time_ok: bool, quat_ok: bool, tol: FormatTolerances) -> None:
    """Trunk position in metres, velocities plausible and consistent with the pose."""
    time = t.values.get("time")
    if "base_z" in t.values:
        z = t.values["base_z"]
        fin = np.isfinite(z)
        if fin.any() and np.median(np.abs(z[fin])) > tol.max_base_height:
            big = fin & (np.abs(z) > tol.max_base_height)
            t.add_rows("base_z", f"trunk height above {tol.max_base_height:g} m (median "
                       f"{np.median(z[fin]):.4g})", big, " — millimetres instead of metres?")
            t.flagged.add("base_z")
    if time_ok:
        dt = np.diff(time)
        for col in BASE_POSITION:
            if t.ok(col):
                speed = np.abs(np.diff(t.values[col])) / dt
                p95 = float(np.percentile(speed, 95))
                if p95 > tol.max_base_speed:
                    fast = np.r_[False, speed > tol.max_base_speed]
                    t.add_rows(col, f"changes faster than {tol.max_base_speed:g} m/s if in metres "
                               f"(95th percentile {p95:.4g} m/s)", fast,
                               " — millimetres instead of metres?")
                    t.flagged.add(col)
    for cols, limit, unit, hint in ((BASE_LINEAR_VELOCITY, tol.max_base_speed, "m/s",
                                     " — mm/s instead of m/s?"),
                                    (BASE_ANGULAR_VELOCITY, tol.max_base_rate, "rad/s",
                                     " — degrees per second?")):
        for col in cols:
            if col in t.values:
                v = t.values[col]
                fin = np.isfinite(v)
                if fin.sum() and np.percentile(np.abs(v[fin]), 95) > limit:
                    t.add_rows(col, f"|{col}| above {limit:g} {unit} (95th percentile "
                               f"{np.percentile(np.abs(v[fin]), 95):.4g})",
                               fin & (np.abs(v) > limit), hint)
                    t.flagged.add(col)
    if not time_ok:
        return
    dt = np.diff(time)
    for pos, vel in zip(BASE_POSITION, BASE_LINEAR_VELOCITY):
        if t.ok(pos, vel):
            _rate_consistency(t, vel, _midpoints(t.values[vel]), np.diff(t.values[pos]) / dt,
                              pos, False, tol)
    if quat_ok and t.ok(*BASE_QUATERNION):
        quat = np.column_stack([t.values[c] for c in BASE_QUATERNION])
        conj = quat[:-1] * np.array([1.0, -1.0, -1.0, -1.0])
        rel = _quat_mul(conj, quat[1:])                 # q_i⁻¹ ⊗ q_{i+1}: body-frame increment
        rel *= np.sign(rel[:, :1] + (rel[:, :1] == 0))
        omega = 2.0 * rel[:, 1:] / dt[:, None]          # ω_B ≈ 2 vec(Δq) / Δt
        for k, col in enumerate(BASE_ANGULAR_VELOCITY):
            if t.ok(col):
                _rate_consistency(t, col, _midpoints(t.values[col]), omega[:, k],
                                  "the trunk quaternion (body-frame rate)", True, tol)


def _check_contact(t: _Trial, labels: np.ndarray | None, facts: _RobotFacts | None,
                   speed: float | None, time_ok: bool, tol: FormatTolerances) -> None:
    """GRF sign and magnitude, intrusion unit and sign, direction of travel."""
    for col in INTRUSION_COLUMNS:
        if col in t.values:
            v = t.values[col]
            big = np.isfinite(v) & (np.abs(v) > tol.max_intrusion)
            if big.any():
                peak = float(np.max(np.abs(v[big])))
                t.add_rows(col, f"|{col}| above {tol.max_intrusion:g} m (longer than the leg)",
                           big, f"; largest {peak:.4g} — millimetres or centimetres instead of "
                           "metres?")
                t.flagged.add(col)
    duration = None
    if time_ok:
        time = t.values["time"]
        duration = float(time[-1] - time[0])
    if labels is not None:
        stance = np.isin(labels, ("left", "right"))
        if not stance.any():
            t.add("stance is 'none' in every row: the trial has no stance phase", "stance")
        elif stance.sum() >= 10:
            if t.ok("grf_z"):
                fz = t.values["grf_z"]
                weight = facts.weight if facts is not None else None
                med = float(np.median(fz[stance]))
                if med < 0 and (weight is None or med < -0.1 * weight):
                    t.add(f"grf_z is negative during stance (median {med:.4g} N): format v1 wants "
                          "the force OF the ground ON the foot, positive up", "grf_z")
                    t.flagged.add("grf_z")
                elif weight is not None and duration is not None \
                        and duration >= tol.min_travel_duration:
                    ratio = float(np.sum(fz[stance]) / (len(fz) * weight))
                    if not 1 / tol.weight_ratio <= ratio <= tol.weight_ratio:
                        hint = ""
                        for factor, unit in ((1 / 9.81, "kgf"), (1e3, "mN"), (1e-3, "kN")):
                            if ratio > 0 and abs(math.log(ratio / factor)) < math.log(1.5):
                                hint = f" — in {unit} instead of N?"
                        t.add(f"the mean vertical ground force over the trial is {ratio:.3g}× the "
                              f"robot's weight {weight:.4g} N (expected about 1){hint}", "grf_z")
                        t.flagged.add("grf_z")
            if t.ok("intrusion_z"):
                z = t.values["intrusion_z"][stance]
                if np.median(z) < 0 and np.percentile(z, 10) < -tol.intrusion_sign \
                        and np.percentile(z, 90) < tol.intrusion_sign:
                    t.add(f"intrusion_z is negative during most of stance (10th percentile "
                          f"{np.percentile(z, 10):.4g} m): format v1 counts z positive DEEPER "
                          "(sinkage) — sign flipped?", "intrusion_z")
                    t.flagged.add("intrusion_z")
    if speed is not None and abs(speed) >= 0.05 and duration is not None \
            and duration >= tol.min_travel_duration and t.ok("base_x", "base_y"):
        dx = float(t.values["base_x"][-1] - t.values["base_x"][0])
        dy = float(t.values["base_y"][-1] - t.values["base_y"][0])
        travel = math.hypot(dx, dy)
        if travel >= 0.25 * abs(speed) * duration:
            cos = dx * math.copysign(1.0, speed) / travel
            if cos < math.cos(math.radians(45)):
                t.add(f"the trunk travelled (Δx, Δy) = ({dx:.3g}, {dy:.3g}) m in {duration:.3g} s "
                      f"at a commanded speed of {speed:g} m/s: world x must be the walking "
                      "direction (docs/notation.md)", "base_x,base_y")


def _check_frame(df: pd.DataFrame, rows: np.ndarray, *, file: str, strict_types: bool,
                 facts: _RobotFacts | None, fs: float | None, speed: float | None,
                 tol: FormatTolerances, problems: list[DataProblem]) -> pd.DataFrame | None:
    """Run every check on one trial; return the normalised frame, or None if it has problems."""
    t = _Trial(file, df, np.asarray(rows, dtype=np.int64), strict_types)
    required = _check_header(t, facts)
    if len(df) < 2:
        t.add(f"has {len(df)} data row(s); a trial needs at least 2")
    present = [c for c in required if c in df.columns and c != "stance"]
    if len(df):
        for col in present:
            _numeric_values(t, col)
    labels = None
    if "stance" in df.columns and len(df):
        raw = df["stance"].astype(object).to_numpy()
        stance_problems = _stance_problems(raw, t.rows, file)
        t.problems += stance_problems
        if not stance_problems:
            labels = raw.astype(str)
    if len(df) >= 2:
        time_ok = _check_time(t, fs, tol)
        quat_ok = _check_orientation(t, tol)
        if facts is not None:
            _check_joints(t, facts, time_ok, tol)
        _check_base(t, time_ok, quat_ok, tol)
        _check_contact(t, labels, facts, speed, time_ok, tol)
    problems += t.problems
    if t.problems:
        return None
    out = df.copy()
    for col in present:
        if out[col].dtype != np.float64:
            out[col] = t.values[col]
    out["stance"] = out["stance"].astype(str)
    return out


# --------------------------------------------------------------------------------------
# Loading
# --------------------------------------------------------------------------------------


def _resolve_folder(path: str | Path) -> Path:
    p = Path(path).expanduser()
    if p.is_file() and p.name == META_FILE:
        return p.parent
    return p


def _load(path: str | Path, tol: FormatTolerances | None) -> tuple[Dataset | None, list[DataProblem], Path]:
    folder = _resolve_folder(path)
    tol = tol or FormatTolerances()
    problems: list[DataProblem] = []
    if not folder.is_dir():
        problems.append(DataProblem(str(folder), "data set folder not found"))
        return None, problems, folder
    meta_path = folder / META_FILE
    if not meta_path.is_file():
        problems.append(DataProblem(META_FILE, f"{META_FILE} is missing: a data set folder needs "
                                    "it (docs/data-format.md)"))
        return None, problems, folder
    try:
        raw = yaml.load(meta_path.read_text(encoding="utf-8"), Loader=_YAML_LOADER)
    except (OSError, UnicodeDecodeError) as exc:
        problems.append(DataProblem(META_FILE, f"cannot read: {exc}"))
        return None, problems, folder
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        problems.append(DataProblem(META_FILE, f"malformed YAML{where}: {problem}"))
        return None, problems, folder
    if not isinstance(raw, dict):
        problems.append(DataProblem(META_FILE, "top level must be a mapping of keys, got "
                                    f"{type(raw).__name__}"))
        return None, problems, folder
    view = _check_meta(raw, tol, problems)
    if view is None:
        return None, problems, folder
    facts = None
    if view.robot is not None:
        try:
            facts = _robot_facts(view.robot, folder)
        except GranularMpcError as exc:
            text = str(exc)
            text = text if text.startswith("robot") else f"robot: {text}"
            problems.append(DataProblem(META_FILE, f"{text}; joint columns not checked"))
    listed = {f.lower() for _, f, _ in view.trials}
    for p in sorted(folder.iterdir()):
        if p.is_file() and p.suffix.lower() in SUFFIXES.values() and p.name.lower() not in listed:
            problems.append(DataProblem(p.name, "trial file is not listed under trials in "
                                        f"{META_FILE} (list it, or move it out of the folder)"))
    frames: dict[str, pd.DataFrame] = {}
    for name, file, speed in view.trials:
        p = folder / file
        if not p.is_file():
            problems.append(DataProblem(file, f"trial file of trial {name!r} not found in "
                                        f"{folder}"))
            continue
        reader = _read_csv if p.suffix.lower() == ".csv" else _read_parquet
        df, rows, read_problems = reader(p, file)
        problems += read_problems
        if df is None:
            continue
        out = _check_frame(df, rows, file=file, strict_types=reader is _read_parquet,
                           facts=facts, fs=view.sample_rate_hz, speed=speed, tol=tol,
                           problems=problems)
        if out is not None and not read_problems:
            frames[name] = out
    if problems or view.meta is None or facts is None:
        return None, problems, folder
    return Dataset(path=folder.resolve(), meta=view.meta, trials=MappingProxyType(frames),
                   joint_names=facts.joints), problems, folder


def check_dataset(path: str | Path, *, tolerances: FormatTolerances | None = None) -> list[DataProblem]:
    """Every problem of the data set in folder ``path`` (empty list: it loads cleanly).

    Args:
        path: the data set folder (or its ``meta.yaml``).
        tolerances: thresholds of the checks (default :class:`FormatTolerances`).
    """
    return _load(path, tolerances)[1]


def load_dataset(path: str | Path, *, tolerances: FormatTolerances | None = None) -> Dataset:
    """Load and check a format-v1 data set.

    Args:
        path: the data set folder (or its ``meta.yaml``).
        tolerances: thresholds of the checks (default :class:`FormatTolerances`).

    Returns:
        The data set, every check passed.

    Raises:
        DataFormatError: listing every problem found (file, column, first row, message).
    """
    dataset, problems, folder = _load(path, tolerances)
    if problems or dataset is None:
        raise DataFormatError(problems, root=str(folder))
    return dataset


def check_trials(meta: DatasetMeta | Mapping[str, Any], trials: Mapping[str, pd.DataFrame], *,
                 tolerances: FormatTolerances | None = None) -> list[DataProblem]:
    """Every format-v1 problem of in-memory trials (before writing them).

    Numeric columns must have numeric dtypes here (as in Parquet). Problems name the
    trial file given in ``meta`` and 1-based data rows (row 1 = ``df.iloc[0]``).

    Args:
        meta: the data set's meta (validated with :class:`DatasetMeta`).
        trials: trial name → DataFrame; the names must be those of ``meta.trials``.
        tolerances: thresholds of the checks.

    Raises:
        ConfigError: ``meta`` is invalid.
        ConfigError, ModelError: the robot cannot be loaded.
    """
    meta = meta if isinstance(meta, DatasetMeta) else validate(DatasetMeta, dict(meta),
                                                               source="meta")
    tol = tolerances or FormatTolerances()
    facts = _robot_facts(meta.robot, None)
    problems: list[DataProblem] = []
    for name in trials:
        if name not in meta.trials:
            problems.append(DataProblem(str(name), "trial has data but no entry under trials "
                                        "in the meta"))
    for name, entry in meta.trials.items():
        if name not in trials:
            problems.append(DataProblem(entry.file, f"trial {name!r} is listed in the meta but "
                                        "has no data"))
            continue
        df = trials[name]
        if not isinstance(df, pd.DataFrame):
            problems.append(DataProblem(entry.file, f"trial {name!r} is a {type(df).__name__}, "
                                        "not a pandas DataFrame"))
            continue
        _check_frame(df, np.arange(1, len(df) + 1), file=entry.file, strict_types=True,
                     facts=facts, fs=meta.sample_rate_hz, speed=entry.commanded_speed_mps,
                     tol=tol, problems=problems)
    return problems


# --------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------


def write_dataset(path: str | Path, meta: DatasetMeta | Mapping[str, Any],
                  trials: Mapping[str, pd.DataFrame],
                  format: Literal["csv", "parquet"] = "csv", *, overwrite: bool = False,
                  check: bool = True, tolerances: FormatTolerances | None = None) -> Path:
    """Write a format-v1 data set: ``meta.yaml`` plus ``<trial>.csv`` or ``<trial>.parquet``.

    Trial files are named after their trials; the ``file`` entries of ``meta`` are set
    accordingly (so a CSV data set's meta can be written as Parquet). Columns are written
    in the DataFrame's order, without its index; CSV floats are written with enough
    digits to read back bit-for-bit. Each file is written to a temporary name and
    renamed; ``meta.yaml`` is written last, so an interrupted write never looks complete.
    The caller's objects are not modified.

    Args:
        path: the data set folder (created if needed).
        meta: the meta (``trials`` entries may omit ``file``).
        trials: trial name → DataFrame with the format-v1 columns (extra columns allowed).
        format: ``"csv"`` or ``"parquet"``.
        overwrite: replace ``meta.yaml`` and trial files already in the folder. Other
            ``*.csv`` / ``*.parquet`` files there are left alone (and the loader will
            report them as unlisted).
        check: run :func:`check_trials` first and refuse to write a data set that would
            not load. Turn off only to produce deliberately broken data (tests).
        tolerances: thresholds of the checks.

    Returns:
        The data set folder.

    Raises:
        ConfigError: invalid ``meta`` or ``format``.
        DataFormatError: ``check`` found problems (nothing was written).
        OutputError: the folder or a file cannot be written, or exists and not ``overwrite``.
    """
    if format not in SUFFIXES:
        raise ConfigError(f"unknown data set format {format!r}", key="format",
                          value=format, allowed="csv, parquet")
    suffix = SUFFIXES[format]
    data = meta.model_dump(mode="json") if isinstance(meta, DatasetMeta) else dict(meta)
    entries = data.get("trials")
    if isinstance(entries, Mapping):
        data["trials"] = {name: ({**dict(entry), "file": f"{name}{suffix}"}
                                 if isinstance(entry, Mapping) else entry)
                          for name, entry in entries.items()}
    meta_obj = validate(DatasetMeta, data, source="write_dataset meta")
    if check:
        problems = check_trials(meta_obj, trials, tolerances=tolerances)
        if problems:
            raise DataFormatError(problems, root=str(path))
    else:
        mismatch = ([DataProblem(f"{n}{suffix}", f"trial {n!r} is listed in the meta but has no "
                                 "data") for n in meta_obj.trials if n not in trials]
                    + [DataProblem(str(n), "trial has data but no entry under trials in the meta")
                       for n in trials if n not in meta_obj.trials])
        if mismatch:
            raise DataFormatError(mismatch, root=str(path))
    folder = Path(path).expanduser()
    targets = [folder / META_FILE] + [folder / e.file for e in meta_obj.trials.values()]
    existing = [p.name for p in targets if p.exists()]
    if existing and not overwrite:
        raise OutputError(f"{folder} already holds {', '.join(existing)} (pass overwrite=True "
                          "to replace)")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        for name, entry in meta_obj.trials.items():
            target = folder / entry.file
            tmp = folder / f".{entry.file}.tmp"
            df = trials[name]
            if format == "csv":
                df.to_csv(tmp, index=False, encoding="utf-8", lineterminator="\n")
            else:
                df.to_parquet(tmp, index=False)
            os.replace(tmp, target)
        tmp = folder / f".{META_FILE}.tmp"
        tmp.write_text(yaml.safe_dump(meta_obj.model_dump(mode="json", exclude_defaults=True),
                                      sort_keys=False, allow_unicode=True), encoding="utf-8")
        os.replace(tmp, folder / META_FILE)
    except OSError as exc:
        raise OutputError(f"cannot write the data set {folder}: {exc}") from None
    return folder


__all__ = [
    "SCHEMA_VERSION", "META_FILE", "STANCE_LABELS", "BASE_COLUMNS", "GRF_COLUMNS",
    "INTRUSION_COLUMNS", "TrialMeta", "GeneratorMeta", "DatasetMeta", "FormatTolerances",
    "Dataset", "StancePhase", "stance_phases", "format_columns", "joint_columns",
    "load_dataset", "check_dataset", "check_trials", "write_dataset",
]
