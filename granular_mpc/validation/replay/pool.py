"""Many replays at once: (model kind, variant) pairs over the same stance windows.

:class:`ReplayPool` forks worker processes that share the replayed model and the windows;
each task is one variant × a chunk of windows. ``REPLAYERS`` maps a model kind
(:data:`~.model.MODELS`) to its one-window replayer.
"""

from __future__ import annotations

import os
import time as _time
from typing import Any, Callable, Mapping, Sequence

from ...parallel import map_tasks
from ..prepare import StanceWindow
from .granular import replay_granular
from .model import ReplayModel, Variant
from .planar import replay_planar
from .rigid import replay_rigid

REPLAYERS: dict[str, Callable] = {"granular": replay_granular, "rigid": replay_rigid,
                                  "planar": replay_planar}
"""Model kind → ``fn(model, window, variant) -> outputs`` (one stance window)."""

#: what the forked workers inherit (set just before the fork)
_SHARED: dict = {}


def _run_chunk(task: tuple) -> list:
    kind, vkey, indices = task
    model = _SHARED["model"]
    windows = _SHARED["windows"]
    variant = _SHARED["variants"][vkey]
    fn = REPLAYERS[kind]
    return [(vkey, i, fn(model, windows[i], variant)) for i in indices]


class ReplayPool:
    """Replays of many (model kind, variant) pairs over the same windows.

    Forks ``workers`` processes that share the model and the windows (set before the
    fork); each task is one variant × a chunk of windows. With ``workers=1`` everything
    runs in this process.
    """

    def __init__(self, model: ReplayModel, windows: Sequence[StanceWindow], *,
                 workers: int | None = None) -> None:
        self.model = model
        self.windows = list(windows)
        n_cpu = os.cpu_count() or 1
        self.workers = max(1, min(n_cpu if workers is None else int(workers), len(self.windows)))
        self.n_replays = 0
        self.replay_time_s = 0.0

    def __enter__(self) -> "ReplayPool":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Nothing to release: each :meth:`run` uses a fresh pool (kept for ``with``)."""

    def run(self, variants: Mapping[Any, Variant], kind: str = "granular") -> dict:
        """``{variant key: [per-window output dict]}`` for every variant."""
        t0 = _time.perf_counter()
        variants = dict(variants)
        idx = list(range(len(self.windows)))
        results: dict = {k: [None] * len(idx) for k in variants}
        if self.workers <= 1 or len(idx) < 4:
            for k, var in variants.items():
                fn = REPLAYERS[kind]
                for i in idx:
                    results[k][i] = fn(self.model, self.windows[i], var)
        else:
            # windows are sorted by cost (length) and dealt round-robin
            order = sorted(idx, key=lambda i: -self.windows[i].n)
            n_chunks = self.workers * 2
            chunks = [order[c::n_chunks] for c in range(n_chunks)]
            _SHARED.update(model=self.model, windows=self.windows, variants=variants)
            # a fresh pool per call: the workers inherit the current variants by fork
            tasks = [(kind, k, ch) for k in variants for ch in chunks if ch]
            run = map_tasks(_run_chunk, tasks, workers=self.workers, start_method="fork")
            if run.interrupted:
                raise KeyboardInterrupt
            for part in run.results:
                for vkey, i, res in part:
                    results[vkey][i] = res
        self.n_replays += len(variants) * len(idx)
        self.replay_time_s += _time.perf_counter() - t0
        return results


__all__ = ["REPLAYERS", "ReplayPool"]
