"""The run folder: its default name, preparing it for a run, the resolved scenario file.

A run folder (``granular-mpc run --out DIR``) holds ``config.resolved.yaml``,
``summary.json``, ``log/part-*.parquet``, ``plots/*.png`` and ``animation.html``; the
names are those of :mod:`granular_mpc.columns`.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import yaml

from .. import __version__
from ..columns import HTML_FILE, LOG_DIR, PLOTS_DIR, RESOLVED_FILE, SUMMARY_FILE
from ..config import ScenarioConfig
from ..exceptions import OutputError
from ..output import make_output_folder
from ..scenario import resolved_dict


def default_out_dir(scenario: ScenarioConfig, root: str | Path = "runs") -> Path:
    """``runs/<scenario-name>-<YYYYmmdd-HHMMSS>`` (a suffix if that folder exists)."""
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    base = Path(root) / f"{scenario.name}-{stamp}"
    cand, k = base, 2
    while cand.exists():
        cand = base.with_name(f"{base.name}-{k}")
        k += 1
    return cand


def prepare_out_dir(out_dir: str | Path) -> Path:
    """Create the run folder (or reuse one), removing a previous run's outputs in it.

    Only the files a run writes are removed (``log/part-*.parquet``, ``summary.json``,
    ``config.resolved.yaml``, ``plots/*.png``, ``animation.html``); anything else stays.

    Raises:
        OutputError: the folder cannot be created or written.
    """
    out = make_output_folder(out_dir)
    stale = [out / SUMMARY_FILE, out / RESOLVED_FILE, out / HTML_FILE]
    stale += list((out / LOG_DIR).glob("part-*.parquet")) + list((out / LOG_DIR).glob("part-*.tmp"))
    stale += list((out / PLOTS_DIR).glob("*.png"))
    for p in stale:
        try:
            p.unlink(missing_ok=True)
        except OSError as exc:
            raise OutputError(f"cannot replace {p}: {exc.strerror or exc}") from None
    return out


def write_resolved_config(scenario: ScenarioConfig, path: str | Path) -> Path:
    """Write the fully resolved scenario (files inlined) as YAML; it loads back equal.

    Raises:
        OutputError: the file cannot be written.
    """
    path = Path(path)
    head = (f"# Resolved scenario '{scenario.name}' (granular_mpc {__version__}, "
            f"{_dt.datetime.now().isoformat(timespec='seconds')}).\n"
            "# Every file inlined; rerun with: granular-mpc run THIS_FILE\n")
    try:
        path.write_text(head + yaml.safe_dump(resolved_dict(scenario), sort_keys=False,
                                              allow_unicode=True), encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


__all__ = ["default_out_dir", "prepare_out_dir", "write_resolved_config"]
