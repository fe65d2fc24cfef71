"""The run folder: its default name, preparing it for a run, the resolved scenario file.

A run folder (``granular-mpc run --out DIR``) holds ``config.resolved.yaml``,
``summary.json``, ``status.json``, ``log/part-*.parquet``, ``plots/*.png`` and
``animation.html``; the names are those of :mod:`granular_mpc.columns`. A previous run's
outputs are replaced only with ``overwrite`` (``--overwrite``); other files stay.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import yaml

from .. import __version__
from ..columns import HTML_FILE, LOG_DIR, PLOTS_DIR, RESOLVED_FILE, STATUS_FILE, SUMMARY_FILE
from ..config import ScenarioConfig
from ..exceptions import OutputError
from ..output import make_output_folder, refuse_existing, remove_files
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


def run_outputs(out_dir: str | Path) -> list[Path]:
    """The files of a previous run in ``out_dir`` (those a run writes: ``summary.json``,
    ``status.json``, ``config.resolved.yaml``, ``animation.html``, ``log/part-*``,
    ``plots/*.png``)."""
    out = Path(out_dir)
    found = [out / SUMMARY_FILE, out / STATUS_FILE, out / RESOLVED_FILE, out / HTML_FILE]
    found += list((out / LOG_DIR).glob("part-*.parquet")) + list((out / LOG_DIR).glob("part-*.tmp"))
    found += list((out / PLOTS_DIR).glob("*.png"))
    return [p for p in found if p.exists()]


def prepare_out_dir(out_dir: str | Path, overwrite: bool = False) -> Path:
    """Create the run folder (or reuse one); a previous run's outputs in it are replaced
    only with ``overwrite``.

    Only the files a run writes are removed (:func:`run_outputs`); anything else stays.
    Lock the folder first (:class:`~granular_mpc.output.OutputLock`) when another process
    might write it.

    Raises:
        OutputError: the folder cannot be created or written, or holds a previous run and
            not ``overwrite``.
    """
    out = make_output_folder(out_dir)
    remove_files(refuse_existing(out, run_outputs(out), what="a previous run",
                                 overwrite=overwrite))
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


__all__ = ["default_out_dir", "prepare_out_dir", "run_outputs", "write_resolved_config"]
