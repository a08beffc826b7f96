"""Batch generation: many proven get-ups into a results store, on a local pool or a Ray cluster.

``tasks`` (deterministic ids; posture files), ``worker`` (one task), ``backends`` (local pool, Ray), ``store``
(the parquet table and trajectory files), ``run`` (run_batch), ``summary``, ``export``.
pyarrow (``robot-rise[batch]``) and Ray (``robot-rise[ray]``) are imported only when used.
"""

from robot_rise.batch.export import EXPORT_FORMATS, export_trajectories
from robot_rise.batch.run import BatchProgress, BatchSummary, run_batch
from robot_rise.batch.store import ROW_FIELDS, ResultStore
from robot_rise.batch.summary import summarize, summary_table
from robot_rise.batch.tasks import (
    BatchTask,
    PostureFile,
    make_tasks,
    options_key,
    read_posture_dir,
    task_id,
)

__all__ = [
    "BatchProgress", "BatchSummary", "BatchTask", "EXPORT_FORMATS", "ROW_FIELDS", "ResultStore",
    "PostureFile", "export_trajectories", "make_tasks", "options_key", "read_posture_dir", "run_batch", "summarize",
    "summary_table", "task_id",
]
