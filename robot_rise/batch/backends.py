"""Where batch tasks run: a local process pool (default) or a Ray cluster.

Both backends take the tasks and a picklable ``execute(task) -> row`` function and yield
``(task, row, error, tries)`` as tasks finish, in any order. A task that raises, or whose worker
dies, is retried once; then it is yielded with ``row=None`` and its error, and the batch goes on.

Local pool: a crash of one worker process breaks the whole ``ProcessPoolExecutor``, failing every
task in flight; the pool is rebuilt and each of those tasks is retried alone in a one-process pool,
so a second crash is the task's own and the innocent tasks still succeed.

Ray: ``address="local"`` starts a local Ray cluster with ``jobs`` CPUs, any other address joins
an existing cluster (``ray.init(address=...)``). Ray is the engine our users run clusters with;
it is an optional extra (``robot-rise[ray]``). A task that crashes a Ray worker fails only itself.
"""

from __future__ import annotations

import logging
import os
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from robot_rise.batch.tasks import BatchTask
from robot_rise.errors import RobotRiseError

__all__ = ["Finished", "default_jobs", "run_local", "run_ray", "MAX_TRIES"]

log = logging.getLogger(__name__)

MAX_TRIES = 2  # a crashing task is tried once more, then recorded failed
IN_FLIGHT_PER_WORKER = 2  # tasks queued per worker: keeps workers busy, memory flat in N

Finished = tuple[BatchTask, "dict[str, Any] | None", str, int]
"""(task, its row or None when it failed, the error of the last try or '', tries)."""


def default_jobs() -> int:
    """All the cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _describe(e: BaseException) -> str:
    if isinstance(e, BrokenProcessPool):
        return "worker process died (BrokenProcessPool)"
    return f"{type(e).__name__}: {e}".strip()


def run_local(tasks: Iterable[BatchTask], execute: Callable[[BatchTask], dict[str, Any]], *, jobs: int) -> Iterator[Finished]:
    """Run the tasks on ``jobs`` local worker processes (see the module docstring for retries)."""
    if jobs < 1:
        raise RobotRiseError(f"--jobs must be at least 1, got {jobs}")
    pending = deque(tasks)
    retry: deque[BatchTask] = deque()
    pools = {1: ProcessPoolExecutor(max_workers=jobs), 2: ProcessPoolExecutor(max_workers=1)}  # by try: retries run alone
    inflight: dict[Future, tuple[BatchTask, int, ProcessPoolExecutor]] = {}
    try:
        while pending or retry or inflight:
            while pending and sum(t == 1 for _, t, _ in inflight.values()) < IN_FLIGHT_PER_WORKER * jobs:
                task = pending.popleft()
                inflight[pools[1].submit(execute, task)] = (task, 1, pools[1])
            if retry and not any(t == 2 for _, t, _ in inflight.values()):
                task = retry.popleft()
                inflight[pools[2].submit(execute, task)] = (task, 2, pools[2])
            done, _ = wait(list(inflight), return_when=FIRST_COMPLETED)
            for fut in done:
                task, tries, pool = inflight.pop(fut)
                try:
                    row = fut.result()
                except Exception as e:  # noqa: BLE001 - any crash of a task is recorded, never fatal
                    error = _describe(e)
                    if isinstance(e, BrokenProcessPool) and pools[tries] is pool:  # rebuild it once
                        pool.shutdown(wait=False, cancel_futures=True)
                        pools[tries] = ProcessPoolExecutor(max_workers=jobs if tries == 1 else 1)
                    if tries < MAX_TRIES:
                        log.warning("task %s crashed (%s); retrying it alone", task.id, error)
                        retry.append(task)
                    else:
                        log.warning("task %s crashed again (%s); recorded failed", task.id, error)
                        yield task, None, error, tries
                    continue
                yield task, row, "", tries
    finally:
        for pool in pools.values():
            pool.shutdown(wait=False, cancel_futures=True)


def _call(execute: Callable[[BatchTask], dict[str, Any]], task: BatchTask) -> dict[str, Any]:
    """A Ray task: Ray wraps functions, not ``functools.partial`` objects."""
    return execute(task)


def _import_ray():
    try:
        import ray
    except ImportError:
        raise RobotRiseError("--ray needs Ray, which is not installed", hint="pip install 'robot-rise[ray]'") from None
    return ray


def run_ray(tasks: Iterable[BatchTask], execute: Callable[[BatchTask], dict[str, Any]], *, address: str, jobs: int | None = None) -> Iterator[Finished]:
    """Run the tasks on Ray: ``address`` "local" starts a local cluster of ``jobs`` CPUs, else joins ``address``."""
    ray = _import_ray()
    started = False
    if not ray.is_initialized():
        if address == "local":
            ray.init(num_cpus=jobs or default_jobs(), include_dashboard=False, log_to_driver=False, logging_level=logging.WARNING)
        else:
            try:
                ray.init(address=address, log_to_driver=False, logging_level=logging.WARNING)
            except (ConnectionError, RuntimeError, ValueError) as e:
                raise RobotRiseError(f"cannot join the Ray cluster at {address}: {e}", hint="start one with `ray start --head`, or pass --ray local") from None
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(_call)
        fn = ray.put(execute)
        capacity = max(1, int(ray.cluster_resources().get("CPU", 1)))
        pending = deque(tasks)
        inflight: dict[Any, tuple[BatchTask, int]] = {}
        while pending or inflight:
            while pending and len(inflight) < IN_FLIGHT_PER_WORKER * capacity:
                task = pending.popleft()
                inflight[remote.remote(fn, task)] = (task, 1)
            ready, _ = ray.wait(list(inflight), num_returns=1)
            for ref in ready:
                task, tries = inflight.pop(ref)
                try:
                    yield task, ray.get(ref), "", tries
                except Exception as e:  # noqa: BLE001 - RayTaskError wraps the task's own exception
                    error = _describe(getattr(e, "cause", None) or e)
                    if tries < MAX_TRIES:
                        log.warning("task %s crashed (%s); retrying it", task.id, error)
                        inflight[remote.remote(fn, task)] = (task, tries + 1)
                    else:
                        yield task, None, error, tries
    finally:
        if started:
            ray.shutdown()
