"""Where batch tasks run: a local process pool (default) or a Ray cluster.

Both backends take the tasks and a picklable ``execute(task) -> row`` function and yield
``(task, row, error, tries)`` as tasks finish, in any order. A task that raises, or whose worker
dies, is retried once; then it is yielded with ``row=None`` and its error, and the batch goes on.

Local pool: a crash of one worker process breaks the whole ``ProcessPoolExecutor``, failing every
task in flight; the pool is rebuilt and each of those tasks is retried alone in a one-process pool,
so a second crash is the task's own and the innocent tasks still succeed. The workers die with the
batch's process (Linux: ``PR_SET_PDEATHSIG``), so a killed batch leaves no worker finishing its
task behind it and writing into the store a later run resumes.

Memory: a worker process is replaced by a fresh one after ``WORKER_TASKS`` tasks (the pool's
``max_tasks_per_child``, which needs ``spawn`` workers; Ray: ``max_calls``). A worker's resident
memory grows with the tasks it has run (OP3, --no-ensemble: peak 138 MiB after 25 tasks, 214 MiB
after 100, 251 MiB after 500 without replacement), so without this a worker's memory would grow
with N; with it, it is bounded whatever N (226 MiB at most over 1,000 postures). Starting a
worker and building its context costs about 2 s, about 1 % of its ``WORKER_TASKS`` tasks.

Ray: ``address="local"`` starts a local Ray cluster with ``jobs`` CPUs, any other address joins
an existing cluster (``ray.init(address=...)``). Ray is the engine our users run clusters with;
it is an optional extra (``robot-rise[ray]``). A task that crashes a Ray worker fails only itself.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from robot_rise.batch.tasks import BatchTask
from robot_rise.errors import RobotRiseError

__all__ = ["Finished", "default_jobs", "run_local", "run_ray", "MAX_TRIES", "WORKER_TASKS"]

log = logging.getLogger(__name__)

MAX_TRIES = 2  # a crashing task is tried once more, then recorded failed
IN_FLIGHT_PER_WORKER = 2  # tasks queued per worker: keeps workers busy, memory flat in N
WORKER_TASKS = 100  # tasks a worker process runs before a fresh one replaces it: its memory flat in N

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


def _die_with_parent(parent: int) -> None:
    """Worker initializer: ask the kernel to SIGKILL this worker when its parent dies (Linux; a no-op elsewhere)."""
    try:
        import ctypes
        import signal

        libc = ctypes.CDLL(None, use_errno=True)
        PR_SET_PDEATHSIG = 1
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # not Linux
        return
    try:  # the batch died before prctl (under forkserver the worker's parent is the server, not the batch)
        os.kill(parent, 0)
    except ProcessLookupError:
        os._exit(1)
    except PermissionError:
        pass


def _pool(workers: int) -> ProcessPoolExecutor:
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"), max_tasks_per_child=WORKER_TASKS,
                               initializer=_die_with_parent, initargs=(os.getpid(),))


def run_local(tasks: Iterable[BatchTask], execute: Callable[[BatchTask], dict[str, Any]], *, jobs: int) -> Iterator[Finished]:
    """Run the tasks on ``jobs`` local worker processes (see the module docstring for retries)."""
    if jobs < 1:
        raise RobotRiseError(f"--jobs must be at least 1, got {jobs}")
    pending = deque(tasks)
    retry: deque[BatchTask] = deque()
    pools = {1: _pool(jobs), 2: _pool(1)}  # by try: retries run alone
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
                        pools[tries] = _pool(jobs if tries == 1 else 1)
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
        remote = ray.remote(num_cpus=1, max_retries=0, max_calls=WORKER_TASKS)(_call)
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
