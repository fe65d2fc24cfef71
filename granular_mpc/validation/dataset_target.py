"""Where a data set may be written: the output-safety rules of ``synth`` (and
:func:`~granular_mpc.validation.synth.noisy_copy`).

Measured data (a ``meta.yaml`` without a ``generator`` section) is never replaced; a
synthetic data set only with ``overwrite``; a non-empty folder without ``meta.yaml`` never
(the result would not be a data set). The folder is locked
(:class:`~granular_mpc.output.OutputLock`) while the command writes it.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from ..columns import META_FILE
from ..exceptions import OutputError
from ..output import OutputLock, make_output_folder, remove_files


def dataset_target(folder: str | Path, overwrite: bool = False) -> list[Path]:
    """Check that a data set may be written into ``folder``; returns the files of a
    previous synthetic data set there that are to be replaced (``overwrite`` only).

    * missing or empty (hidden files aside): fine, nothing to replace;
    * ``meta.yaml`` with a ``generator`` section (written by ``synth``): replaced only
      with ``overwrite`` (its ``meta.yaml`` and listed trial files);
    * ``meta.yaml`` without ``generator`` — measured data — or unreadable: never replaced;
    * other files but no ``meta.yaml``: refused (the result would not be a data set).

    Raises:
        OutputError: naming the folder and why.
    """
    folder = Path(folder)
    if not folder.exists():
        return []
    if not folder.is_dir():
        raise OutputError(f"output folder {folder} exists and is not a folder")
    meta = folder / META_FILE
    if not meta.is_file():
        entries = sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))
        if entries:
            shown = ", ".join(entries[:5]) + (" …" if len(entries) > 5 else "")
            raise OutputError(f"{folder} is not empty ({shown}) and holds no data set "
                              f"({META_FILE}): a data set is written only into a new or empty "
                              "folder, or over a synthetic data set; choose another folder")
        return []
    try:
        data = yaml.safe_load(meta.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise OutputError(f"{meta} cannot be read ({type(exc).__name__}), so {folder} may hold "
                          "measured data: it is not replaced; choose another folder") from None
    if not isinstance(data, dict) or not data.get("generator"):
        raise OutputError(f"{folder} holds measured data ({META_FILE} without a generator "
                          "section): it is never overwritten, not even with --overwrite; "
                          "choose another folder")
    trials = data.get("trials") if isinstance(data.get("trials"), dict) else {}
    files = [meta]
    for entry in trials.values():
        f = folder / str(entry.get("file", "")) if isinstance(entry, dict) else None
        if f is not None and f.is_file() and f.parent == folder \
                and f.suffix in (".csv", ".parquet"):
            files.append(f)
    if not overwrite:
        raise OutputError(f"{folder} already holds a synthetic data set ({len(files) - 1} "
                          f"trial file(s), generator: {data['generator'].get('scenario', '?') if isinstance(data['generator'], dict) else '?'}); "
                          "pass --overwrite (overwrite=True) to replace it, or choose another "
                          "folder")
    return files


class DatasetTarget:
    """Context manager: a data set folder checked (:func:`dataset_target`), created and locked for this
    command; :meth:`clear` removes the previous synthetic data set just before writing.
    A folder this command created is removed again if nothing was written."""

    def __init__(self, folder: Path, overwrite: bool) -> None:
        self.folder = Path(folder).expanduser()
        self.overwrite = overwrite
        self._created = False
        self._lock: OutputLock | None = None

    def __enter__(self) -> "DatasetTarget":
        dataset_target(self.folder, self.overwrite)
        self._created = not self.folder.exists()
        make_output_folder(self.folder)
        self._lock = OutputLock(self.folder).acquire()
        return self

    def clear(self) -> None:
        remove_files(dataset_target(self.folder, self.overwrite))

    def __exit__(self, *exc) -> None:
        if self._lock is not None:
            self._lock.release()
        if self._created:
            try:
                self.folder.rmdir()       # only if still empty
            except OSError:
                pass


__all__ = ["dataset_target", "DatasetTarget"]
