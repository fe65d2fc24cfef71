"""Ending a run cleanly on SIGINT / SIGTERM, whatever phase it is in.

:class:`RunSignals` holds the signal policy of a whole run (``run_scenario``):

* **start-up** (building, preparing the folder): a signal raises
  :class:`~granular_mpc.exceptions.Interrupted` at once;
* **loop** (:meth:`RunSignals.attach`): the first signal asks the loop to stop at the
  next plant step (``end_reason`` ``interrupted by SIGINT`` / ``SIGTERM``); a second one
  raises :class:`~granular_mpc.exceptions.Interrupted` (the run ends at once, the log so
  far and the summary are still written);
* **hold** (:meth:`RunSignals.hold`, while the final summary and status are written):
  signals are noted, never raised, so the summary is always final;
* **figures** (after :meth:`RunSignals.release`): a signal raises ``Interrupted`` (the
  figures are skipped; the summary is already final).

:class:`StopOnSignal` is the older, loop-only policy (kept for scripts).
"""

from __future__ import annotations

import signal
import threading
from typing import Any

from ..exceptions import Interrupted
from .state import LoopState

_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class RunSignals:
    """Context manager: the SIGINT / SIGTERM policy of one run (see the module docstring).

    Only installed in the main thread (signals cannot be caught elsewhere); the previous
    handlers are restored on exit.

    Attributes:
        received: names of the signals received, in order.
    """

    def __init__(self) -> None:
        self.received: list[str] = []
        self._state: LoopState | None = None
        self._phase = "startup"
        self._old: dict[int, Any] = {}

    def __enter__(self) -> "RunSignals":
        if threading.current_thread() is threading.main_thread():
            for sig in _SIGNALS:
                try:
                    self._old[sig] = signal.signal(sig, self._handle)
                except (ValueError, OSError):  # pragma: no cover - exotic embedders
                    pass
        return self

    @property
    def first(self) -> str:
        """Name of the first signal received (``""`` if none)."""
        return self.received[0] if self.received else ""

    def attach(self, state: LoopState) -> None:
        """Loop phase: the first signal stops ``state``'s loop at the next step."""
        self._state = state
        self._phase = "loop"

    def hold(self) -> None:
        """Hold phase: signals are only noted (the final summary is being written)."""
        self._phase = "hold"

    def release(self) -> None:
        """Figures phase: a signal raises :class:`Interrupted`; one noted while holding
        is not replayed (the summary already records the interruption, if any)."""
        self._phase = "figures"

    def _handle(self, signum, frame) -> None:
        name = signal.Signals(signum).name
        self.received.append(name)
        if self._phase == "hold":
            return
        if self._phase == "loop" and self._state is not None and len(self.received) == 1:
            self._state.request_stop(f"interrupted by {name}")
            return
        raise Interrupted(signum)

    def __exit__(self, *exc) -> None:
        for sig, old in self._old.items():
            try:
                signal.signal(sig, old)
            except (ValueError, OSError):  # pragma: no cover
                pass


class StopOnSignal:
    """Context manager: SIGINT/SIGTERM → ``state.request_stop`` (the loop ends cleanly at
    the next step, with ``end_reason`` ``interrupted by SIGINT`` / ``SIGTERM``).

    A second signal raises :class:`~granular_mpc.exceptions.Interrupted` (a
    ``KeyboardInterrupt``). Only installed in the main thread; the previous handlers are
    restored on exit.

    Args:
        state: the loop state to stop.
    """

    def __init__(self, state: LoopState) -> None:
        self._signals = RunSignals()
        self._signals.attach(state)

    def __enter__(self) -> "StopOnSignal":
        self._signals.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self._signals.__exit__(*exc)


__all__ = ["RunSignals", "StopOnSignal"]
