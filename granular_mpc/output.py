"""Writing results: output folders that are checked before any work, and JSON-safe values."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

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
