"""Writing results: output folders checked before any work and locked while written,
JSON-safe values, JSON files written atomically.

Safety rules of every output folder (``run``, ``sweep``, ``synth``):

* a folder is locked (:class:`OutputLock`, file ``.granular-mpc.lock`` holding the
  writer's PID and host) while a command writes it: a second writer gets an
  :class:`~granular_mpc.exceptions.OutputError` naming the holder; the lock of a process
  that no longer runs is taken over (with a note);
* what the package did not write in the same command is never deleted or replaced
  without an explicit ``overwrite`` (``--overwrite``): :func:`refuse_existing`.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
import socket
import sys
import warnings
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from .columns import LOCK_FILE
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


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` of this host still runs (a zombie counts as ended)."""
    try:
        pid = int(pid)
    except (TypeError, ValueError):
        return False
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:     # another user's process: it exists
        return True
    except OSError:
        return False
    try:                        # Linux: a zombie has ended
        stat = Path(f"/proc/{pid}/stat").read_text()
        return stat.rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def now_iso() -> str:
    """The local time with its UTC offset, to the millisecond (ISO 8601)."""
    return _dt.datetime.now().astimezone().isoformat(timespec="milliseconds")


def command_line() -> str:
    """This process's command line (for locks and status files)."""
    return " ".join(sys.argv)[:300]


class OutputLock:
    """The lock of one output folder while this process writes it.

    The lock is the file ``<folder>/.granular-mpc.lock`` created exclusively, holding
    ``{"pid", "host", "start", "command"}``. A lock whose process no longer runs (same
    host, PID gone) is taken over and :attr:`note` says so (also warned). Use as a
    context manager, or :meth:`acquire` / :meth:`release`.

    Args:
        folder: the output folder (must exist).

    Raises:
        OutputError: (on acquire) another live process holds the folder — the message
            names its PID, host, start time and command.
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.path = self.folder / LOCK_FILE
        self.note = ""
        self._held = False

    def holder(self) -> dict:
        """The current lock file's content (``{}`` if none or unreadable)."""
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
            return data if isinstance(data, dict) else {}
        except (OSError, ValueError):
            return {}

    def acquire(self) -> "OutputLock":
        me = {"pid": os.getpid(), "host": socket.gethostname(), "start": now_iso(),
              "command": command_line()}
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                held = self.holder()
                pid, host = held.get("pid"), held.get("host")
                if pid == os.getpid() and host == me["host"]:
                    raise OutputError(f"{self.folder} is already being written by this "
                                      f"process (PID {pid}) — a second writer in one process")
                if host not in (None, me["host"]):
                    raise OutputError(
                        f"{self.folder} is in use by PID {pid} on host {host} (since "
                        f"{held.get('start', '?')}: {held.get('command', '?')}); if that "
                        f"process has ended, delete {self.path} and try again")
                if pid is not None and pid_alive(pid):
                    raise OutputError(
                        f"{self.folder} is in use by PID {pid} (since {held.get('start', '?')}"
                        f": {held.get('command', '?')}); wait for it to end or choose "
                        "another output folder")
                self.note = (f"took over the stale lock of {self.folder} left by PID {pid} "
                             f"(no longer running, since {held.get('start', '?')})")
                warnings.warn(self.note, stacklevel=2)
                try:
                    self.path.unlink()
                except FileNotFoundError:
                    pass
                except OSError as exc:
                    raise OutputError(f"cannot take over {self.path}: "
                                      f"{exc.strerror or exc}") from None
                continue
            except OSError as exc:
                raise OutputError(f"cannot lock the output folder {self.folder}: "
                                  f"{exc.strerror or exc}") from None
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(json.dumps(me) + "\n")
            self._held = True
            return self
        raise OutputError(f"cannot lock the output folder {self.folder}: another process "
                          "keeps taking it")

    def release(self) -> None:
        """Remove the lock file if this process holds it (idempotent)."""
        if not self._held:
            return
        self._held = False
        if self.holder().get("pid") == os.getpid():
            try:
                self.path.unlink()
            except OSError:
                pass

    def __enter__(self) -> "OutputLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def refuse_existing(folder: str | Path, found: Iterable[Path], *, what: str,
                    overwrite: bool) -> list[Path]:
    """Refuse to replace ``found`` (files of ``folder`` a command would replace) unless
    ``overwrite``; returns them (to be removed by the caller when ``overwrite``).

    Raises:
        OutputError: some exist and not ``overwrite`` (names up to five of them).
    """
    found = sorted({Path(p) for p in found if Path(p).exists()})
    if found and not overwrite:
        folder = Path(folder)
        names = ", ".join(str(p.relative_to(folder)) if p.is_relative_to(folder) else str(p)
                          for p in found[:5])
        more = f" and {len(found) - 5} more" if len(found) > 5 else ""
        raise OutputError(f"{folder} already holds {what} ({names}{more}); pass --overwrite "
                          "(overwrite=True) to replace it, or choose another output folder")
    return found


def remove_files(paths: Iterable[Path]) -> None:
    """Delete ``paths`` (missing ones are fine).

    Raises:
        OutputError: one cannot be deleted.
    """
    for p in paths:
        try:
            Path(p).unlink(missing_ok=True)
        except OSError as exc:
            raise OutputError(f"cannot replace {p}: {exc.strerror or exc}") from None


@contextlib.contextmanager
def exclusive_lock(lock_path: str | Path):
    """Hold an exclusive ``fcntl`` lock on ``lock_path`` (created if missing) for the
    ``with`` block; other processes asking for it wait. For work that several processes
    may want at once and only one should do (a compiled library, a shared test data set).
    A no-op where ``fcntl`` is missing: the processes then just duplicate the work."""
    try:
        import fcntl
    except ImportError:                     # not POSIX
        yield
        return
    with open(lock_path, "a+") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


__all__ = ["make_output_folder", "json_safe", "write_json", "OutputLock", "pid_alive",
           "refuse_existing", "remove_files", "now_iso", "command_line", "exclusive_lock"]
