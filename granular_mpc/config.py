"""Typed configuration: YAML → validated, immutable config objects.

Every config object is a frozen pydantic model that rejects unknown keys. Errors are
turned into one :class:`~granular_mpc.exceptions.ConfigError` naming the dotted key path,
the offending value, what is allowed and — for misspelt keys — the closest valid key.

Scenario files (``sim/*.yaml``) refer to a robot file (``models/<robot>.yaml``) and a
terrain file (``models/terrain/<name>.yaml``) by name. :func:`load_scenario` resolves
those references into one plain dictionary (the *resolved config*, saved with every run),
applies ``--set key.path=value`` overrides, then validates it.
"""

from __future__ import annotations

import difflib
import math
import types
from pathlib import Path
from typing import Annotated, Any, Literal, Mapping, Sequence, Union, get_args, get_origin

import yaml
from pydantic import (BaseModel, ConfigDict, Field, ValidationError, field_validator,
                      model_validator)

from .exceptions import ConfigError, ModelFileError
from .paths import resolve_file

# --------------------------------------------------------------------------------------
# Base class and helpers
# --------------------------------------------------------------------------------------


class StrictModel(BaseModel):
    """Frozen config object; unknown keys are errors."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True,
                              arbitrary_types_allowed=False)


PositiveFloat = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]


def _fmt_loc(loc: Sequence[Any]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _model_fields_at(model: type[BaseModel], loc: Sequence[Any]) -> list[str]:
    """Field names of the (nested) model addressed by ``loc`` — for did-you-mean hints."""
    current: Any = model
    for part in loc:
        current = _unwrap(current, part)
        if current is None:
            return []
    if isinstance(current, type) and issubclass(current, BaseModel):
        return list(current.model_fields)
    return []


def _unwrap(tp: Any, part: Any) -> Any:
    """Follow one loc element through annotations, lists, dicts and unions."""
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        if isinstance(part, str) and part in tp.model_fields:
            return _strip(tp.model_fields[part].annotation)
        return None
    origin = get_origin(tp)
    if origin in (list, tuple, Sequence) and isinstance(part, int):
        args = get_args(tp)
        return _strip(args[0]) if args else None
    if origin in (dict, Mapping) and isinstance(part, str):
        args = get_args(tp)
        return _strip(args[1]) if len(args) == 2 else None
    if _is_union(origin):
        for arg in get_args(tp):
            arg = _strip(arg)
            if isinstance(arg, type) and issubclass(arg, BaseModel):
                kind = arg.model_fields.get("kind")
                if kind is not None and part in get_args(kind.annotation):
                    return arg
        for arg in get_args(tp):
            arg = _strip(arg)
            found = _unwrap(arg, part)
            if found is not None:
                return found
    return None


def _is_union(origin: Any) -> bool:
    """``typing.Union[...]`` or a PEP 604 ``X | Y``."""
    return origin is Union or origin is types.UnionType


def _strip(tp: Any) -> Any:
    if get_origin(tp) is Annotated:
        return get_args(tp)[0]
    return tp


def _is_tag(model: type[BaseModel], loc: Sequence[Any], i: int) -> bool:
    """True if loc[i] is a discriminated-union tag inserted by pydantic."""
    parent = model
    for part in loc[:i]:
        parent = _unwrap(parent, part)
        if parent is None:
            return False
    origin = get_origin(parent)
    if not _is_union(origin):
        return False
    # only discriminated unions (members with a ``kind`` tag) insert the tag in the loc
    return any(isinstance(_strip(a), type) and issubclass(_strip(a), BaseModel)
               and "kind" in _strip(a).model_fields for a in get_args(parent))


def validate(model: type[BaseModel], data: Any, *, source: str = "", prefix: str = ""):
    """Validate ``data`` against ``model``; raise one ConfigError listing every problem."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        messages = []
        first_key = ""
        first_value: Any = None
        allowed_first = ""
        for err in exc.errors():
            loc = list(err["loc"])
            # drop discriminator tags (e.g. 'granular') that pydantic inserts in the loc
            clean = [p for i, p in enumerate(loc) if not _is_tag(model, loc, i)]
            key = _fmt_loc(([prefix] if prefix else []) + clean)
            typ = err["type"]
            allowed = ""
            if typ == "extra_forbidden":
                valid = _model_fields_at(model, [p for p in loc[:-1]])
                close = difflib.get_close_matches(str(loc[-1]), valid, n=1, cutoff=0.5)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                msg = f"unknown key '{loc[-1]}'{hint}"
                allowed = ", ".join(valid)
            elif typ == "missing":
                msg = "required key is missing"
            elif typ == "union_tag_invalid":
                ctx = err.get("ctx", {})
                msg = f"unknown kind {ctx.get('tag')!r}"
                allowed = str(ctx.get("expected_tags", ""))
            else:
                msg = f"{err['msg']} (got {err.get('input')!r})"
            if not first_key:
                first_key, first_value, allowed_first = key, err.get("input"), allowed
            line = f"{key}: {msg}" if key else msg
            if allowed and typ != "extra_forbidden":
                line += f" (allowed: {allowed})"
            elif allowed:
                line += f" (valid keys here: {allowed})"
            messages.append(line)
        text = messages[0] if len(messages) == 1 else (
            f"{len(messages)} problems:\n  - " + "\n  - ".join(messages))
        # the allowed values are already in the text: keep them as data only
        err = ConfigError(text, value=first_value, source=source)
        err.allowed = allowed_first
        err.key = first_key
        raise err from None


def load_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping; a missing or malformed file raises one clear error."""
    p = Path(path)
    if not p.is_file():
        raise ModelFileError(f"file not found: {p}", value=str(p))
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ModelFileError(f"cannot read {p}: {exc.strerror}", value=str(p)) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"malformed YAML{where}: {problem}", source=str(p)) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"top level must be a mapping, got {type(data).__name__}",
                          source=str(p))
    return data


# --------------------------------------------------------------------------------------
# Effects (optional physical terms, see terrain/effects.py)
# --------------------------------------------------------------------------------------


class EffectSpec(StrictModel):
    """One optional physical effect, by registered name, with parameter values.

    Accepts the compact string form ``"name:param=value,param=value"`` too.
    """

    name: str
    params: dict[str, float] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _from_string(cls, value: Any) -> Any:
        if isinstance(value, str):
            return parse_effect_string(value)
        return value


def parse_effect_string(text: str) -> dict[str, Any]:
    """``"inertial_drag:c_d=1.2"`` → ``{"name": "inertial_drag", "params": {"c_d": 1.2}}``."""
    name, _, rest = text.partition(":")
    params: dict[str, float] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, val = item.partition("=")
        if not eq:
            raise ConfigError(f"effect parameter {item!r} must look like name=value",
                              key="effect", value=text)
        try:
            params[key.strip()] = float(val)
        except ValueError:
            raise ConfigError(f"effect parameter {key.strip()!r} must be a number, got {val!r}",
                              key="effect", value=text) from None
    return {"name": name.strip(), "params": params}


# --------------------------------------------------------------------------------------
# Terrain
# --------------------------------------------------------------------------------------


class RFTCoefficients(StrictModel):
    """Li et al. (2013) discrete-Fourier coefficients of the RFT stresses, generic set [N/cm³].

    α_z = A00 + A10 cos2β + B11 sin(2β+γ) + B01 sinγ + Bm11 sin(γ−2β)
    α_x = C11 cos(2β+γ) + C01 cosγ + Cm11 cos(γ−2β) + D10 sin2β
    """

    A00: FiniteFloat = 0.206
    A10: FiniteFloat = 0.169
    B11: FiniteFloat = 0.212
    B01: FiniteFloat = 0.358
    Bm11: FiniteFloat = 0.055
    C11: FiniteFloat = -0.124
    C01: FiniteFloat = 0.253
    Cm11: FiniteFloat = 0.007
    D10: FiniteFloat = 0.088


class _TerrainBase(StrictModel):
    name: str = Field("terrain", description="Human-readable name of the medium.")
    description: str = ""
    source: str = Field("", description="Where the parameter values come from.")
    surface_height: FiniteFloat = Field(0.0, description="Height of the free surface z [m], world frame.")
    surface_slope: list[Annotated[float, Field(ge=-0.5, le=0.5)]] = Field(
        [0.0, 0.0], min_length=2, max_length=2,
        description="Surface slope dz/dx, dz/dy [-]: the surface is z = h + s_x x + s_y y.")
    effects: list[EffectSpec] = Field(default_factory=list)


class GranularTerrainConfig(_TerrainBase):
    """A granular layer (RFT closed form, solidified wedge, bulldozing) over rigid ground."""

    kind: Literal["granular"] = "granular"
    zeta: PositiveFloat = Field(1.36, description="RFT scaling ζ of the generic coefficients [-].")
    phi_s_deg: float = Field(38.0, gt=0.0, lt=90.0, allow_inf_nan=False,
                             description="Solidified-zone (granular friction) angle φ_s [deg], in (0, 90).")
    density: PositiveFloat = Field(1660.0, description="Bulk density ρ [kg/m³].")
    layer_depth: PositiveFloat = Field(0.12, description="Thickness of the layer over rigid ground [m].")
    bulldozing_length: PositiveFloat = Field(0.01, description="Bulldozing saturation length λ [m] (calibrated).")
    sole_shear_alpha: NonNegFloat = Field(0.136, description="Generic in-plane shear stress per depth of the sole [N/cm³] (α_x(0,0)).")
    added_mass_scale: NonNegFloat = Field(1.0, description="Scale of the solidified-zone added mass [-].")
    contact_stiffness: PositiveFloat = Field(2.0e5, description="Elastic regularisation stiffness per contact patch [N/m].")
    contact_damping: NonNegFloat = Field(100.0, description="Elastic-regime damping per patch [N·s/m].")
    bottom_friction: PositiveFloat = Field(0.8, description="Coulomb friction of the rigid floor under the layer [-].")
    direction_time_constant: PositiveFloat = Field(0.01, description="Blends elastic displacement into the flow direction at low speed [s].")
    rft: RFTCoefficients = Field(default_factory=RFTCoefficients)


class RigidTerrainConfig(_TerrainBase):
    """Rigid, non-sinking ground: stiff unilateral contact with Coulomb friction."""

    kind: Literal["rigid"] = "rigid"
    friction: PositiveFloat = Field(0.8, description="Coulomb friction coefficient μ [-].")
    contact_stiffness: PositiveFloat = Field(1.0e5, description="Normal and tangential stiffness per patch [N/m].")
    contact_damping: NonNegFloat = Field(100.0, description="Normal and tangential damping per patch [N·s/m].")


TerrainConfig = Annotated[Union[GranularTerrainConfig, RigidTerrainConfig],
                          Field(discriminator="kind")]


# --------------------------------------------------------------------------------------
# Robot
# --------------------------------------------------------------------------------------


class FootGeometry(StrictModel):
    """Semi-cylindrical rigid sole: a circular arc in the foot's x–z plane, extruded along y."""

    chord: PositiveFloat = Field(0.075, description="Chord of the sole arc along x [m].")
    height: PositiveFloat = Field(0.024, description="Arc height (sagitta) [m].")
    width: PositiveFloat = Field(0.063, description="Width W along y [m].")
    slices: int = Field(2, ge=1, le=8, description="Contact patches across the width (roll/yaw moments).")

    @model_validator(mode="after")
    def _check(self) -> "FootGeometry":
        if self.height > self.chord / 2:
            raise ValueError("foot.height must not exceed chord/2 (arc at most a half circle)")
        return self

    @property
    def radius(self) -> float:
        """Arc radius R = (c²/4 + h²) / (2h) [m]."""
        return (self.chord ** 2 / 4.0 + self.height ** 2) / (2.0 * self.height)

    @property
    def half_angle(self) -> float:
        """Half-angle ψ_max of the arc about the foot's −z axis [rad]."""
        return math.asin(self.chord / (2.0 * self.radius))


class FootConfig(StrictModel):
    frame: str = Field(description="URDF frame at the centre of the sole arc; x forward, z up.")


class RobotConfig(StrictModel):
    """A biped description: URDF plus what the URDF cannot say."""

    name: str
    urdf: str = Field(description="URDF path, relative to the robot YAML file.")
    joints: list[str] = Field(min_length=6, max_length=6,
                              description="Actuated joints: left hip abd., hip pitch, knee, then right.")
    feet: dict[Literal["left", "right"], FootConfig]
    foot: FootGeometry = Field(default_factory=FootGeometry)
    standing_joints: list[FiniteFloat] = Field(min_length=6, max_length=6,
                                                description="Nominal standing joint angles [rad].")
    joint_damping: NonNegFloat = Field(0.0, description="Viscous joint damping [N·m·s/rad].")
    source_dir: str = Field("", description="Folder of the robot file (filled in by the loader).")

    @property
    def urdf_path(self) -> Path:
        p = Path(self.urdf)
        return p if p.is_absolute() else Path(self.source_dir) / p


# --------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------


class SimConfig(StrictModel):
    dt: float = Field(5.0e-4, gt=0.0, le=0.01, description="Plant integration step [s].")
    integrator: Literal["verlet", "semi_implicit_euler"] = "verlet"
    duration: PositiveFloat = Field(2.0, description="Simulated time [s].")
    seed: int = 0
    max_speed: PositiveFloat = Field(200.0, description="Divergence bound on |v| [m/s, rad/s].")


class DropConfig(StrictModel):
    """Drop test: joints held at the standing pose by stiff PD, released above the surface."""

    height: NonNegFloat = Field(0.02, description="Clearance of the lowest sole point above the surface [m].")
    kp: PositiveFloat = Field(150.0, description="Joint PD stiffness [N·m/rad].")
    kd: NonNegFloat = Field(3.0, description="Joint PD damping [N·m·s/rad].")


# --------------------------------------------------------------------------------------
# Loading robot / terrain files
# --------------------------------------------------------------------------------------


def robot_dict(name_or_path: str, *, relative_to: Path | None = None, key: str = "robot") -> dict:
    path = resolve_file("robot", name_or_path, relative_to=relative_to, key=key)
    data = load_yaml(path)
    data.setdefault("source_dir", str(path.parent))
    return data


def terrain_dict(name_or_path: str, *, relative_to: Path | None = None, key: str = "terrain") -> dict:
    path = resolve_file("terrain", name_or_path, relative_to=relative_to, key=key)
    return load_yaml(path)


def load_robot(name_or_path: str = "yobogo10s") -> RobotConfig:
    """Load and validate a robot file by name (``models/<name>.yaml``) or path."""
    path = resolve_file("robot", name_or_path, key="robot")
    data = load_yaml(path)
    data.setdefault("source_dir", str(path.parent))
    return validate(RobotConfig, data, source=str(path))


def load_terrain(name_or_path: str = "dry_sand", **overrides: Any):
    """Load and validate a terrain file by name (``models/terrain/<name>.yaml``) or path."""
    path = resolve_file("terrain", name_or_path, key="terrain")
    data = load_yaml(path)
    data.update(overrides)
    return validate(_TerrainAdapter, {"terrain": data}, source=str(path)).terrain


class _TerrainAdapter(StrictModel):
    terrain: TerrainConfig


def terrain_from_dict(data: Mapping[str, Any], *, source: str = ""):
    """Validate an in-memory terrain mapping (e.g. built in user code)."""
    return validate(_TerrainAdapter, {"terrain": dict(data)}, source=source).terrain


# --------------------------------------------------------------------------------------
# Overrides: --set key.path=value
# --------------------------------------------------------------------------------------


def parse_override(text: str) -> tuple[list[str], Any]:
    """``"terrain.zeta=1.5"`` → (["terrain", "zeta"], 1.5). Values are parsed as YAML."""
    key, eq, raw = text.partition("=")
    if not eq or not key.strip():
        raise ConfigError(f"override {text!r} must look like key.path=value", key="--set")
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError:
        value = raw
    return [k for k in key.strip().split(".")], value


def apply_override(data: dict, path: list[str], value: Any, *, schema: type[BaseModel] | None = None) -> None:
    """Set ``data[path] = value`` in place; the key must exist in ``schema`` (if given)."""
    if schema is not None:
        _check_path_in_schema(schema, path)
    node = data
    for i, part in enumerate(path[:-1]):
        nxt = node.get(part) if isinstance(node, dict) else None
        if nxt is None:
            nxt = {}
            node[part] = nxt
        elif not isinstance(nxt, dict):
            raise ConfigError(f"cannot set a sub-key of a {type(nxt).__name__}",
                              key=".".join(path[: i + 1]))
        node = nxt
    node[path[-1]] = value


def _check_path_in_schema(schema: type[BaseModel], path: list[str]) -> None:
    current: Any = schema
    for i, part in enumerate(path):
        # dict-valued fields accept any key
        if get_origin(current) in (dict, Mapping):
            current = _strip(get_args(current)[1])
            continue
        fields = _fields_of(current)
        if fields is None:
            raise ConfigError("this key has no sub-keys", key=".".join(path[:i]))
        if part not in fields:
            close = difflib.get_close_matches(part, list(fields), n=1, cutoff=0.5)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise ConfigError(f"no such key '{part}'{hint}", key=".".join(path[: i + 1]),
                              allowed=", ".join(sorted(fields)))
        current = fields[part]


def _fields_of(tp: Any) -> dict[str, Any] | None:
    tp = _strip(tp)
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return {k: _strip(f.annotation) for k, f in tp.model_fields.items()}
    origin = get_origin(tp)
    if _is_union(origin):
        merged: dict[str, Any] = {}
        for arg in get_args(tp):
            sub = _fields_of(arg)
            if sub:
                for k, v in sub.items():
                    merged.setdefault(k, v)
        return merged or None
    return None


def to_plain(obj: Any) -> Any:
    """A config object as plain YAML-friendly data (for config.resolved.yaml)."""
    if isinstance(obj, BaseModel):
        return to_plain(obj.model_dump(mode="json"))
    if isinstance(obj, dict):
        return {k: to_plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v) for v in obj]
    return obj


def dump_yaml(obj: Any, path: str | Path) -> None:
    Path(path).write_text(yaml.safe_dump(to_plain(obj), sort_keys=False), encoding="utf-8")


# --------------------------------------------------------------------------------------
# Controller
# --------------------------------------------------------------------------------------


class GaitConfig(StrictModel):
    """Periodic gait: each leg swings for ``swing_fraction`` of the period."""

    period: float = Field(0.4, gt=0.05, le=5.0, description="Gait cycle period T [s].")
    swing_fraction: float = Field(0.5, gt=0.0, le=0.5,
                                  description="Swing share of the cycle per leg; 0.5 = no double support.")
    weight_shift: NonNegFloat = Field(0.5, le=5.0, description="Initial double support shifting the CoM toward the first stance foot [s].")
    load_transfer: Union[Literal["auto"], NonNegFloat] = Field("auto", description="Double support at each touchdown [s]; 'auto': the time a foot needs to sink to the depth that bears the robot's weight at mpc.max_sink_rate (0 on rigid ground).")

    @property
    def double_support(self) -> bool:
        return self.swing_fraction < 0.5 - 1e-9


class SwingConfig(StrictModel):
    height: PositiveFloat = Field(0.10, description="Cycloid apex above the lift-off/touchdown line [m].")
    touchdown_depth: NonNegFloat = Field(0.0, description="Extra target depth below the surface at touchdown [m] (on top of the expected sinkage).")
    kp: PositiveFloat = Field(400.0, description="Swing-foot task stiffness [1/s²].")
    kd: NonNegFloat = Field(40.0, description="Swing-foot task damping [1/s].")


class FootholdConfig(StrictModel):
    """Capture-point (DCM) foothold with a speed-proportional offset, see control/gait.py."""

    step_width: PositiveFloat = Field(0.12, description="Nominal lateral distance between footholds [m] (hips are 0.19 m apart: a narrower stance shortens the yaw lever of the fore-aft ground force, see docs/controller.md).")
    lateral_margin: float = Field(0.6, gt=0.0, le=1.0, description="Step width is narrowed so the gait's lateral force stays within this share of the ground's lateral capacity [-].")
    k_velocity: float = Field(0.0, ge=-0.9, le=2.0, description="Extra scale of the speed offset [-].")
    k_position: NonNegFloat = Field(0.5, description="Walking-line correction: foothold shift per metre off the line per second of stance [1/s].")
    k_speed_integral: NonNegFloat = Field(0.5, description="Integral gain on the forward speed error (after the speed ramp) added to the speed used for footholds [1/s].")
    max_speed_correction: NonNegFloat = Field(0.3, description="Bound on that integral correction [m/s].")
    max_step: PositiveFloat = Field(0.25, description="Largest foothold offset from the capture point, each axis [m].")


class MPCConfig(StrictModel):
    horizon: int = Field(10, ge=2, le=40, description="Number of MPC steps.")
    dt: float = Field(0.04, gt=0.0, le=0.2, description="MPC step [s]; horizon·dt ≥ one gait cycle.")
    rate_hz: float = Field(40.0, gt=0.0, le=1000.0, description="How often the MPC is solved [Hz].")
    weights_orientation: list[NonNegFloat] = Field([30.0, 30.0, 10.0], min_length=3, max_length=3)
    weights_position: list[NonNegFloat] = Field([2.0, 20.0, 200.0], min_length=3, max_length=3)
    weights_angular_velocity: list[NonNegFloat] = Field([1.0, 1.0, 1.0], min_length=3, max_length=3)
    weights_velocity: list[NonNegFloat] = Field([20.0, 5.0, 10.0], min_length=3, max_length=3)
    weight_force: NonNegFloat = Field(1e-5, description="Force regularisation [1/N²].")
    weight_sinkage: NonNegFloat = Field(0.0, description="Penalty on predicted sinkage [1/m²].")
    max_sinkage: PositiveFloat = Field(0.04, description="Sinkage allowed by the force constraints [m].")
    max_sink_rate: PositiveFloat = Field(0.6, description="Fastest planned sinkage of a loading foot [m/s]: the normal force may only grow as fast as the foot sinks into capacity.")
    friction: PositiveFloat = Field(0.6, description="Friction coefficient of the rigid-ground model [-].")
    max_normal_force: PositiveFloat = Field(300.0, description="Upper bound on the normal force per foot [N].")
    com_height: PositiveFloat = Field(0.41, description="Desired CoM height above the undisturbed surface [m].")


class WBCConfig(StrictModel):
    """Whole-body QP weights and task gains (see control/wbc.py)."""

    rate_hz: float = Field(500.0, gt=0.0, le=5000.0, description="WBC rate [Hz] (torques held between ticks).")
    w_orientation: list[NonNegFloat] = Field([10.0, 10.0, 5.0], min_length=3, max_length=3,
                                             description="Trunk roll, pitch, yaw task weights. Yaw is weak: without a hip-yaw joint the trunk's yaw is the stance foot's, which only rotational slip can change.")
    w_com: NonNegFloat = 20.0
    w_swing: NonNegFloat = 100.0
    w_contact: NonNegFloat = 1000.0
    w_force: NonNegFloat = Field(10.0, description="Weight on tracking the MPC forces [1/N²].")
    w_regularisation: NonNegFloat = 1e-4
    kp_orientation: NonNegFloat = 300.0
    kd_orientation: NonNegFloat = 30.0
    kp_com: NonNegFloat = 100.0
    kd_com: NonNegFloat = 20.0


class ControllerConfig(StrictModel):
    terrain: str = Field("plant", description="Terrain model inside the controller: 'plant' (same as the plant) or a terrain file name.")
    gait: GaitConfig = Field(default_factory=GaitConfig)
    swing: SwingConfig = Field(default_factory=SwingConfig)
    foothold: FootholdConfig = Field(default_factory=FootholdConfig)
    mpc: MPCConfig = Field(default_factory=MPCConfig)
    wbc: WBCConfig = Field(default_factory=WBCConfig)


class CommandConfig(StrictModel):
    speed: float = Field(0.2, ge=-1.0, le=1.5, description="Commanded forward speed [m/s].")
    lateral_speed: float = Field(0.0, ge=-0.5, le=0.5, description="Commanded lateral speed [m/s].")
    max_acceleration: PositiveFloat = Field(0.5, description="Ramp acceleration limit [m/s²] (Ruckig).")
    max_jerk: PositiveFloat = Field(2.0, description="Ramp jerk limit [m/s³] (Ruckig).")
    start_delay: NonNegFloat = Field(0.8, description="Time before the speed ramp starts (weight shift, then stepping in place) [s].")


# --------------------------------------------------------------------------------------
# Scenarios (sim/*.yaml): what `granular-mpc run` and `granular-mpc sweep` read.
# Loading (names → inlined files, --set overrides): granular_mpc/scenario.py.
# --------------------------------------------------------------------------------------

from typing import Optional  # noqa: E402  (typing.Union, not PEP 604: see _fields_of)

Vector3 = Annotated[list[FiniteFloat], Field(min_length=3, max_length=3)]


class FallConfig(StrictModel):
    """When the closed loop counts as fallen (checked at every controller tick)."""

    enabled: bool = Field(True, description="Detect falls at all.")
    min_trunk_height: PositiveFloat = Field(0.25, description="Fallen when the trunk origin is less than this above the free surface [m] (standing: ≈ 0.47 m).")
    max_roll_deg: float = Field(15.0, gt=0.0, le=180.0, description="Fallen when |trunk roll| exceeds this [deg] (Z-Y-X Euler angles).")
    max_pitch_deg: float = Field(15.0, gt=0.0, le=90.0, description="Fallen when |trunk pitch| exceeds this [deg].")
    stop: bool = Field(True, description="End the run at the fall (else record it and go on).")


class PushConfig(StrictModel):
    """A push on the trunk: a constant world-frame force (and torque) held for ``duration``.

    Give ``force`` [N] or ``impulse`` [N·s] (then force = impulse / duration). ``at: time``
    starts the push at ``time``; ``at: mid_stance`` at the first planned mid-stance (of
    ``side``, or of either foot) at or after ``time``.
    """

    at: Literal["time", "mid_stance"] = "time"
    time: NonNegFloat = Field(description="Start [s] ('time'), or earliest start ('mid_stance').")
    side: Literal["left", "right", "any"] = Field("any", description="Stance foot whose mid-stance starts the push ('mid_stance' only).")
    force: Optional[Vector3] = Field(None, description="Force on the trunk [N], world frame.")
    impulse: Optional[Vector3] = Field(None, description="Impulse on the trunk [N·s], world frame.")
    torque: Vector3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="Torque on the trunk [N·m], world frame.")
    duration: PositiveFloat = Field(0.1, description="How long the push lasts [s].")

    @model_validator(mode="after")
    def _one_of(self) -> "PushConfig":
        if (self.force is None) == (self.impulse is None):
            raise ValueError("give exactly one of 'force' [N] and 'impulse' [N·s]")
        return self

    @property
    def force_W(self) -> list[float]:
        """The force held during the push [N], world frame."""
        if self.force is not None:
            return list(self.force)
        return [i / self.duration for i in self.impulse]


class GuideRigConfig(StrictModel):
    """Drop tests: a vertical guide rail on the trunk (springs and dampers on trunk x, y
    and orientation; vertical motion free), as in a drop-tower experiment."""

    stiffness: PositiveFloat = Field(1.0e5, description="Horizontal spring [N/m].")
    damping: NonNegFloat = Field(1500.0, description="Horizontal damper [N·s/m].")
    rot_stiffness: PositiveFloat = Field(800.0, description="Orientation spring [N·m/rad].")
    rot_damping: NonNegFloat = Field(30.0, description="Orientation damper [N·m·s/rad].")


class MetricsConfig(StrictModel):
    """The window over which summary averages are taken (docs/user-guide.md, summary.json)."""

    settle: NonNegFloat = Field(1.0, description="Time after the end of the speed ramp before averaging starts [s].")


class OutputConfig(StrictModel):
    log_rate_hz: Optional[PositiveFloat] = Field(None, description="Log rows per simulated second [Hz]; default: the WBC rate.")
    flush_every: int = Field(500, ge=1, description="Rows per log part written to disk.")
    plots: bool = Field(True, description="Write DIR/plots/*.png after the run.")
    html_fps: PositiveFloat = Field(30.0, description="Frame rate of DIR/animation.html [1/s].")


class SweepConfig(StrictModel):
    """Runs of one scenario over speeds × terrains (× controller terrains × grid × seeds)."""

    speeds: list[FiniteFloat] = Field(min_length=1, description="Commanded speeds [m/s].")
    terrains: list[str] = Field(min_length=1, description="Plant terrain names (models/terrain/).")
    controller_terrains: list[str] = Field(default_factory=lambda: ["plant"], min_length=1,
                                           description="Controller terrain models ('plant' or terrain names).")
    grid: dict[str, list[Any]] = Field(default_factory=dict, description="Dotted scenario key → values; every combination is run.")
    duration: Optional[PositiveFloat] = Field(None, description="sim.duration of every run [s] (default: the scenario's).")
    seeds: list[int] = Field(default_factory=list, description="sim.seed values (default: the scenario's).")
    plots: bool = Field(False, description="Write each run's plots (slower).")

    @field_validator("grid", mode="before")
    @classmethod
    def _flatten(cls, value: Any) -> Any:
        """``{controller: {mpc: {horizon: [8, 10]}}}`` → ``{"controller.mpc.horizon": [8, 10]}``."""
        if not isinstance(value, Mapping):
            return value
        out: dict[str, Any] = {}

        def walk(prefix: str, node: Any) -> None:
            if isinstance(node, Mapping) and (node or not prefix):
                for k, v in node.items():
                    walk(f"{prefix}.{k}" if prefix else str(k), v)
            else:
                out[prefix] = node
        walk("", value)
        return out


class ScenarioConfig(StrictModel):
    """One closed-loop scenario: robot, plant terrain, controller, command and run options.

    ``robot`` and ``terrain`` are the loaded robot and terrain files (scenario YAML names
    them; :func:`granular_mpc.scenario.load_scenario` inlines them). ``controller_terrain``
    is the loaded file named by ``controller.terrain`` (``None`` when that is ``plant``).
    """

    name: str = Field("scenario", description="Scenario name (default output folder runs/<name>-<time>).")
    description: str = ""
    mode: Literal["walk", "drop"] = Field("walk", description="'walk': closed-loop walking; 'drop': drop test on a guide rig.")
    robot: RobotConfig
    terrain: TerrainConfig
    controller_terrain: Optional[Annotated[Union[GranularTerrainConfig, RigidTerrainConfig],
                                           Field(discriminator="kind")]] = None
    sim: SimConfig = Field(default_factory=SimConfig)
    controller: ControllerConfig = Field(default_factory=ControllerConfig)
    command: CommandConfig = Field(default_factory=CommandConfig)
    initial_clearance: Optional[float] = Field(None, ge=-0.05, le=0.5, description="Lowest sole point above the free surface at t = 0 [m] (walk); default 0 on rigid ground, −0.005 on sand.")
    drop: DropConfig = Field(default_factory=DropConfig)
    rig: GuideRigConfig = Field(default_factory=GuideRigConfig)
    fall: FallConfig = Field(default_factory=FallConfig)
    pushes: list[PushConfig] = Field(default_factory=list)
    metrics: MetricsConfig = Field(default_factory=MetricsConfig)
    output: OutputConfig = Field(default_factory=OutputConfig)
    sweep: Optional[SweepConfig] = None

    @model_validator(mode="after")
    def _consistent(self) -> "ScenarioConfig":
        if self.controller.terrain == "plant" and self.controller_terrain is not None:
            raise ValueError("controller_terrain is given but controller.terrain is 'plant'; "
                             "set controller.terrain to a terrain name, or drop controller_terrain")
        if self.mode == "drop" and self.pushes:
            raise ValueError("pushes are not supported in mode 'drop' (the guide rig holds the trunk)")
        if self.output.log_rate_hz is not None and self.output.log_rate_hz * self.sim.dt > 1.0 + 1e-9:
            raise ValueError(f"output.log_rate_hz = {self.output.log_rate_hz:g} exceeds the plant "
                             f"rate 1/sim.dt = {1.0 / self.sim.dt:g} Hz")
        return self

    @property
    def log_rate_hz(self) -> float:
        """Log rows per simulated second [Hz]."""
        return self.output.log_rate_hz or self.controller.wbc.rate_hz

    @property
    def start_clearance(self) -> float:
        """Clearance of the lowest sole point above the surface at t = 0 [m]."""
        if self.mode == "drop":
            return self.drop.height
        if self.initial_clearance is not None:
            return self.initial_clearance
        return 0.0 if self.terrain.kind == "rigid" else -0.005
