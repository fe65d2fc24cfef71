"""Ending a run cleanly on SIGINT / SIGTERM: the loop stops at the next plant step."""

from __future__ import annotations

import signal
import threading
from typing import Any

from .state import LoopState


class StopOnSignal:
    """Context manager: SIGINT/SIGTERM → ``state.request_stop`` (the loop ends cleanly at
    the next step, with ``end_reason`` ``interrupted by SIGINT`` / ``SIGTERM``).

    A second signal gets the previous handler (Ctrl-C twice: KeyboardInterrupt). Only
    installed in the main thread (signals cannot be caught elsewhere); the previous
    handlers are restored on exit.

    Args:
        state: the loop state to stop.
    """

    def __init__(self, state: LoopState) -> None:
        self.state = state
        self._old: dict[int, Any] = {}

    def __enter__(self) -> "StopOnSignal":
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                try:
                    self._old[sig] = signal.signal(sig, self._handle)
                except (ValueError, OSError):  # pragma: no cover - exotic embedders
                    pass
        return self

    def _handle(self, signum, frame) -> None:
        self.state.request_stop(f"interrupted by {signal.Signals(signum).name}")
        old = self._old.get(signum)
        if old is not None:
            signal.signal(signum, old)

    def __exit__(self, *exc) -> None:
        for sig, old in self._old.items():
            try:
                signal.signal(sig, old)
            except (ValueError, OSError):  # pragma: no cover
                pass


__all__ = ["StopOnSignal"]
