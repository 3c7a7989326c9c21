"""Where dataset shards are computed: a local process pool or a Ray cluster.

Both executors run the same picklable job function ``fn(start, stop) -> arrays``
on each shard's index range and yield results as they complete (in any order);
the caller writes the shards, so the bytes on disk do not depend on the executor.
Closing the iterator early (an exception in the caller) cancels what has not started.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any

__all__ = ["ShardJob", "run_local", "run_ray"]

log = logging.getLogger(__name__)

ShardJob = tuple[int, int, int]
"""``(shard index, first sample index, one past the last sample index)``."""

JobFn = Callable[[int, int], Any]


def run_local(fn: JobFn, jobs: Sequence[ShardJob], workers: int | None = None
              ) -> Iterator[tuple[ShardJob, Any]]:
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


def run_ray(fn: JobFn, jobs: Sequence[ShardJob], address: str | None = None
            ) -> Iterator[tuple[ShardJob, Any]]:
    """Run jobs as Ray tasks (one CPU each).

    Uses the running Ray session if there is one; otherwise connects to ``address``
    (``None``: start a local Ray instance) and shuts the session down afterwards.

    Args:
        fn: Picklable callable ``fn(start, stop)``; its module must be importable by the workers.
        jobs: The shards to compute.
        address: Ray cluster address, e.g. ``"ray://head:10001"`` or ``"auto"``.

    Yields:
        ``(job, fn(start, stop))`` as each job completes.

    Raises:
        ImportError: Ray is not installed (``pip install 'uav-swarm[distributed]'``).
    """
    try:
        import ray
    except ImportError as exc:
        raise ImportError("the Ray executor needs ray: pip install 'ray[default]'") from exc
    own_session = not ray.is_initialized()
    if own_session:
        ray.init(address=address, include_dashboard=False, logging_level=logging.WARNING)
    elif address is not None:
        log.warning("Ray is already initialised; ignoring address %s", address)
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
        if own_session:
            ray.shutdown()
