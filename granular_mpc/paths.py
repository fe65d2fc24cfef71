"""Where robot, terrain and scenario files are found.

Search order for a name such as ``dry_sand`` of kind ``terrain``:

1. the name as a path (absolute, or relative to the referring file's folder, then the
   current folder), with or without ``.yaml``;
2. every folder in the ``GRANULAR_MPC_MODELS`` environment variable (``os.pathsep``
   separated), then the package's own ``models/`` folder, under the kind's sub-folder
   (``terrain/`` for terrain files, top level for robots).
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

from .exceptions import ModelFileError

_PACKAGE_DIR = Path(__file__).resolve().parent
_warned_missing: set[str] = set()


def models_dirs() -> list[Path]:
    """Folders searched for robot and terrain files, first match wins."""
    dirs: list[Path] = []
    env = os.environ.get("GRANULAR_MPC_MODELS", "")
    for p in filter(None, env.split(os.pathsep)):
        if not Path(p).is_dir():
            if p not in _warned_missing:     # once per folder and process
                _warned_missing.add(p)
                warnings.warn(f"GRANULAR_MPC_MODELS names {p!r}, which is not a folder: "
                              "ignored", stacklevel=2)
            continue
        dirs.append(Path(p))
    for candidate in (_PACKAGE_DIR / "_models", _PACKAGE_DIR.parent / "models"):
        if candidate.is_dir():
            dirs.append(candidate)
    return dirs


def sim_dir() -> Path | None:
    """The folder holding the shipped scenario files, if present."""
    for candidate in (_PACKAGE_DIR / "_sim", _PACKAGE_DIR.parent / "sim"):
        if candidate.is_dir():
            return candidate
    return None


_SUBDIR = {"robot": "", "terrain": "terrain", "scenario": ""}


def available(kind: str) -> list[str]:
    """Names of the shipped files of one kind (for error messages)."""
    names: set[str] = set()
    for d in models_dirs():
        sub = d / _SUBDIR[kind] if _SUBDIR[kind] else d
        if sub.is_dir():
            for f in sub.glob("*.yaml"):
                if kind == "robot" and f.parent.name == "terrain":
                    continue
                names.add(f.stem)
    return sorted(names)


def resolve_file(kind: str, name: str, *, relative_to: Path | None = None, key: str = "") -> Path:
    """Return the path of a robot / terrain / scenario file named ``name``.

    Raises:
        ModelFileError: naming what was searched and which names exist.
    """
    if kind not in _SUBDIR:
        raise ValueError(f"unknown file kind {kind!r}")
    raw = Path(str(name)).expanduser()
    candidates: list[Path] = []
    bases = [relative_to] if relative_to is not None else []
    bases.append(Path.cwd())
    for base in bases:
        p = raw if raw.is_absolute() else base / raw
        candidates += [p, p.with_name(p.name + ".yaml")]
    if kind != "scenario":
        for d in models_dirs():
            sub = d / _SUBDIR[kind] if _SUBDIR[kind] else d
            candidates += [sub / raw, sub / f"{raw}.yaml"]
    for c in candidates:
        if c.is_file():
            return c.resolve()
    allowed = ", ".join(available(kind)) if kind != "scenario" else "an existing YAML file"
    raise ModelFileError(f"{kind} file {str(name)!r} not found", key=key, value=name,
                         allowed=allowed or "a path to a YAML file")
