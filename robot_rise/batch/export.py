"""Export a store's proven trajectories as one table: the layout learning pipelines read.

One row per trajectory sample: ``id`` (the task), ``t`` [s], one column per joint target [rad]
named after the joint, and, when the trajectory has planned root poses, ``root_x``, ``root_y``,
``root_z`` [m], ``root_qw``, ``root_qx``, ``root_qy``, ``root_qz`` (NaN in rows without one).

Parquet and CSV are streamed one trajectory at a time (memory flat in the store's size); NPZ holds
arrays ``id`` (T,), ``t`` (T,), ``q`` (T, n_joints), ``root`` (T, 7) and ``joint_names`` (n_joints,),
built in memory. The output is written to a temporary file, then renamed.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from robot_rise.batch.store import ResultStore, require_pyarrow
from robot_rise.errors import RobotRiseError
from robot_rise.trajectory import read_trajectory

__all__ = ["EXPORT_FORMATS", "ROOT_COLUMNS", "export_trajectories"]

EXPORT_FORMATS = ("parquet", "csv", "npz")
ROOT_COLUMNS = ("root_x", "root_y", "root_z", "root_qw", "root_qx", "root_qy", "root_qz")


def _blocks(store: ResultStore) -> Iterator[tuple[str, tuple[str, ...], np.ndarray, np.ndarray, np.ndarray]]:
    """(id, joint names, t (T,), q (T, n), root (T, 7)) of each proven row, in the store's order."""
    names: tuple[str, ...] | None = None
    for row in store.rows():
        if not row["proven"] or not row["trajectory"]:
            continue
        tr = read_trajectory(store.root / row["trajectory"])
        if names is None:
            names = tr.joint_names
        elif tr.joint_names != names:
            raise RobotRiseError(f"{row['id']} has other joints than the first trajectory ({tr.robot}): one table needs one joint set",
                                 hint="export a store of one robot")
        root = tr.root if tr.root is not None else np.full((len(tr.t), 7), np.nan)
        yield row["id"], names, tr.t, tr.q, root


def _arrow_table(pa, task_id: str, names: tuple[str, ...], t: np.ndarray, q: np.ndarray, root: np.ndarray):
    cols = {"id": pa.array([task_id] * len(t), pa.string()), "t": pa.array(t, pa.float64())}
    cols.update({name: pa.array(q[:, j], pa.float64()) for j, name in enumerate(names)})
    cols.update({name: pa.array(root[:, j], pa.float64()) for j, name in enumerate(ROOT_COLUMNS)})
    return pa.table(cols)


def export_trajectories(store_dir: str | os.PathLike[str], fmt: str, out: str | os.PathLike[str]) -> int:
    """Write the proven trajectories of the store at ``store_dir`` to ``out``; return the number of trajectories.

    Raises:
        RobotRiseError: an unknown format, no store, or trajectories of different joint sets.
    """
    if fmt not in EXPORT_FORMATS:
        raise RobotRiseError(f"unknown export format {fmt!r}; choose from {', '.join(EXPORT_FORMATS)}")
    store = ResultStore(Path(store_dir))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.{uuid.uuid4().hex}.tmp")
    count = 0
    try:
        if fmt == "npz":
            ids, ts, qs, roots, names = [], [], [], [], ()
            for task_id, names, t, q, root in _blocks(store):
                ids += [task_id] * len(t)
                ts.append(t), qs.append(q), roots.append(root)
                count += 1
            n = len(names)
            with open(tmp, "wb") as f:
                np.savez_compressed(
                    f, id=np.array(ids, dtype=str), t=np.concatenate(ts) if ts else np.zeros(0),
                    q=np.concatenate(qs) if qs else np.zeros((0, n)), root=np.concatenate(roots) if roots else np.zeros((0, 7)),
                    joint_names=np.array(names, dtype=str),
                )
        else:
            pa = require_pyarrow()
            import pyarrow.csv as pcsv
            import pyarrow.parquet as pq

            writer = None
            try:
                for block in _blocks(store):
                    table = _arrow_table(pa, *block)
                    if writer is None:
                        writer = pq.ParquetWriter(tmp, table.schema) if fmt == "parquet" else pcsv.CSVWriter(str(tmp), table.schema)
                    writer.write_table(table)
                    count += 1
            finally:
                if writer is not None:
                    writer.close()
            if writer is None:  # no proven trajectory: an empty table with the id and t columns
                empty = pa.table({"id": pa.array([], pa.string()), "t": pa.array([], pa.float64())})
                pq.write_table(empty, tmp) if fmt == "parquet" else pcsv.write_csv(empty, str(tmp))
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    return count
