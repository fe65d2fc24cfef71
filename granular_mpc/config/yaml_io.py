"""YAML files of the config: read as UTF-8, parsed with duplicate keys rejected.

At the bottom of the config package (it imports nothing of it), so that every config
module can read YAML the same way.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from ..exceptions import ConfigError, ModelFileError


class UniqueKeyLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that rejects a key given twice in one mapping (plain YAML keeps
    the last one silently: a ``duration: 0.3`` followed by ``duration: 5`` runs 5 s)."""

    def construct_mapping(self, node, deep=False):
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            try:
                key = self.construct_object(key_node, deep=True)
                hash(key)
            except (TypeError, yaml.YAMLError):
                continue
            line = key_node.start_mark.line + 1
            if key in seen and key != "<<":
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r} (first given at line {seen[key]}, again)",
                    key_node.start_mark)
            seen[key] = line
        return super().construct_mapping(node, deep=deep)


def parse_yaml(text: str, source: str = "") -> Any:
    """Parse YAML text with :class:`UniqueKeyLoader` (duplicate keys are errors).

    Raises:
        ConfigError: malformed YAML or a duplicate key, with line and column.
    """
    try:
        return yaml.load(text, Loader=UniqueKeyLoader)  # noqa: S506 - a SafeLoader
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        text = (f"{problem}{where}" if problem.startswith("duplicate key")
                else f"malformed YAML{where}: {problem}")
        raise ConfigError(text, source=source) from None


def load_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping; a missing or malformed file raises one clear error.

    Raises:
        ModelFileError: the file does not exist or cannot be read.
        ConfigError: malformed YAML (with line and column), a key given twice, text that
            is not UTF-8, or the top level is not a mapping.
    """
    p = Path(path)
    if not p.is_file():
        raise ModelFileError(f"file not found: {p}", value=str(p))
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        bad = exc.object[exc.start:exc.start + 1]
        raise ConfigError(f"not UTF-8 text (byte {exc.start}: {bad!r}); save the file as "
                          "UTF-8", source=str(p)) from None
    except OSError as exc:
        raise ModelFileError(f"cannot read {p}: {exc.strerror}", value=str(p)) from None
    data = parse_yaml(text, str(p))
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"top level must be a mapping, got {type(data).__name__}",
                          source=str(p))
    return data


__all__ = ["UniqueKeyLoader", "parse_yaml", "load_yaml"]
