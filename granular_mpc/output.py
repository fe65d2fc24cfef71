"""Writing results: output folders checked before any work, JSON-safe values, JSON files
written atomically."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .exceptions import OutputError


def make_output_folder(folder: str | Path) -> Path:
    """Create ``folder`` (parents too) and check that it can be written.

    Raises:
        OutputError: it exists and is not a folder, or it cannot be created or written.
    """
    out = Path(folder)
    if out.exists() and not out.is_dir():
        raise OutputError(f"output folder {out} exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".granular-mpc-write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        raise OutputError(f"cannot write the output folder {out}: "
                          f"{exc.strerror or exc}") from None
    return out


def json_safe(x: Any) -> Any:
    """A value ``json.dumps`` accepts: NaN/inf → None, numpy scalars and arrays → Python,
    dict keys → str."""
    if isinstance(x, dict):
        return {str(k): json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_safe(x.tolist())
    if isinstance(x, (np.floating, float)):
        x = float(x)
        return x if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_json(path: str | Path, data: Mapping) -> Path:
    """Write ``data`` as strict JSON (indent 2, no NaN), atomically.

    The text goes to ``<path>.tmp`` first, then replaces ``path``: a reader never sees a
    half-written file. Pass JSON-safe data (:func:`json_safe`).

    Raises:
        OutputError: the file cannot be written.
        ValueError: ``data`` holds NaN or infinity.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        tmp.replace(path)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


__all__ = ["make_output_folder", "json_safe", "write_json"]
