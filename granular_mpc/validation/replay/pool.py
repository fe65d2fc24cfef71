"""Many replays at once: (model kind, variant) pairs over the same stance windows.

:class:`ReplayPool` forks worker processes that share the replayed model and the windows;
each task is one variant × a chunk of windows. The workers are forked once, at the first
:meth:`ReplayPool.run`, and serve every later run (the variants travel pickled with the
tasks); a run whose variants cannot be pickled (an effect defined in a closure) forks a
pool of its own that inherits them. ``REPLAYERS`` maps a model kind
(:data:`~.model.MODELS`) to its one-window replayer.
"""

from __future__ import annotations

import os
import pickle
import time as _time
from typing import Any, Callable, Mapping, Sequence

from ...parallel import WorkerPool, map_tasks
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
    """A chunk whose variant the forked worker inherited (``_SHARED["variants"]``)."""
    kind, vkey, indices = task
    return _run_sent_chunk((kind, vkey, _SHARED["variants"][vkey], indices))


def _run_sent_chunk(task: tuple) -> list:
    """A chunk whose variant was sent with the task."""
    kind, vkey, variant, indices = task
    model = _SHARED["model"]
    windows = _SHARED["windows"]
    fn = REPLAYERS[kind]
    return [(vkey, i, fn(model, windows[i], variant)) for i in indices]


def _picklable(obj: Any) -> bool:
    try:
        pickle.dumps(obj)
    except Exception:  # noqa: BLE001 - any pickling failure means "send by fork"
        return False
    return True


class ReplayPool:
    """Replays of many (model kind, variant) pairs over the same windows.

    Forks ``workers`` processes that share the model and the windows (set before the
    fork) once, at the first :meth:`run`; each task is one variant × a chunk of windows.
    With ``workers=1`` everything runs in this process. Use as a context manager (or call
    :meth:`close`) to end the workers.
    """

    def __init__(self, model: ReplayModel, windows: Sequence[StanceWindow], *,
                 workers: int | None = None) -> None:
        self.model = model
        self.windows = list(windows)
        n_cpu = os.cpu_count() or 1
        self.workers = max(1, min(n_cpu if workers is None else int(workers), len(self.windows)))
        self.n_replays = 0
        self.replay_time_s = 0.0
        self._workers: WorkerPool | None = None
        #: worker pools started so far (one, unless a run's variants cannot be pickled)
        self.forks = 0

    def __enter__(self) -> "ReplayPool":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """End the worker processes (a later :meth:`run` starts new ones)."""
        if self._workers is not None:
            self._workers.close()
            self._workers = None

    def _pool(self, kind: str) -> WorkerPool:
        """The persistent workers, forked now if none are running."""
        if self._workers is None or self._workers.closed:
            if kind == "granular" and self.model.plant == "compiled":
                self.model.compiled_plant()         # built once, inherited by the fork
            _SHARED.update(model=self.model, windows=self.windows)
            self._workers = WorkerPool(self.workers, start_method="fork")
            self.forks += 1
        return self._workers

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
            if _picklable(variants):
                tasks = [(kind, k, variants[k], ch) for k in variants for ch in chunks if ch]
                run = self._pool(kind).map(_run_sent_chunk, tasks)
            else:
                _SHARED.update(model=self.model, windows=self.windows, variants=variants)
                # a fresh pool: the workers inherit the current variants by fork
                tasks = [(kind, k, ch) for k in variants for ch in chunks if ch]
                run = map_tasks(_run_chunk, tasks, workers=self.workers, start_method="fork")
                self.forks += 1
            if run.interrupted:
                raise KeyboardInterrupt
            for part in run.results:
                for vkey, i, res in part:
                    results[vkey][i] = res
        self.n_replays += len(variants) * len(idx)
        self.replay_time_s += _time.perf_counter() - t0
        return results


__all__ = ["REPLAYERS", "ReplayPool"]
