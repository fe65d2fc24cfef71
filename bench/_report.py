"""Shared output of the benchmarks: one ``name: value unit`` line per figure, and the same
figures as a JSON object with ``--json PATH`` (the contract in shared/DESIGN.md)."""

from __future__ import annotations

import json
import math


def emit(figures: dict, json_path: str | None = None, units: dict | None = None) -> None:
    """Print each figure (unit looked up by name suffix in ``units``) and write the JSON."""
    units = units or {}
    for name, value in figures.items():
        unit = next((u for suffix, u in units.items() if name.endswith(suffix)), "")
        text = f"{value:.4g}" if isinstance(value, float) and math.isfinite(value) else str(value)
        print(f"{name}: {text} {unit}".rstrip(), flush=True)
    if json_path:
        with open(json_path, "w", encoding="utf-8") as fh:
            json.dump(figures, fh, indent=2)


def emit_study(figures: dict, rows: list, json_path=None) -> None:
    """A study's figures as ``name: value`` lines (3 significant digits) and, with
    ``json_path``, ``{"figures": …, "rows": …}`` as JSON (rows as written, other values as
    text)."""
    for k, v in figures.items():
        print(f"{k}: {v:.3g}" if isinstance(v, float) else f"{k}: {v}")
    if json_path:
        with open(json_path, "w", encoding="utf-8") as fh:
            json.dump({"figures": figures, "rows": rows}, fh, indent=1, default=str)
