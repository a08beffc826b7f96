"""The results store of a batch: a directory with one table and one file per proven trajectory.

Layout::

    STORE/results.parquet            one row per finished task (ROW_FIELDS), merged
    STORE/parts/<id>.parquet         rows finished since the last merge, one file per task
    STORE/trajectories/<id>.json     the trajectory of each proven row (robot-rise/trajectory@1)
    STORE/.lock                      held (flock) by the batch writing the store

Every file is written to a temporary name (``*.tmp``, never ``*.parquet`` or ``*.json``) and
renamed, so a batch killed at any moment leaves whole files only: at most the tasks in flight are
lost, and the next run of the store removes the temporary files a killed one left. A proven
task's trajectory is written before its row, so a row never points at a missing file (a kill
between the two leaves a trajectory without a row; the task runs again and replaces it). Merging folds the parts into
``results.parquet`` (rewritten atomically), then deletes them; a kill between the two leaves a
part whose row is already merged, and reading drops such duplicates by id.

Parquet (via pyarrow, the ``batch`` extra) because it is the columnar format learning pipelines
read; it is imported only when a store is read or written.
"""

from __future__ import annotations

import contextlib
import logging
import os
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_rise.errors import RobotRiseError

__all__ = ["ROW_FIELDS", "ResultStore", "require_pyarrow"]

log = logging.getLogger(__name__)

# name -> pyarrow type name; None in a float column means "not measured" (no ensemble, not on the feet)
ROW_FIELDS: dict[str, str] = {
    "id": "string",
    "robot": "string",
    "robot_digest": "string",
    "scene": "string",
    "scene_digest": "string",  # SHA-256 of the scene's files
    "kind": "string",
    "seed": "int64",
    "index": "int64",
    "posture_file": "string",  # the --postures file ('' for a sampled posture)
    "posture_digest": "string",  # SHA-256 of its canonical content ('' for a sampled posture)
    "options": "string",  # the rise options that change a result (JSON, defaults filled in)
    "status": "string",  # proven | unproven | failed (the task crashed twice)
    "proven": "bool_",
    "reason": "string",  # why not proven, or the error of a failed task
    "duration_s": "float64",  # get-up duration of the returned trajectory [s]
    "peak_torque_ratio": "float64",
    "worst_tilt_deg": "float64",  # worst over the ensemble of model variants
    "worst_height_fraction": "float64",
    "worst_torque_ratio": "float64",
    "worst_zmp_margin_m": "float64",
    "ensemble_standing": "int64",
    "ensemble_size": "int64",
    "motion": "string",  # the library motion it connects to
    "attempts": "int64",  # candidates tried
    "plan_s": "float64",  # planning seconds summed over attempts
    "filter_s": "float64",  # filtering seconds summed over attempts
    "wall_s": "float64",  # the task's wall time [s]
    "tries": "int64",  # 1, or 2 when the first try crashed
    "trajectory": "string",  # path relative to the store, '' when not proven
}

RESULTS_FILE = "results.parquet"
PARTS_DIR = "parts"
TRAJECTORIES_DIR = "trajectories"
LOCK_FILE = ".lock"
TEMPORARY_SUFFIX = ".tmp"


def require_pyarrow():
    """Import pyarrow, or raise a one-line error naming the extra to install."""
    try:
        import pyarrow  # noqa: F401
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        raise RobotRiseError("the results store needs pyarrow", hint="pip install 'robot-rise[batch]'") from None
    return pyarrow


def _schema():
    pa = require_pyarrow()
    return pa.schema([(name, getattr(pa, kind)()) for name, kind in ROW_FIELDS.items()])


def _sort_key(row: dict[str, Any]) -> tuple:
    return (row["robot"], row["robot_digest"] or "", row["scene"], row["kind"], row["seed"], row["index"], row["id"])


@dataclass(frozen=True)
class ResultStore:
    """A results store directory (created on first write)."""

    root: Path

    def __post_init__(self) -> None:
        object.__setattr__(self, "root", Path(self.root))

    @property
    def results_path(self) -> Path:
        return self.root / RESULTS_FILE

    @property
    def parts_dir(self) -> Path:
        return self.root / PARTS_DIR

    @property
    def trajectories_dir(self) -> Path:
        return self.root / TRAJECTORIES_DIR

    def trajectory_path(self, task_id: str) -> Path:
        return self.trajectories_dir / f"{task_id}.json"

    @contextlib.contextmanager
    def writing(self) -> Iterator[ResultStore]:
        """Hold the store's lock while a batch writes it, and remove what a killed batch left half-written.

        The lock (``flock`` on ``STORE/.lock``) is released by the kernel when its process dies,
        however it dies; so a held lock means another batch is running on this store.

        Raises:
            RobotRiseError: another batch is writing the store.
        """
        import fcntl

        self.root.mkdir(parents=True, exist_ok=True)
        with open(self.root / LOCK_FILE, "a+") as f:
            try:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                f.seek(0)
                raise RobotRiseError(f"{self.root}: another batch is writing this store ({f.read().strip() or 'pid unknown'})",
                                     hint="wait for it to finish, or use another --out") from None
            f.seek(0), f.truncate(), f.write(f"pid {os.getpid()}\n"), f.flush()
            removed = self.remove_temporaries()
            if removed:
                log.info("%s: removed %d temporary files a killed batch left", self.root, removed)
            try:
                yield self
            finally:
                fcntl.flock(f, fcntl.LOCK_UN)

    def temporaries(self) -> list[Path]:
        """The temporary files in the store: those of writes in progress, or left by a killed batch."""
        dirs = [d for d in (self.root, self.parts_dir, self.trajectories_dir) if d.is_dir()]
        return sorted(p for d in dirs for p in d.glob(f"*{TEMPORARY_SUFFIX}"))

    def remove_temporaries(self) -> int:
        """Remove :meth:`temporaries` (only while holding :meth:`writing`); return how many."""
        paths = self.temporaries()
        for p in paths:
            p.unlink(missing_ok=True)
        return len(paths)

    def exists(self) -> bool:
        return self.results_path.exists() or self.parts_dir.is_dir()

    def _write_table(self, rows: list[dict[str, Any]], path: Path) -> None:
        import pyarrow.parquet as pq

        pa = require_pyarrow()
        table = pa.Table.from_pylist([{k: r.get(k) for k in ROW_FIELDS} for r in rows], schema=_schema())
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}{TEMPORARY_SUFFIX}")
        try:
            pq.write_table(table, tmp)
            os.replace(tmp, path)
        finally:
            if tmp.exists():
                tmp.unlink()

    def add(self, row: dict[str, Any]) -> None:
        """Record one finished task (its own part file, written atomically)."""
        self._write_table([row], self.parts_dir / f"{row['id']}.parquet")

    def _parts(self) -> list[Path]:
        return sorted(self.parts_dir.glob("*.parquet")) if self.parts_dir.is_dir() else []

    def rows(self) -> list[dict[str, Any]]:
        """Every recorded row, one per id, sorted by robot, scene, kind, seed, index.

        Raises:
            RobotRiseError: ``root`` holds no store.
        """
        import pyarrow.parquet as pq

        if not self.exists():
            raise RobotRiseError(f"{self.root} is not a results store (no {RESULTS_FILE})", hint="run robot-rise batch --out STORE first")
        by_id: dict[str, dict[str, Any]] = {}
        sources = ([self.results_path] if self.results_path.exists() else []) + self._parts()
        for path in sources:
            for row in pq.read_table(path).to_pylist():
                by_id.setdefault(row["id"], row)
        return sorted(by_id.values(), key=_sort_key)

    def done_ids(self) -> set[str]:
        """Ids of the tasks already recorded (an empty set for a new store)."""
        import pyarrow.parquet as pq

        ids: set[str] = set()
        if self.results_path.exists():
            ids.update(pq.read_table(self.results_path, columns=["id"]).column("id").to_pylist())
        for path in self._parts():
            ids.add(path.stem)
        return ids

    def merge(self) -> int:
        """Fold the parts into ``results.parquet``; return the number of rows."""
        parts = self._parts()
        if not parts and self.results_path.exists():
            import pyarrow.parquet as pq

            return pq.read_metadata(self.results_path).num_rows
        rows = self.rows()
        self._write_table(rows, self.results_path)
        for path in parts:
            path.unlink(missing_ok=True)
        log.info("merged %d parts into %s (%d rows)", len(parts), self.results_path, len(rows))
        return len(rows)
