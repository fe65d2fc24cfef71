"""The live status of a run or sweep folder (``status.json``) and its reader.

While a command writes a folder, ``status.json`` holds ``{"state": "running", "pid",
"host", "start", "heartbeat", "end": null, "command", "package_version",
"proxsuite_build"}``; a background thread rewrites ``heartbeat`` (and ``sim_time_s``)
every :data:`HEARTBEAT_S` seconds. At the end ``state`` becomes ``complete``,
``interrupted`` or ``failed`` with ``end`` and ``reason``. A process killed outright
(SIGKILL, power loss) leaves ``running`` behind: :func:`run_status` then reports
``dead`` because its PID is gone or its heartbeat is stale.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import socket
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import __version__
from ..columns import STATUS_FILE, SUMMARY_FILE
from ..control.solvers.proxqp import proxsuite_build
from ..exceptions import GranularMpcError, OutputError
from ..output import command_line, now_iso, pid_alive, write_json

HEARTBEAT_S = 2.0
"""Seconds between two heartbeats of a running command."""
STALE_S = 15.0
"""A heartbeat older than this [s] means the writer is gone."""
STATES = ("running", "complete", "interrupted", "failed")
"""States a writer records; :func:`run_status` adds ``dead`` and ``unknown``."""


def proxsuite_build_name() -> str:
    """The ProxSuite binding this process uses (``proxsuite_pywrap_avx2`` …), or
    ``unavailable: <why>``."""
    try:
        return proxsuite_build()
    except (GranularMpcError, ImportError, AttributeError) as exc:
        return f"unavailable: {exc}"


def provenance() -> dict[str, str]:
    """``{"package_version", "proxsuite_build"}`` of this process (recorded in
    ``summary.json`` and ``status.json``)."""
    return {"package_version": __version__, "proxsuite_build": proxsuite_build_name()}


def end_state(complete: bool, reason: str) -> str:
    """The final state for a run that ended with ``complete`` / ``reason``."""
    if complete:
        return "complete"
    return "interrupted" if reason.startswith("interrupted") else "failed"


class StatusWriter:
    """Writes ``status.json`` of one folder: :meth:`start`, heartbeats, :meth:`finish`.

    Args:
        folder: the run or sweep folder.
        extra: more fields for the file (e.g. ``scenario``).
        interval: seconds between heartbeats.
    """

    def __init__(self, folder: str | Path, extra: dict[str, Any] | None = None,
                 interval: float = HEARTBEAT_S) -> None:
        self.path = Path(folder) / STATUS_FILE
        self.interval = float(interval)
        self.data: dict[str, Any] = {
            "state": "running", "pid": os.getpid(), "host": socket.gethostname(),
            "start": now_iso(), "heartbeat": now_iso(), "end": None, "reason": "",
            "command": command_line(), **provenance(), **(extra or {})}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.finished = False

    def start(self) -> "StatusWriter":
        """Write ``running`` and start the heartbeat thread."""
        self._write()
        self._thread = threading.Thread(target=self._beat, name="granular-mpc-heartbeat",
                                        daemon=True)
        self._thread.start()
        return self

    def update(self, **fields: Any) -> None:
        """Fields written with the next heartbeat (cheap: no file access)."""
        self.data.update(fields)

    def _beat(self) -> None:
        while not self._stop.wait(self.interval):
            if self.finished:
                return
            self.data["heartbeat"] = now_iso()
            try:
                self._write()
            except OutputError:     # a full disk must not kill the run
                pass

    def _write(self) -> None:
        with self._lock:
            write_json(self.path, dict(self.data))

    def finish(self, state: str, reason: str = "") -> None:
        """Stop the heartbeats and write the final ``state`` (one of :data:`STATES`)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        now = now_iso()
        self.data.update(state=state, reason=reason, end=now, heartbeat=now)
        self.finished = True
        self._write()


@dataclass(frozen=True)
class RunStatus:
    """What a run or sweep folder says about its writer (:func:`run_status`).

    Attributes:
        folder: the folder.
        state: ``running`` (the writer is alive), ``complete``, ``interrupted``,
            ``failed``, ``dead`` (``running`` recorded but the writer is gone: its PID no
            longer runs or its heartbeat is older than ``stale_after``) or ``unknown`` (no
            status file).
        pid, host: the writer.
        start, heartbeat, end: ISO 8601 times (``end`` ``None`` while running).
        heartbeat_age_s: seconds since the last heartbeat (``None`` if unknown).
        reason: why it ended (or why it is considered dead).
        package_version, proxsuite_build: what wrote it.
    """

    folder: Path
    state: str
    pid: int | None = None
    host: str = ""
    start: str = ""
    heartbeat: str = ""
    end: str | None = None
    heartbeat_age_s: float | None = None
    reason: str = ""
    package_version: str = ""
    proxsuite_build: str = ""

    @property
    def alive(self) -> bool:
        """The writer still runs."""
        return self.state == "running"


def _age(stamp: Any) -> float | None:
    try:
        t = _dt.datetime.fromisoformat(str(stamp))
    except ValueError:
        return None
    now = _dt.datetime.now(t.tzinfo) if t.tzinfo else _dt.datetime.now()
    return (now - t).total_seconds()


def run_status(folder: str | Path, stale_after: float = STALE_S) -> RunStatus:
    """Read ``status.json`` of a run or sweep folder and tell a live writer from a dead one.

    A recorded ``running`` becomes ``dead`` when the writer's PID no longer runs (same
    host) or its heartbeat is older than ``stale_after`` seconds. Without a status file
    (older runs), ``summary.json`` decides between ``complete``/``interrupted``/``failed``
    and ``unknown``.

    Args:
        folder: the folder.
        stale_after: heartbeat age [s] after which the writer counts as gone.
    """
    folder = Path(folder)
    try:
        data = json.loads((folder / STATUS_FILE).read_text(encoding="utf-8"))
        if not isinstance(data, dict):
            raise ValueError
    except (OSError, ValueError):
        try:
            s = json.loads((folder / SUMMARY_FILE).read_text(encoding="utf-8"))
            reason = str(s.get("reason", ""))
            state = "unknown" if reason == "running" else end_state(bool(s.get("complete")),
                                                                    reason)
            return RunStatus(folder, state, reason=reason)
        except (OSError, ValueError, AttributeError):
            return RunStatus(folder, "unknown")
    state = str(data.get("state", "unknown"))
    reason = str(data.get("reason", ""))
    age = _age(data.get("heartbeat"))
    pid = data.get("pid") if isinstance(data.get("pid"), int) else None
    if state == "running":
        if data.get("host") == socket.gethostname() and pid is not None and not pid_alive(pid):
            state, reason = "dead", f"PID {pid} no longer runs (last heartbeat " \
                                    f"{data.get('heartbeat')})"
        elif age is not None and age > stale_after:
            state, reason = "dead", f"no heartbeat for {age:.0f} s (PID {pid})"
    return RunStatus(folder, state, pid, str(data.get("host", "")), str(data.get("start", "")),
                     str(data.get("heartbeat", "")), data.get("end"), age, reason,
                     str(data.get("package_version", "")), str(data.get("proxsuite_build", "")))


__all__ = ["StatusWriter", "RunStatus", "run_status", "provenance", "proxsuite_build_name",
           "end_state", "HEARTBEAT_S", "STALE_S", "STATES"]
