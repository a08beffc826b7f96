"""What one batch task does in a worker process: take or sample its posture, rise, write the trajectory, return its row.

The worker keeps one ``RiseContext`` per robot directory and scene (the checker, library and
tree cost a fraction of a second each to build) and holds no trajectory after returning: memory
stays flat however many tasks a worker runs.

A worker is one core's worth of work: its ensemble replays run one after another (one thread),
and the batch's parallelism is its workers (``--jobs``, or Ray's CPUs). The variants' verdicts do
not depend on the thread count, so neither does a row.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from robot_rise.batch.store import ROW_FIELDS, TRAJECTORIES_DIR
from robot_rise.batch.tasks import BatchTask, posture_seed

__all__ = ["execute_task", "failed_row"]

_CONTEXTS: dict[tuple[str, str], Any] = {}  # per worker process: (robot_dir, scene) -> RiseContext
ENSEMBLE_THREADS = 1  # per worker: the workers are the parallelism


def _context(task: BatchTask):
    key = (task.robot_dir, task.scene)
    if key in _CONTEXTS:
        return _CONTEXTS[key]
    import dataclasses

    from robot_rise.proof.ensemble import EnsembleReplayer
    from robot_rise.model import load_robot
    from robot_rise.rise import RiseContext

    class WorkerContext(RiseContext):
        """A RiseContext whose ensemble replays on ENSEMBLE_THREADS threads (built on first use, as the base's)."""

        def ensemble(self) -> EnsembleReplayer:
            if self._ensemble is None:
                self._ensemble = EnsembleReplayer(self.robot, self.scene, threads=ENSEMBLE_THREADS)
            return self._ensemble

    base = RiseContext.build(load_robot(task.robot_dir), task.scene)
    _CONTEXTS[key] = WorkerContext(**{f.name: getattr(base, f.name) for f in dataclasses.fields(base)})
    return _CONTEXTS[key]


def _base_row(task: BatchTask) -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(ROW_FIELDS)
    row.update(id=task.id, robot=task.robot, robot_digest=task.robot_digest, scene=task.scene, kind=task.kind, seed=task.seed, index=task.index,
               scene_digest=task.scene_digest, posture_file=task.posture_file, posture_digest=task.posture_digest, options=task.options)
    row.update(reason="", motion="", trajectory="", proven=False, tries=1)
    return row


def failed_row(task: BatchTask, error: str, *, tries: int, wall_s: float | None = None) -> dict[str, Any]:
    """The row of a task that crashed ``tries`` times (the last error as its reason)."""
    row = _base_row(task)
    row.update(status="failed", reason=error, tries=tries, wall_s=wall_s)
    return row


def execute_task(task: BatchTask, *, store_root: str, rise_options: dict[str, Any] | None = None) -> dict[str, Any]:
    """Rise from the task's posture (its posture file's, or sampled); write its trajectory when proven; return its row.

    An expected failure (no proof, a posture that cannot be sampled or is invalid) is a row with
    status ``unproven`` and its reason. Anything else raises, and the backend retries the task.

    Args:
        task: the task.
        store_root: the results store directory (the trajectory goes to its ``trajectories/``).
        rise_options: keyword arguments of :func:`robot_rise.rise.rise` (default: the product's).
    """
    import json

    from robot_rise.errors import RobotRiseError
    from robot_rise.posture import posture_from_dict
    from robot_rise.rise import RiseOptions, rise
    from robot_rise.sampling import sample_lying
    from robot_rise.trajectory import write_trajectory

    t0 = time.perf_counter()
    row = _base_row(task)
    context = _context(task)
    try:
        if task.posture:  # a posture file's
            posture = posture_from_dict(json.loads(task.posture), context.robot, where=task.posture_file or task.id)
        else:
            posture = sample_lying(context.robot, task.kind, 1, posture_seed(task.seed, task.index), scene=task.scene).postures[0]  # type: ignore[arg-type]
        result = rise(context.robot, posture, RiseOptions(scene=task.scene, seed=task.seed, **(rise_options or {})), context=context)
    except RobotRiseError as e:  # an expected failure of this posture: a status, not a crash
        row.update(status="unproven", reason=f"{type(e).__name__}: {e}", wall_s=time.perf_counter() - t0)
        return row
    proof = result.proof
    row.update(
        status="proven" if result.proven else "unproven",
        proven=bool(result.proven),
        reason=result.reason,
        attempts=len(result.attempts),
        plan_s=sum(a.seconds.get("plan", 0.0) for a in result.attempts),
        filter_s=sum(a.seconds.get("filter", 0.0) for a in result.attempts),
        motion=str(result.trajectory.report.get("motion", "")) if result.trajectory is not None else "",
    )
    if proof is not None:
        row.update(
            duration_s=proof.duration_s,
            peak_torque_ratio=proof.peak_torque_ratio,
            worst_tilt_deg=proof.worst_tilt_deg,
            worst_height_fraction=proof.worst_height_fraction,
            worst_torque_ratio=proof.worst_torque_ratio,
            worst_zmp_margin_m=proof.worst_zmp_margin_m,
            ensemble_standing=proof.ensemble_standing if proof.ensemble else None,
            ensemble_size=len(proof.ensemble),
        )
    if result.proven and result.trajectory is not None:
        rel = f"{TRAJECTORIES_DIR}/{task.id}.json"
        write_trajectory(Path(store_root) / rel, result.trajectory.with_report(batch_task=task.id))
        row["trajectory"] = rel
    row["wall_s"] = time.perf_counter() - t0
    return row
