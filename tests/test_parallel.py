"""The process-pool helper: in-process and pool runs, order, interruption, errors, BLAS."""
from __future__ import annotations

import math
import os

import numpy as np  # noqa: F401  (loads BLAS in this process and its forks)
import pytest
from threadpoolctl import threadpool_info

from granular_mpc.parallel import PoolRun, WorkerPool, map_tasks, worker_count


def square(x: int) -> int:
    return x * x


def blas_threads(_: object) -> list[int]:
    """BLAS thread counts seen inside the worker (one per loaded BLAS library)."""
    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


def worker_pid(_: object) -> int:
    return os.getpid()


def test_worker_count_is_capped_by_tasks_and_at_least_one():
    assert worker_count(4, 2) == 2
    assert worker_count(2, 10) == 2
    assert worker_count(0, 3) == 1
    assert worker_count(None, 1) == 1
    assert worker_count(None, 10_000) == (os.cpu_count() or 1)
    assert worker_count(3, 0) == 1


def test_one_worker_runs_in_this_process_in_order():
    seen = []
    res = map_tasks(worker_pid, range(3), workers=1, on_result=seen.append)
    assert res.results == (os.getpid(),) * 3 and seen == list(res.results)
    assert res.indices == (0, 1, 2) and res.complete and not res.interrupted


@pytest.mark.parametrize("ordered", [True, False])
def test_pool_results_come_back_in_task_order(ordered):
    seen = []
    res = map_tasks(square, list(range(7)), workers=2, ordered=ordered, start_method="fork",
                    on_result=seen.append)
    assert isinstance(res, PoolRun) and res.complete
    assert res.results == tuple(x * x for x in range(7)) and res.indices == tuple(range(7))
    assert sorted(seen) == sorted(res.results)
    if ordered:
        assert seen == list(res.results)


def test_worker_pool_keeps_its_workers_across_maps():
    with WorkerPool(2, start_method="fork") as pool:
        a = pool.map(worker_pid, range(6))
        b = pool.map(square, [3, 4])
        c = pool.map(worker_pid, range(6))
    assert a.complete and b.results == (9, 16) and c.complete
    assert os.getpid() not in a.results + c.results
    assert len(set(a.results) | set(c.results)) <= 2          # the same two processes
    assert pool.closed


def test_worker_pool_closes_on_a_failing_task():
    pool = WorkerPool(2, start_method="fork")
    with pytest.raises(ValueError):
        pool.map(math.sqrt, [4.0, -1.0, 9.0])
    assert pool.closed


def test_pool_runs_in_other_processes_with_spawn():
    res = map_tasks(worker_pid, range(4), workers=2, start_method="spawn")
    assert len(res.results) == 4 and os.getpid() not in res.results


def test_pool_workers_use_one_blas_thread():
    res = map_tasks(blas_threads, range(2), workers=2, start_method="fork")
    for counts in res.results:
        assert counts and all(n == 1 for n in counts)


def test_stop_when_drops_the_remaining_tasks_in_process():
    seen = []
    res = map_tasks(square, [1, 2, 3, 4], workers=1, on_result=seen.append,
                    stop_when=lambda r: r >= 4)
    assert res.results == (1, 4) and seen == [1, 4]
    assert res.interrupted and not res.complete and res.n_tasks == 4


def test_a_task_error_is_raised_in_the_parent():
    with pytest.raises(ValueError):
        map_tasks(math.sqrt, [4.0, -1.0, 9.0], workers=2, start_method="fork")
    with pytest.raises(ValueError):
        map_tasks(math.sqrt, [4.0, -1.0], workers=1)
