"""Reading config files: YAML → validated objects, ``--set key.path=value`` overrides, YAML out.

Robot files are found by name in ``models/`` (``models/<name>.yaml``), terrain files in
``models/terrain/`` (see :mod:`granular_mpc.paths`), or by path. A misspelt override key
is rejected with its dotted path and the closest valid key.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any, Mapping, get_args, get_origin

import yaml
from pydantic import BaseModel

from ..exceptions import ConfigError, ModelFileError
from ..paths import resolve_file
from .base import StrictModel
from .errors import validate
from .robot import RobotConfig
from .schema_walk import fields_of, strip_annotated
from .terrain import TerrainConfig
from .yaml_io import UniqueKeyLoader, load_yaml, parse_yaml  # noqa: F401 (re-exported)

# --------------------------------------------------------------------------------------
# YAML files
# --------------------------------------------------------------------------------------


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
    """Write a config object (or plain data) as YAML, keys in their order."""
    Path(path).write_text(yaml.safe_dump(to_plain(obj), sort_keys=False), encoding="utf-8")


# --------------------------------------------------------------------------------------
# Robot and terrain files
# --------------------------------------------------------------------------------------


def robot_dict(name_or_path: str, *, relative_to: Path | None = None, key: str = "robot") -> dict:
    """The robot file's mapping, not validated, with ``source_dir`` set to its folder."""
    path = resolve_file("robot", name_or_path, relative_to=relative_to, key=key)
    data = load_yaml(path)
    data.setdefault("source_dir", str(path.parent))
    return data


def terrain_dict(name_or_path: str, *, relative_to: Path | None = None, key: str = "terrain") -> dict:
    """The terrain file's mapping, not validated."""
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
            current = strip_annotated(get_args(current)[1])
            continue
        fields = fields_of(current)
        if fields is None:
            raise ConfigError("this key has no sub-keys", key=".".join(path[:i]))
        if part not in fields:
            close = difflib.get_close_matches(part, list(fields), n=1, cutoff=0.5)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise ConfigError(f"no such key '{part}'{hint}", key=".".join(path[: i + 1]),
                              allowed=", ".join(sorted(fields)))
        current = fields[part]


__all__ = ["load_yaml", "parse_yaml", "UniqueKeyLoader", "to_plain", "dump_yaml", "robot_dict",
           "terrain_dict", "load_robot",
           "load_terrain", "terrain_from_dict", "parse_override", "apply_override"]
