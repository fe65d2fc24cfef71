"""A sweep's outputs: the table ``sweep.csv`` (one row per run) and the CoT-vs-speed plot."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd


def flatten_summary(prefix: str, value: Any, out: dict) -> None:
    """Put ``value`` into ``out`` as scalar columns, nested keys joined with ``_``.

    Lists become JSON text, except ``window_s`` → ``window_start_s``, ``window_end_s``.

    Args:
        prefix: column name of ``value`` (``""`` at the top).
        value: a summary value (dict, list or scalar).
        out: the row being filled (changed in place).
    """
    if isinstance(value, Mapping):
        for k, v in value.items():
            flatten_summary(f"{prefix}_{k}" if prefix else str(k), v, out)
    elif isinstance(value, (list, tuple)):
        if prefix == "window_s" and len(value) == 2:
            out["window_start_s"], out["window_end_s"] = value
        else:
            out[prefix] = json.dumps(value)
    else:
        out[prefix] = value


def sweep_table(results: Sequence[Mapping[str, Any]]) -> pd.DataFrame:
    """``sweep.csv`` rows from worker results (order kept).

    Args:
        results: :func:`~granular_mpc.runner.sweep.sweep_task` results
            (``{"name", "params", "run_dir", "summary"}``).

    Returns:
        One row per run: ``run``, ``state`` (``complete``, ``interrupted``, ``failed``,
        ``killed``), ``run_dir``, the swept values, then every scalar of the summary
        (nested values flattened with ``_``; ``notes`` left out). JSON nulls are NaN in
        numeric columns; the plot's columns exist even if no run produced them.
    """
    rows = []
    for r in results:
        s = r["summary"]
        reason = str(s.get("reason", ""))
        state = ("complete" if s.get("complete") else "killed" if reason.startswith("killed")
                 else "interrupted" if reason.startswith("interrupted") else "failed")
        row: dict[str, Any] = {"run": r["name"], "state": state, "run_dir": r["run_dir"]}
        row.update(r["params"])
        summary = dict(r["summary"])
        summary.pop("notes", None)
        flatten_summary("", summary, row)
        rows.append(row)
    df = pd.DataFrame(rows)
    for col in df.columns:   # None (JSON null) → NaN in numeric columns
        vals = [v for v in df[col] if v is not None]
        if df[col].dtype == object and vals and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
            df[col] = pd.to_numeric(df[col])
        elif df[col].dtype == object and not vals:
            df[col] = np.nan
    for col, default in (("terrain", ""), ("controller_terrain_model", ""),
                         ("commanded_speed_mps", np.nan), ("mean_speed_mps", np.nan),
                         ("fell", True), ("cot", np.nan), ("complete", False)):
        if col not in df.columns:
            df[col] = default
    return df


def sweep_plot(table: pd.DataFrame, path: Path, reference_terrain: str = "rigid"):
    """CoT vs v/√(g h_CoM) of a sweep table (``plot_cot_vs_speed``), written to ``path``.

    Uses the complete runs (never an interrupted or failed one) that did not fall and
    have a finite CoT; if every such run fell, the complete runs with a finite CoT (up to
    their fall). Returns ``(path or None, ratio table, note)`` — the note says which runs
    are shown.
    """
    # matplotlib is imported only when a plot is made
    from ..viz.plots import plot_cot_vs_speed

    empty = pd.DataFrame(columns=["series", "terrain", "controller_terrain_model",
                                  "commanded_speed_mps", "cot_ratio"])
    if table.empty or "h_com_m" not in table.columns:
        return None, empty, "no runs with a CoT: no plot"
    done = table[table["complete"].astype(bool)] if "complete" in table.columns else table
    left_out = len(table) - len(done)
    cot = pd.to_numeric(done["cot"], errors="coerce")
    finite = done[np.isfinite(cot.to_numpy(dtype=float))]
    good = finite[~finite["fell"].astype(bool)]
    if not good.empty:
        use, note = good, f"{len(good)} of {len(table)} runs (runs that fell are left out)"
    elif not finite.empty:
        use, note = finite, (f"every run with a CoT fell: the plot shows those {len(finite)} "
                             "runs anyway (CoT up to the fall)")
    else:
        return None, empty, ("no complete run has a finite CoT: no plot" if left_out else
                             "no run has a finite CoT (no forward progress): no plot")
    if left_out:
        note += f"; {left_out} incomplete run(s) (interrupted or failed) left out"
    df = use.assign(h_com=use["h_com_m"].astype(float), cot=use["cot"].astype(float),
                    mean_speed_mps=use["mean_speed_mps"].astype(float))
    out = plot_cot_vs_speed(df, path, reference_terrain=reference_terrain)
    return out.path, out.data["ratio"], note


__all__ = ["sweep_table", "sweep_plot", "flatten_summary"]
