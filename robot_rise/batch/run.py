"""Run a batch: make the tasks, skip those already in the store, run the rest, record each row as it finishes.

Postures are sampled (``n`` per robot, scene and kind) or taken from a directory of posture files
(``postures``): every file is read and checked before anything runs, and a file that is not a
posture of the batch's robots refuses the batch (one line per bad file), so an hour-long batch
never stops, or silently shrinks, on a typo. A posture that is readable but cannot be risen from
(e.g. in collision in the scene) is a row with status ``unproven`` and its reason.
"""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_rise.batch.backends import default_jobs, run_local, run_ray
from robot_rise.batch.store import ResultStore, require_pyarrow
from robot_rise.batch.tasks import make_tasks, read_posture_dir
from robot_rise.batch.worker import execute_task, failed_row
from robot_rise.errors import RobotRiseError
from robot_rise.model import load_robot
from robot_rise.sampling import LYING_KINDS

__all__ = ["BatchProgress", "BatchSummary", "run_batch", "MERGE_EVERY"]

log = logging.getLogger(__name__)

MERGE_EVERY = 64  # parts folded into results.parquet this often (and at the end)


@dataclass(frozen=True)
class BatchProgress:
    """Where a running batch is: tasks finished this run, of those to run, and how fast."""

    done: int
    total: int
    proven: int
    failed: int
    elapsed_s: float

    @property
    def rate_per_s(self) -> float:
        return self.done / self.elapsed_s if self.elapsed_s > 0 else 0.0

    @property
    def eta_s(self) -> float:
        return (self.total - self.done) / self.rate_per_s if self.rate_per_s > 0 else float("nan")


@dataclass(frozen=True)
class BatchSummary:
    """What a run of :func:`run_batch` did.

    Attributes:
        store: the results store directory.
        tasks: tasks of the batch.
        skipped: already in the store (done by an earlier run).
        ran: tasks run now.
        proven: of those run now, proven.
        failed: of those run now, crashed twice.
        rows: rows in the store after the run.
        wall_s: wall time of the run [s].
        backend: "local (K jobs)" or "ray ADDRESS".
    """

    store: Path
    tasks: int
    skipped: int
    ran: int
    proven: int
    failed: int
    rows: int
    wall_s: float
    backend: str


def run_batch(
    *,
    n: int | None = None,
    seed: int,
    out: str | Path,
    postures: str | Path | None = None,
    kinds: Sequence[str] = LYING_KINDS,
    scenes: Sequence[str] = ("flat",),
    robots: Sequence[str | None] = (None,),
    jobs: int | None = None,
    ray: str | None = None,
    progress: Callable[[BatchProgress], None] | None = None,
    rise_options: dict[str, Any] | None = None,
    execute: Callable[..., dict[str, Any]] = execute_task,
) -> BatchSummary:
    """Rise from ``n`` sampled postures per robot, scene and kind, or from the posture files of
    ``postures``; record every outcome in the store ``out``.

    Tasks already in the store are skipped, so running the same batch again resumes it. Task ids
    cover the robot and library files, the scene's files, the seed, the posture and the rise
    options (see :mod:`robot_rise.batch.tasks`): other options are other tasks, never skipped.

    Args:
        n: postures per robot, scene and kind (sampled); exclusive with ``postures``.
        seed: batch seed (postures and planner).
        out: the results store directory (created if missing).
        postures: a directory of posture@1 files (``*.json``): each is risen from once per scene,
            for the robot it names; ``kinds`` does not apply.
        kinds: lying kinds (sampled postures).
        scenes: shipped scene names or MJCF paths.
        robots: robot directories (None: the embedded OP3-class robot).
        jobs: local worker processes (default: all cores); with ``ray="local"``, the CPUs of the local cluster.
        ray: None for the local pool, "local" to start a local Ray cluster, or a cluster address to join.
        progress: called after each finished task.
        rise_options: keyword arguments of ``rise`` that change results (``RESULT_OPTIONS``: budget_s,
            candidates, retries, filter_config); default the product's. Part of every task id.
        execute: the task function (internal: tests inject crashes); must be picklable.

    Raises:
        RobotRiseError: bad inputs (bad posture files: one line each, nothing run), pyarrow missing,
            Ray missing when ``ray`` is set, or another batch writing the same store.
    """
    require_pyarrow()
    t0 = time.monotonic()
    if (n is None) == (postures is None):
        raise RobotRiseError("a batch takes either --n N (sampled postures) or --postures DIR, not both" if n is not None
                             else "a batch needs --n N (sampled postures) or --postures DIR")
    loaded = [load_robot(r) for r in robots]
    files = read_posture_dir(postures, loaded) if postures is not None else None
    tasks = make_tasks(loaded, n=n, seed=seed, kinds=kinds, scenes=scenes, postures=files, rise_options=rise_options)
    store = ResultStore(Path(out))
    with store.writing():
        return _run(store, tasks, t0=t0, jobs=jobs, ray=ray, progress=progress, rise_options=rise_options, execute=execute)


def _run(store: ResultStore, tasks, *, t0: float, jobs, ray, progress, rise_options, execute) -> BatchSummary:
    done_ids = store.done_ids()
    todo = [t for t in tasks if t.id not in done_ids]
    others = len(done_ids - {t.id for t in tasks})
    if others:
        log.warning("%s holds %d rows of other tasks (other postures, seed, options, or changed robot, library or scene "
                    "files); they are kept", store.root, others)
    store.parts_dir.mkdir(parents=True, exist_ok=True)
    fn = functools.partial(execute, store_root=str(store.root.resolve()), rise_options=rise_options)  # Ray workers may run elsewhere
    jobs = jobs or default_jobs()
    if ray is None:
        finished = run_local(todo, fn, jobs=min(jobs, max(1, len(todo))))
        backend = f"local ({jobs} jobs)"
    else:
        finished = run_ray(todo, fn, address=ray, jobs=jobs)
        backend = f"ray {ray}"
    ran = proven = failed = since_merge = 0
    try:
        for task, row, error, tries in finished:
            if row is None:
                row = failed_row(task, error, tries=tries)
                failed += 1
            row["tries"] = tries
            store.add(row)
            ran += 1
            proven += bool(row["proven"])
            since_merge += 1
            if since_merge >= MERGE_EVERY:
                store.merge()
                since_merge = 0
            if progress is not None:
                progress(BatchProgress(ran, len(todo), proven, failed, time.monotonic() - t0))
    finally:
        finished.close()
    rows = store.merge()
    log.info("batch of %d tasks: %d skipped, %d run (%d proven, %d failed)", len(tasks), len(tasks) - len(todo), ran, proven, failed)
    return BatchSummary(store.root, len(tasks), len(tasks) - len(todo), ran, proven, failed, rows, time.monotonic() - t0, backend)
