"""Where dataset shards are computed: a local process pool or a Ray cluster.

Both executors run the same picklable job function ``fn(start, stop) -> arrays``
on each shard's index range and yield results as they complete (in any order);
the caller writes the shards, so the bytes on disk do not depend on the executor.
Closing the iterator early (an exception in the caller) cancels what has not started.

Ray without an address (:func:`ray_session`) starts a private instance on this machine that
listens on 127.0.0.1 only, with no dashboard and no usage reporting; an address (``"auto"``,
``"ray://head:10001"``, ``"head:6379"``) joins an existing cluster instead.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
from collections.abc import Callable, Generator, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any

__all__ = ["LOOPBACK", "ShardJob", "ray_session", "run_local", "run_ray"]

log = logging.getLogger(__name__)

ShardJob = tuple[int, int, int]
"""``(shard index, first sample index, one past the last sample index)``."""

JobFn = Callable[[int, int], Any]


def run_local(fn: JobFn, jobs: Sequence[ShardJob], workers: int | None = None
              ) -> Generator[tuple[ShardJob, Any], None, None]:
    """Run jobs in a local process pool (spawned workers), or in this process when ``workers == 1``.

    Args:
        fn: Picklable top-level callable ``fn(start, stop)``.
        jobs: The shards to compute.
        workers: Worker processes; ``None`` uses ``os.cpu_count()``.

    Yields:
        ``(job, fn(start, stop))`` as each job completes.

    Raises:
        ValueError: ``workers < 1``.
    """
    workers = workers or os.cpu_count() or 1
    if workers < 1:
        raise ValueError(f"workers = {workers} must be >= 1")
    if workers == 1 or len(jobs) <= 1:
        for job in jobs:
            yield job, fn(job[1], job[2])
        return
    context = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=context)
    try:
        pending = {pool.submit(fn, job[1], job[2]): job for job in jobs}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                yield pending.pop(future), future.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _call(fn: JobFn, start: int, stop: int) -> Any:
    return fn(start, stop)


LOOPBACK = "127.0.0.1"
"""The only address a local Ray instance listens on."""

_LOCAL_RAY_ENV = {
    "RAY_USAGE_STATS_ENABLED": "0",  # no usage reporting
    # Ray's "single machine" mode: its node address stays the loopback one instead of the
    # machine's routable address, so every server of the instance binds to 127.0.0.1.
    "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",
}


@contextlib.contextmanager
def _local_ray_settings() -> Iterator[None]:
    """Loopback-only, no-reporting settings for a local Ray instance, restored afterwards."""
    from ray._private import ray_constants

    saved_env = {key: os.environ.get(key) for key in _LOCAL_RAY_ENV}
    saved_cluster = ray_constants.ENABLE_RAY_CLUSTER
    os.environ.update(_LOCAL_RAY_ENV)  # for the processes Ray starts
    ray_constants.ENABLE_RAY_CLUSTER = False  # for this process, which read it at import
    try:
        yield
    finally:
        ray_constants.ENABLE_RAY_CLUSTER = saved_cluster
        for key, value in saved_env.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


@contextlib.contextmanager
def ray_session(address: str | None = None, **local_options: Any) -> Iterator[None]:
    """Join the running Ray session, connect to ``address``, or start a local instance.

    A local instance (``address`` None) is private to this process: it listens on 127.0.0.1
    only, without dashboard or usage reporting, and neither ``RAY_ADDRESS`` nor a cluster
    started with ``ray start`` is joined (pass ``address="auto"`` for those). A session this
    call opened is shut down on exit; a running one is left as it is.

    Args:
        address: Ray cluster address, e.g. ``"ray://head:10001"``, ``"head:6379"`` or ``"auto"``.
        local_options: Further ``ray.init`` arguments for a local instance (``num_cpus``,
            ``logging_level``, ...).

    Raises:
        ImportError: Ray is not installed (``pip install 'uav-swarm[distributed]'``).
    """
    try:
        import ray
    except ImportError as exc:
        raise ImportError("the Ray executor needs ray: pip install 'uav-swarm[distributed]'") from exc
    if ray.is_initialized():
        if address is not None:
            log.warning("Ray is already initialised; ignoring address %s", address)
        yield
        return
    if address is not None:
        ray.init(address=address, include_dashboard=False, logging_level=logging.WARNING)
    else:
        options = {"include_dashboard": False, "dashboard_host": LOOPBACK, "logging_level": logging.WARNING,
                   **local_options}
        with _local_ray_settings():
            ray.init(address="local", _node_ip_address=LOOPBACK, **options)
    try:
        yield
    finally:
        ray.shutdown()


def run_ray(fn: JobFn, jobs: Sequence[ShardJob], address: str | None = None
            ) -> Generator[tuple[ShardJob, Any], None, None]:
    """Run jobs as Ray tasks (one CPU each).

    Uses the running Ray session if there is one; otherwise connects to ``address``
    (``None``: start a local, loopback-only Ray instance, see :func:`ray_session`) and
    shuts the session down afterwards.

    Args:
        fn: Picklable callable ``fn(start, stop)``; its module must be importable by the workers.
        jobs: The shards to compute.
        address: Ray cluster address, e.g. ``"ray://head:10001"`` or ``"auto"``.

    Yields:
        ``(job, fn(start, stop))`` as each job completes.

    Raises:
        ImportError: Ray is not installed (``pip install 'uav-swarm[distributed]'``).
    """
    with ray_session(address):
        import ray

        remote = ray.remote(num_cpus=1)(_call)
        fn_ref = ray.put(fn)
        pending = {remote.remote(fn_ref, job[1], job[2]): job for job in jobs}
        try:
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    yield pending.pop(ref), ray.get(ref)
        finally:
            for ref in pending:
                ray.cancel(ref)
