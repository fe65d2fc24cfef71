"""One process-pool helper for everything that runs many independent tasks: sweeps,
``synth`` trials, replays.

:func:`map_tasks` runs ``fn(task)`` for every task, in this process (``workers`` ≤ 1) or in
a :class:`concurrent.futures.ProcessPoolExecutor` whose workers start with
:func:`init_worker` (one BLAS thread: the tasks' matrices are small and the workers
already use every core; optionally SIGINT ignored). Results come back in task order
(``ordered=True``) or as they finish, each passed to ``on_result`` as it arrives; the
outcome is a frozen :class:`PoolRun`. Ctrl-C in the parent cancels the queued tasks,
waits for the running ones, keeps their results and reports ``interrupted``.

Start methods: ``"spawn"`` gives clean workers (nothing inherited; ``fn``, the tasks and
the results must be picklable); ``"fork"`` (or ``None``, the platform default) lets the
workers inherit module-level state set before the call — a replay puts its model in a
module global, then calls :func:`map_tasks` (a fresh pool per call, so the workers see
the state of that call).
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os
import signal
from dataclasses import dataclass
from typing import Any, Callable, Generic, Sequence, TypeVar

from threadpoolctl import threadpool_limits

T = TypeVar("T")
R = TypeVar("R")

# the BLAS limit of this worker process (kept alive for the worker's lifetime)
_worker_limits: list = []


@dataclass(frozen=True)
class PoolRun(Generic[R]):
    """Outcome of :func:`map_tasks`.

    Attributes:
        results: results of the tasks that finished, in task order.
        indices: their positions in the task list (same order as ``results``).
        n_tasks: number of tasks submitted.
        interrupted: Ctrl-C (KeyboardInterrupt) in the parent, or ``stop_when`` held for
            a result: the remaining tasks were dropped.
    """

    results: tuple[R, ...]
    indices: tuple[int, ...]
    n_tasks: int
    interrupted: bool = False

    @property
    def complete(self) -> bool:
        """Every task finished and nothing was interrupted."""
        return not self.interrupted and len(self.results) == self.n_tasks


def worker_count(workers: int | None, n_tasks: int) -> int:
    """Worker processes for ``n_tasks`` tasks: ``workers`` (all CPUs if ``None``), at least
    one and at most ``n_tasks``."""
    n = (os.cpu_count() or 1) if workers is None else int(workers)
    return max(1, min(n, n_tasks))


def init_worker(blas_threads: int | None = 1, ignore_sigint: bool = False,
                initializer: Callable[..., None] | None = None, initargs: tuple = ()) -> None:
    """Start-up of a pool worker (the pool's ``initializer``).

    Args:
        blas_threads: BLAS/OpenMP threads of this process (``None``: leave as is).
        ignore_sigint: ignore SIGINT in this process (a Ctrl-C in a terminal reaches the
            whole process group; the parent decides what to do with it). A task may still
            install its own handler while it runs.
        initializer: called last with ``initargs`` (e.g. to load a model once per worker;
            must be picklable with the ``spawn`` start method).
        initargs: arguments of ``initializer``.
    """
    if ignore_sigint:
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        except ValueError:  # pragma: no cover - not the main thread
            pass
    if blas_threads is not None:
        _worker_limits.append(threadpool_limits(limits=int(blas_threads)))
    if initializer is not None:
        initializer(*initargs)


def map_tasks(fn: Callable[[T], R], tasks: Sequence[T], *, workers: int | None = None,
              ordered: bool = True, on_result: Callable[[R], None] | None = None,
              start_method: str | None = None, blas_threads: int | None = 1,
              ignore_sigint: bool = False, initializer: Callable[..., None] | None = None,
              initargs: tuple = (), stop_when: Callable[[R], bool] | None = None) -> PoolRun[R]:
    """Run ``fn(task)`` for every task, in a process pool or in this process.

    Args:
        fn: the task function (module-level, picklable).
        tasks: its arguments, one per task.
        workers: processes (:func:`worker_count`: all CPUs if ``None``, capped at the
            number of tasks); one runs every task in this process, in order, without
            :func:`init_worker`.
        ordered: call ``on_result`` in task order (a result waits for the earlier ones);
            else as each task finishes. :attr:`PoolRun.results` is in task order anyway.
        on_result: called in the parent with each result as it arrives.
        start_method: ``"spawn"``, ``"fork"``, ``"forkserver"`` or ``None`` (the platform
            default).
        blas_threads: BLAS threads per worker (:func:`init_worker`).
        ignore_sigint: workers ignore SIGINT (:func:`init_worker`).
        initializer: extra per-worker start-up, called with ``initargs``.
        initargs: arguments of ``initializer``.
        stop_when: in-process mode only: a task that caught the user's Ctrl-C itself (a
            run stops cleanly on SIGINT) says so in its result; when ``stop_when(result)``
            holds, the remaining tasks are not started and the run is ``interrupted``. In
            a pool the parent's own KeyboardInterrupt does that.

    Returns:
        :class:`PoolRun`.

    Raises:
        Exception: the first exception raised by a task (the queued tasks are cancelled,
            the running ones are waited for).
    """
    tasks = list(tasks)
    n_workers = worker_count(workers, len(tasks))
    if n_workers <= 1:
        return _map_here(fn, tasks, on_result, stop_when)
    ctx = mp.get_context(start_method) if start_method is not None else None
    done: dict[int, R] = {}

    def got(i: int, r: R) -> None:
        done[i] = r
        if on_result is not None:
            on_result(r)

    interrupted = False
    with cf.ProcessPoolExecutor(max_workers=n_workers, mp_context=ctx, initializer=init_worker,
                                initargs=(blas_threads, ignore_sigint, initializer,
                                          initargs)) as pool:
        futs = [pool.submit(fn, t) for t in tasks]
        index = {f: i for i, f in enumerate(futs)}
        handled: set = set()
        try:
            for f in (futs if ordered else cf.as_completed(futs)):
                r = f.result()
                handled.add(f)
                got(index[f], r)
        except KeyboardInterrupt:
            # queued tasks are dropped; running ones end (a run stops cleanly on SIGINT)
            interrupted = True
            _cancel(futs)
            for f in futs:
                if f in handled or f.cancelled():
                    continue
                try:
                    got(index[f], f.result())
                except Exception:  # a worker lost to the interrupt
                    pass
        except BaseException:
            _cancel(futs)
            raise
    return _outcome(done, len(tasks), interrupted)


def _map_here(fn: Callable[[T], R], tasks: list, on_result: Callable[[R], None] | None,
              stop_when: Callable[[R], bool] | None) -> PoolRun[R]:
    """:func:`map_tasks` in this process, in task order."""
    done: dict[int, R] = {}
    for i, t in enumerate(tasks):
        r = fn(t)
        done[i] = r
        if on_result is not None:
            on_result(r)
        if stop_when is not None and stop_when(r):
            return _outcome(done, len(tasks), True)
    return _outcome(done, len(tasks), False)


def _cancel(futs: Sequence[cf.Future]) -> None:
    for f in futs:
        f.cancel()


def _outcome(done: dict[int, Any], n_tasks: int, interrupted: bool) -> PoolRun:
    order = sorted(done)
    return PoolRun(tuple(done[i] for i in order), tuple(order), n_tasks, interrupted)


__all__ = ["PoolRun", "map_tasks", "worker_count", "init_worker"]
