"""Scenario files: YAML → resolved, validated :class:`~granular_mpc.config.ScenarioConfig`.

Pipeline (:func:`load_scenario`), in this order:

1. read the scenario YAML (``sim/<name>.yaml`` or any path);
2. apply the **file swaps** among the overrides: ``robot=NAME``, ``terrain=NAME`` and
   ``controller.terrain=NAME`` replace a file reference before anything is loaded;
3. **inline** the files: ``robot`` and ``terrain`` names (or paths, or a mapping with
   ``file: NAME`` plus keys to change) become the loaded mappings (which keep their
   ``name``); a ``controller.terrain`` other than ``plant`` loads that terrain file into
   ``controller_terrain``;
4. apply the other ``--set key.path=value`` overrides, each checked against the schema
   (an unknown key is rejected with its dotted path and a did-you-mean hint);
5. validate everything at once (:func:`granular_mpc.config.validate`).

The result is the *resolved* config: :func:`resolved_dict` writes it as
``config.resolved.yaml``, which loads back (with :func:`load_scenario`) to an equal
:class:`ScenarioConfig` — a run can be repeated from its own folder.

Sweeps (:func:`expand_sweep`) run the same pipeline once per combination of the
``sweep:`` section, with the combination given as overrides.
"""

from __future__ import annotations

import copy
import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping

from .config import (ScenarioConfig, SweepConfig, apply_override, load_yaml, parse_override, robot_dict,
                     terrain_dict, to_plain, validate)
from .exceptions import ConfigError, ModelFileError
from .paths import resolve_file, sim_dir

#: Override paths that name a file (swapped before the files are loaded).
FILE_KEYS = (("robot",), ("terrain",), ("controller", "terrain"))


def find_scenario(name_or_path: str | Path) -> Path:
    """Path of a scenario file: a path (with or without ``.yaml``), else a shipped
    scenario of that name (``sim/<name>.yaml``)."""
    try:
        return resolve_file("scenario", str(name_or_path), key="scenario")
    except ModelFileError:
        shipped = sim_dir()
        if shipped is not None:
            for cand in (shipped / str(name_or_path), shipped / f"{name_or_path}.yaml"):
                if cand.is_file():
                    return cand.resolve()
        names = sorted(p.stem for p in shipped.glob("*.yaml")) if shipped else []
        raise ModelFileError(f"scenario file {str(name_or_path)!r} not found",
                             value=str(name_or_path),
                             allowed=("a path to a YAML file, or one of: " + ", ".join(names))
                             if names else "a path to a YAML file") from None


def _parse(overrides: Iterable[Any]) -> list[tuple[list[str], Any]]:
    out = []
    for item in overrides:
        if isinstance(item, str):
            path, value = parse_override(item)
        else:
            path, value = item
            path = path.split(".") if isinstance(path, str) else list(path)
        if not path or any(not p for p in path):
            raise ConfigError(f"override key {'.'.join(path)!r} has an empty part", key="--set")
        out.append((list(path), value))
    return out


def _load_file(kind: str, ref: Any, *, base_dir: Path | None, key: str) -> Any:
    """A robot/terrain reference (name, path, or mapping with ``file:``) → mapping."""
    loader = robot_dict if kind == "robot" else terrain_dict
    if isinstance(ref, str):
        return loader(ref, relative_to=base_dir, key=key)
    if isinstance(ref, Mapping) and "file" in ref:
        if not isinstance(ref["file"], str):
            raise ConfigError("must be a file name", key=f"{key}.file", value=ref["file"])
        data = loader(ref["file"], relative_to=base_dir, key=f"{key}.file")
        _deep_update(data, {k: v for k, v in ref.items() if k != "file"})
        return data
    if isinstance(ref, Mapping):
        data = dict(ref)
        if kind == "robot" and base_dir is not None:
            data.setdefault("source_dir", str(base_dir))
        return data
    if ref is None:
        return None  # reported as missing by the validation
    raise ConfigError(f"must be a {kind} name, a path or a mapping, got {type(ref).__name__}",
                      key=key, value=ref)


def _deep_update(base: dict, extra: Mapping) -> None:
    for k, v in extra.items():
        if isinstance(v, Mapping) and isinstance(base.get(k), dict):
            _deep_update(base[k], v)
        else:
            base[k] = copy.deepcopy(v)


def resolve_scenario_dict(data: Mapping[str, Any], overrides: Iterable[Any] = (), *,
                          base_dir: Path | None = None) -> dict[str, Any]:
    """Steps 2–4 of the pipeline on a raw scenario mapping; returns a new plain dict.

    Args:
        data: the scenario mapping as read from YAML (not modified).
        overrides: ``"key.path=value"`` strings or ``(path, value)`` pairs, in order.
        base_dir: folder that relative robot/terrain paths are resolved against.

    Raises:
        ConfigError: an override of a key that does not exist, a file that cannot be found.
    """
    out = copy.deepcopy(dict(data))
    parsed = _parse(overrides)
    swaps = [(p, v) for p, v in parsed if tuple(p) in FILE_KEYS]
    others = [(p, v) for p, v in parsed if tuple(p) not in FILE_KEYS]
    for path, value in swaps:
        if not isinstance(value, (str, Mapping)):
            raise ConfigError("must be a file name or a mapping", key=".".join(path), value=value)
        if path == ["controller", "terrain"]:
            if not isinstance(value, str):
                raise ConfigError("must be 'plant' or a terrain file name", key="controller.terrain",
                                  value=value)
            out.pop("controller_terrain", None)   # re-resolved below
        apply_override(out, path, value)
    if "robot" in out:
        out["robot"] = _load_file("robot", out["robot"], base_dir=base_dir, key="robot")
    if "terrain" in out:
        out["terrain"] = _load_file("terrain", out["terrain"], base_dir=base_dir, key="terrain")
    ctrl = out.get("controller")
    ct = ctrl.get("terrain", "plant") if isinstance(ctrl, Mapping) else "plant"
    if isinstance(ct, str) and ct != "plant" and out.get("controller_terrain") is None:
        out["controller_terrain"] = _load_file("terrain", ct, base_dir=base_dir,
                                               key="controller.terrain")
    for path, value in others:
        if path[0] == "controller_terrain" and out.get("controller_terrain") is None:
            raise ConfigError("the controller uses the plant's terrain (controller.terrain: "
                              "plant); set controller.terrain=NAME to give it its own",
                              key=".".join(path))
        apply_override(out, path, value, schema=ScenarioConfig)
    return out


def scenario_from_dict(data: Mapping[str, Any], overrides: Iterable[Any] = (), *,
                       base_dir: Path | None = None, source: str = "",
                       name: str | None = None) -> ScenarioConfig:
    """Resolve and validate an in-memory scenario mapping (see the module docstring)."""
    resolved = resolve_scenario_dict(data, overrides, base_dir=base_dir)
    if name is not None:
        resolved.setdefault("name", name)
    if isinstance(resolved.get("sweep"), Mapping):
        # validated on its own first: inside the Optional its error paths lose the key
        validate(SweepConfig, resolved["sweep"], source=source, prefix="sweep")
    scenario = validate(ScenarioConfig, resolved, source=source)
    if scenario.sweep is not None:
        check_sweep_keys(scenario)
    return scenario


def load_scenario(name_or_path: str | Path, overrides: Iterable[Any] = ()) -> ScenarioConfig:
    """Load a scenario file (path, or a shipped name such as ``sand_walk``) with overrides.

    Example::

        sc = load_scenario("sim/sand_walk.yaml", ["terrain=rigid", "sim.duration=5"])

    Raises:
        ConfigError: malformed YAML, unknown key (dotted path, did-you-mean), wrong type,
            value out of range, an override of a key that does not exist.
        ModelFileError: the scenario, robot or terrain file cannot be found or read.
    """
    path = find_scenario(name_or_path)
    data = load_yaml(path)
    try:
        return scenario_from_dict(data, overrides, base_dir=path.parent, source=str(path),
                                  name=path.stem)
    except ConfigError as exc:
        if not exc.source and not str(exc).startswith(str(path)):
            raise type(exc)(_bare_message(exc), key=exc.key, value=exc.value,
                            allowed=exc.allowed, source=str(path)) from None
        raise


def _bare_message(exc: ConfigError) -> str:
    """The message of a ConfigError without the key/allowed decorations it adds."""
    text = str(exc)
    if exc.key and text.startswith(f"{exc.key}: "):
        text = text[len(exc.key) + 2:]
    if exc.allowed and text.endswith(f" (allowed: {exc.allowed})"):
        text = text[: -len(f" (allowed: {exc.allowed})")]
    return text


def resolved_dict(scenario: ScenarioConfig) -> dict[str, Any]:
    """The scenario as plain data, every file inlined (what ``config.resolved.yaml`` holds)."""
    return to_plain(scenario)


# --------------------------------------------------------------------------- sweeps
@dataclass(frozen=True)
class SweepTask:
    """One run of a sweep.

    Attributes:
        name: run folder name (unique within the sweep).
        params: what distinguishes this run: terrain, controller terrain, commanded speed,
            grid values, seed (column → value, for ``sweep.csv``).
        scenario: the resolved scenario of this run (``sweep`` section removed).
    """

    name: str
    params: dict
    scenario: ScenarioConfig


def check_sweep_keys(scenario: ScenarioConfig) -> None:
    """Every ``sweep.grid`` key must be a scenario key (did-you-mean otherwise)."""
    for key in scenario.sweep.grid:
        try:
            apply_override({}, key.split("."), None, schema=ScenarioConfig)
        except ConfigError as exc:
            raise ConfigError(f"grid key {key!r}: {_bare_message(exc)}", key="sweep.grid",
                              allowed=exc.allowed) from None
        if tuple(key.split(".")) in FILE_KEYS + (("command", "speed"),):
            raise ConfigError(f"grid key {key!r} has its own list: use sweep.terrains, "
                              "sweep.controller_terrains or sweep.speeds", key="sweep.grid")


def _slug(value: Any) -> str:
    text = f"{value:g}" if isinstance(value, float) else str(value)
    return "".join(c if c.isalnum() or c in "-." else "_" for c in text)


def expand_sweep(name_or_path: str | Path, overrides: Iterable[Any] = ()) -> tuple[ScenarioConfig, list[SweepTask]]:
    """The base scenario (with its ``sweep:`` section) and one task per combination.

    Combinations: terrains × controller terrains × speeds × grid values × seeds, in that
    nesting order. Combinations that resolve to the same scenario (e.g. a rigid plant
    with controller terrain ``plant`` and ``rigid``) are run once.

    Raises:
        ConfigError: no ``sweep:`` section, an unknown grid key, a terrain that cannot be found.
    """
    path = find_scenario(name_or_path)
    raw = load_yaml(path)
    overrides = list(overrides)
    base = scenario_from_dict(raw, overrides, base_dir=path.parent, source=str(path),
                              name=path.stem)
    sw = base.sweep
    if sw is None:
        raise ConfigError("this scenario has no 'sweep:' section (speeds, terrains, ...)",
                          key="sweep", source=str(path))
    grid_keys = list(sw.grid)
    grid_values = [sw.grid[k] for k in grid_keys]
    seeds = sw.seeds or [base.sim.seed]
    tasks: list[SweepTask] = []
    seen: dict[str, str] = {}
    for terrain, ctrl, speed, combo, seed in itertools.product(
            sw.terrains, sw.controller_terrains, sw.speeds, itertools.product(*grid_values), seeds):
        extra: list[Any] = [(["terrain"], terrain), (["controller", "terrain"], ctrl),
                            (["command", "speed"], speed), (["sim", "seed"], seed),
                            (["sweep"], None)]
        if sw.duration is not None:
            extra.append((["sim", "duration"], sw.duration))
        if not sw.plots:
            extra.append((["output", "plots"], False))
        extra += [(k.split("."), v) for k, v in zip(grid_keys, combo)]
        try:
            sc = scenario_from_dict(raw, overrides + extra, base_dir=path.parent,
                                    source=str(path), name=path.stem)
        except ConfigError as exc:
            what = f"terrain={terrain}, controller.terrain={ctrl}, speed={speed:g}" + "".join(
                f", {k}={v!r}" for k, v in zip(grid_keys, combo))
            raise type(exc)(f"sweep run ({what}): {exc}") from None
        parts = [_slug(terrain), f"ctrl-{_slug(ctrl)}", f"v{_slug(speed)}"]
        parts += [f"{k.split('.')[-1]}-{_slug(v)}" for k, v in zip(grid_keys, combo)]
        if len(seeds) > 1:
            parts.append(f"seed{seed}")
        name = "_".join(parts)
        params = {"terrain": sc.terrain.name,
                  "controller_terrain": ctrl,
                  "commanded_speed_mps": float(speed), "seed": int(seed)}
        params.update({k: v for k, v in zip(grid_keys, combo)})
        canon = {"name": ""}
        if sc.controller_terrain is not None and sc.controller_terrain == sc.terrain:
            # a controller given the plant's own terrain file is the 'plant' controller
            canon.update(controller_terrain=None,
                         controller=sc.controller.model_copy(update={"terrain": "plant"}))
        key = sc.model_copy(update=canon).model_dump_json()
        if key in seen:
            continue
        seen[key] = name
        tasks.append(SweepTask(name, params, sc.model_copy(update={"name": f"{sc.name}-{name}"})))
    return base, tasks


__all__ = ["load_scenario", "scenario_from_dict", "resolve_scenario_dict", "resolved_dict",
           "find_scenario", "expand_sweep", "SweepTask", "check_sweep_keys", "FILE_KEYS"]
