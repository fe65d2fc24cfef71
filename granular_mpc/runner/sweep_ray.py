"""The Ray backend of sweeps: the same tasks as Ray tasks (one CPU each)."""

from __future__ import annotations

from typing import Any, Callable, Sequence

from ..exceptions import ConfigError


def ray_map(fn: Callable[[Any], Any], payloads: Sequence[Any], workers: int | None,
            address: str | None, on_result: Callable[[Any], None]) -> bool:
    """Run ``fn(payload)`` for every payload as Ray tasks; results to ``on_result`` as they
    finish.

    Args:
        fn: the task function.
        payloads: its arguments.
        workers: CPUs of a local Ray instance started here (all if ``None``).
        address: join a running cluster (``auto``, ``ray://host:10001``) instead.
        on_result: called with each result.

    Returns:
        ``False`` if interrupted (Ctrl-C: pending tasks are cancelled), else ``True``.

    Raises:
        ConfigError: Ray is not installed.
    """
    try:
        import ray  # optional dependency (extra ``cluster``)
    except ImportError:
        raise ConfigError("Ray is not installed: pip install 'granular_mpc[cluster]' "
                          "(or pip install 'ray[default]')", key="--backend", value="ray") from None
    started = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"log_to_driver": False, "include_dashboard": False}
        if address:
            kwargs["address"] = address
        elif workers:
            kwargs["num_cpus"] = workers
        ray.init(**kwargs)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(fn)
        refs = [remote.remote(p) for p in payloads]
        pending = list(refs)
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    on_result(ray.get(ref))
        except KeyboardInterrupt:
            for ref in pending:
                ray.cancel(ref, force=False)
            return False
        return True
    finally:
        if started:
            ray.shutdown()


__all__ = ["ray_map"]
