"""One process-pool helper for everything that runs many independent tasks: sweeps,
``synth`` trials, replays.

:func:`map_tasks` runs ``fn(task)`` for every task, in this process (``workers`` ≤ 1) or in
a :class:`concurrent.futures.ProcessPoolExecutor` whose workers start with
:func:`init_worker` (one BLAS thread: the tasks' matrices are small and the workers
already use every core; optionally SIGINT ignored). Results come back in task order
(``ordered=True``) or as they finish, each passed to ``on_result`` as it arrives; the
outcome is a frozen :class:`PoolRun`. Ctrl-C in the parent (or, with
``handle_signals``, SIGINT / SIGTERM to the parent alone) cancels the queued tasks, sets
the workers' stop flag (:func:`stop_requested`; a task not yet started returns at once),
forwards the signal to the workers (``forward_signals``: a run stops cleanly), waits for
the running tasks (a second signal, or ``grace_s``, kills them), keeps their results and
reports ``interrupted`` with the signal's name.

No orphans: on Linux every worker asks the kernel for SIGKILL when its parent dies
(``PR_SET_PDEATHSIG``), so a parent killed outright (SIGKILL) takes its workers along.

Start methods: ``"spawn"`` gives clean workers (nothing inherited; ``fn``, the tasks and
the results must be picklable); ``"fork"`` (or ``None``, the platform default) lets the
workers inherit module-level state set before the call — a replay puts its model in a
module global, then calls :func:`map_tasks` (a fresh pool per call, so the workers see
the state of that call). :class:`WorkerPool` keeps its workers for several calls (they
see the state of the first call; later calls send what changes with the tasks).
"""

from __future__ import annotations

import concurrent.futures as cf
import ctypes
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Generic, Sequence, TypeVar

from threadpoolctl import threadpool_limits

from .exceptions import Interrupted

T = TypeVar("T")
R = TypeVar("R")

# the BLAS limit of this worker process (kept alive for the worker's lifetime)
_worker_limits: list = []
# the pool's stop flag, in a worker process (set by init_worker)
_worker_stop: list = []
_PR_SET_PDEATHSIG = 1


@dataclass(frozen=True)
class PoolRun(Generic[R]):
    """Outcome of :func:`map_tasks`.

    Attributes:
        results: results of the tasks that finished, in task order.
        indices: their positions in the task list (same order as ``results``).
        n_tasks: number of tasks submitted.
        interrupted: Ctrl-C (KeyboardInterrupt) in the parent, SIGINT / SIGTERM with
            ``handle_signals``, or ``stop_when`` held for a result: the remaining tasks
            were dropped.
        signal: the signal that interrupted (``"SIGINT"``, ``"SIGTERM"``), or ``""``.
        killed: indices of tasks whose worker was killed (a second signal, or the grace
            period ran out).
    """

    results: tuple[R, ...]
    indices: tuple[int, ...]
    n_tasks: int
    interrupted: bool = False
    signal: str = ""
    killed: tuple[int, ...] = ()

    @property
    def complete(self) -> bool:
        """Every task finished and nothing was interrupted."""
        return not self.interrupted and len(self.results) == self.n_tasks


def worker_count(workers: int | None, n_tasks: int) -> int:
    """Worker processes for ``n_tasks`` tasks: ``workers`` (all CPUs if ``None``), at least
    one and at most ``n_tasks``."""
    n = (os.cpu_count() or 1) if workers is None else int(workers)
    return max(1, min(n, n_tasks))


def stop_requested() -> bool:
    """In a pool worker: the parent was interrupted and wants no new work (a task checks
    this before starting something long). ``False`` outside a pool."""
    return bool(_worker_stop) and _worker_stop[0].is_set()


def _die_with_parent(parent_pid: int | None) -> None:
    """Linux: SIGKILL this process when its parent dies (no orphan workers)."""
    if parent_pid is None or not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # pragma: no cover - no prctl
        return
    if os.getppid() != parent_pid:     # the parent died before prctl
        os._exit(1)


def init_worker(blas_threads: int | None = 1, ignore_sigint: bool = False,
                initializer: Callable[..., None] | None = None, initargs: tuple = (),
                stop_event: Any = None, parent_pid: int | None = None) -> None:
    """Start-up of a pool worker (the pool's ``initializer``).

    Args:
        blas_threads: BLAS/OpenMP threads of this process (``None``: leave as is).
        ignore_sigint: ignore SIGINT and SIGTERM in this process (a Ctrl-C in a terminal
            reaches the whole process group; the parent decides what to do with it). A
            task may still install its own handlers while it runs (a run does).
        initializer: called last with ``initargs`` (e.g. to load a model once per worker;
            must be picklable with the ``spawn`` start method).
        initargs: arguments of ``initializer``.
        stop_event: the pool's stop flag (:func:`stop_requested`).
        parent_pid: the parent's PID: this worker is killed when the parent dies.
    """
    _die_with_parent(parent_pid)
    if stop_event is not None:
        _worker_stop[:] = [stop_event]
    if ignore_sigint:
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                signal.signal(sig, signal.SIG_IGN)
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
              initargs: tuple = (), stop_when: Callable[[R], bool] | None = None,
              handle_signals: bool = False, forward_signals: bool = False,
              grace_s: float = 120.0) -> PoolRun[R]:
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
    pool = WorkerPool(n_workers, start_method=start_method, blas_threads=blas_threads,
                      ignore_sigint=ignore_sigint, initializer=initializer, initargs=initargs)
    return pool.map(fn, tasks, ordered=ordered, on_result=on_result,
                    handle_signals=handle_signals, forward_signals=forward_signals,
                    grace_s=grace_s, close=True)


class WorkerPool:
    """A process pool whose workers serve several :meth:`map` calls (started once: a
    ``fork`` costs ≈ 0.1 s per call on a loaded 2-core machine).

    The workers start (``fork``: inherit this process's state) at the first
    :meth:`map`; the tasks and results are pickled. An interrupted or failed
    :meth:`map` shuts the pool down. Use as a context manager, or call :meth:`close`.

    Args:
        workers: worker processes (at least 2; :func:`map_tasks` runs one in-process).
        start_method, blas_threads, ignore_sigint, initializer, initargs: as in
            :func:`map_tasks`.
    """

    def __init__(self, workers: int, *, start_method: str | None = None,
                 blas_threads: int | None = 1, ignore_sigint: bool = False,
                 initializer: Callable[..., None] | None = None, initargs: tuple = ()) -> None:
        ctx = mp.get_context(start_method) if start_method is not None else None
        self.workers = int(workers)
        self._stop = (ctx or mp).Event()
        self._pool = cf.ProcessPoolExecutor(
            max_workers=self.workers, mp_context=ctx, initializer=init_worker,
            initargs=(blas_threads, ignore_sigint, initializer, initargs, self._stop,
                      os.getpid()))
        self.closed = False

    def __enter__(self) -> "WorkerPool":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Wait for the workers to exit (queued tasks are cancelled)."""
        self.closed = True
        self._pool.shutdown(wait=True, cancel_futures=True)

    def map(self, fn: Callable[[T], R], tasks: Sequence[T], *, ordered: bool = True,
            on_result: Callable[[R], None] | None = None, handle_signals: bool = False,
            forward_signals: bool = False, grace_s: float = 120.0,
            close: bool = False) -> PoolRun[R]:
        """``fn(task)`` for every task in the workers (arguments as in :func:`map_tasks`;
        ``close``: shut the pool down afterwards).

        Raises:
            Exception: the first exception raised by a task (the pool is shut down).
        """
        tasks = list(tasks)
        pool = self._pool
        done: dict[int, R] = {}

        def got(i: int, r: R) -> None:
            done[i] = r
            if on_result is not None:
                on_result(r)

        futs: list[cf.Future] = []
        index: dict[cf.Future, int] = {}
        handled: set = set()
        killed: list[int] = []
        signame = ""
        with _ParentSignals(handle_signals):
            try:
                try:
                    futs = [pool.submit(fn, t) for t in tasks]
                    index = {f: i for i, f in enumerate(futs)}
                    for f in (futs if ordered else cf.as_completed(futs)):
                        r = f.result()
                        handled.add(f)
                        got(index[f], r)
                except KeyboardInterrupt as exc:
                    # queued tasks are dropped; running ones end (a run stops cleanly)
                    signame = getattr(exc, "signame", "SIGINT")
                    self._stop.set()
                    pool.shutdown(wait=False, cancel_futures=True)
                    close = True
                    killed = _drain(futs, index, handled, got, signame, forward_signals,
                                    grace_s)
                except BaseException:
                    self._stop.set()
                    pool.shutdown(wait=False, cancel_futures=True)
                    close = True
                    raise
            finally:
                if close:
                    self.close()
        return _outcome(done, len(tasks), bool(signame), signame, killed)


class _ParentSignals:
    """SIGINT / SIGTERM → :class:`Interrupted` in the parent while a pool runs."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled and threading.current_thread() is threading.main_thread()
        self._old: dict[int, Any] = {}

    def __enter__(self) -> "_ParentSignals":
        if self.enabled:
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._raise)
        return self

    @staticmethod
    def _raise(signum, frame) -> None:
        raise Interrupted(signum)

    def __exit__(self, *exc) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


def _workers() -> list:
    """This process's live worker processes (``multiprocessing`` children)."""
    return [p for p in mp.active_children() if p.pid is not None]


def _drain(futs: list, index: dict, handled: set, got: Callable, signame: str,
           forward: bool, grace_s: float) -> list[int]:
    """After an interruption: collect the results of the running tasks, forwarding the
    signal to the workers; a second signal or ``grace_s`` kills them. Returns the
    indices of the tasks lost with a killed worker."""
    sig = getattr(signal, signame, signal.SIGINT)
    deadline = time.monotonic() + grace_s
    next_forward = 0.0
    pending = [f for f in futs if f not in handled and not f.cancelled()]
    kill = False
    while pending and not kill:
        try:
            if forward and time.monotonic() >= next_forward:
                for p in _workers():
                    _send(p.pid, sig)
                next_forward = time.monotonic() + 2.0
            done, _ = cf.wait(pending, timeout=0.2)
            for f in done:
                handled.add(f)
                try:
                    got(index[f], f.result())
                except (Exception, cf.CancelledError):  # a worker lost to the interrupt
                    pass
            pending = [f for f in pending if f not in done and not f.cancelled()]
            kill = time.monotonic() > deadline
        except KeyboardInterrupt:          # a second signal: no more waiting
            kill = True
    if not pending:
        return []
    for p in _workers():
        _send(p.pid, signal.SIGKILL)
    for f in pending:
        try:
            got(index[f], f.result(timeout=10.0))
            handled.add(f)
        except BaseException:  # noqa: BLE001 - the worker is gone
            pass
    return sorted(index[f] for f in pending if f not in handled)


def _send(pid: int, sig: int) -> None:
    try:
        os.kill(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


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


def _outcome(done: dict[int, Any], n_tasks: int, interrupted: bool, signame: str = "",
             killed: Sequence[int] = ()) -> PoolRun:
    order = sorted(done)
    return PoolRun(tuple(done[i] for i in order), tuple(order), n_tasks, interrupted,
                   signame, tuple(killed))


__all__ = ["PoolRun", "WorkerPool", "map_tasks", "worker_count", "init_worker",
           "stop_requested"]
