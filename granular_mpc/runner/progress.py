"""Progress bars on stderr (rich): one for a run, one for a sweep."""

from __future__ import annotations

import time

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


class RunProgress:
    """Progress bar of one run: simulated time, real-time factor, falls.

    Redrawn at most every 0.2 s of wall time (unless forced). Does nothing when
    ``enabled`` is false.

    Args:
        enabled: show the bar.
        name: label (the scenario name).
        duration: simulated duration of the run [s] (the bar's total).
    """

    def __init__(self, enabled: bool, name: str, duration: float) -> None:
        self.enabled = enabled
        self._next = 0.0
        if not enabled:
            return
        self._p = Progress(TextColumn("[bold]{task.description}"), BarColumn(),
                           TextColumn("t = {task.completed:.2f} / {task.total:.2f} s"),
                           TextColumn("RTF {task.fields[rtf]}"),
                           TextColumn("falls {task.fields[falls]}"),
                           TimeElapsedColumn(), console=Console(stderr=True))
        self._task = self._p.add_task(name, total=duration, rtf="-", falls=0)
        self._p.start()

    def update(self, t: float, wall: float, falls: int, force: bool = False) -> None:
        """Show simulated time ``t`` [s] after ``wall`` [s] of wall time and ``falls`` falls."""
        if not self.enabled:
            return
        now = time.perf_counter()
        if not force and now < self._next:
            return
        self._next = now + 0.2
        rtf = f"{t / wall:.2f}" if wall > 0 else "-"
        self._p.update(self._task, completed=t, rtf=rtf, falls=falls)

    def close(self) -> None:
        """Stop drawing (the last state stays on screen)."""
        if self.enabled:
            self._p.stop()


class SweepProgress:
    """Progress bar of a sweep: finished runs out of all, and how many fell.

    Does nothing when ``enabled`` is false.

    Args:
        enabled: show the bar.
        total: number of runs.
    """

    def __init__(self, enabled: bool, total: int) -> None:
        self.enabled = enabled
        if not enabled:
            return
        self._p = Progress(TextColumn("[bold]sweep"), BarColumn(), MofNCompleteColumn(),
                           TextColumn("falls {task.fields[falls]}"), TimeElapsedColumn(),
                           console=Console(stderr=True))
        self._task = self._p.add_task("sweep", total=total, falls=0)
        self._p.start()

    def update(self, completed: int, falls: int) -> None:
        """Show ``completed`` finished runs, ``falls`` of which fell."""
        if self.enabled:
            self._p.update(self._task, completed=completed, falls=falls)

    def close(self) -> None:
        """Stop drawing."""
        if self.enabled:
            self._p.stop()


__all__ = ["RunProgress", "SweepProgress"]
