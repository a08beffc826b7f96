"""Batch generation into a results store (robot_rise.batch, robot-rise batch / export).

Tasks rise with the nominal filter only (no ensemble) to stay fast; the product runs the ensemble.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from robot_rise.batch import ResultStore, make_tasks, run_batch, task_id
from robot_rise.batch.worker import execute_task, failed_row
from robot_rise.cli import main
from robot_rise.filter import FilterConfig
from robot_rise.model import load_robot
from robot_rise.trajectory import read_trajectory

pytest.importorskip("pyarrow")

FAST = {"filter_config": FilterConfig(ensemble=False)}
BATCH = dict(n=1, seed=3, kinds=("supine", "prone"), rise_options=FAST)
VOLATILE = ("wall_s", "plan_s", "filter_s")  # timings differ from run to run


def _stable(rows):
    return [{k: v for k, v in r.items() if k not in VOLATILE} for r in rows]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted batch of two tasks on two local workers."""
    out = tmp_path_factory.mktemp("batch") / "ref"
    summary = run_batch(out=out, jobs=2, **BATCH)
    return out, summary


def test_a_batch_writes_one_row_per_task_and_a_trajectory_file_per_proven_row(reference):
    out, summary = reference
    rows = ResultStore(out).rows()
    digest = load_robot(None).digest()
    assert summary.ran == 2 and summary.rows == 2
    assert sorted(r["id"] for r in rows) == sorted(task_id(digest, "flat", k, 3, 0) for k in ("supine", "prone"))
    assert {r["kind"] for r in rows} == {"supine", "prone"}
    proven = [r for r in rows if r["proven"]]
    assert proven, "no task was proven"
    for r in proven:
        tr = read_trajectory(out / r["trajectory"])
        assert tr.report["proven"] and tr.report["batch_task"] == r["id"]
        assert r["duration_s"] > 0 and 0 < r["peak_torque_ratio"] <= 1
    assert sorted(p.stem for p in (out / "trajectories").glob("*.json")) == sorted(r["id"] for r in proven)
    assert not list((out / "parts").iterdir()), "parts are merged at the end"


def test_task_ids_depend_on_every_input_and_on_nothing_else():
    robot = load_robot(None)
    a = make_tasks([robot], n=2, seed=0, kinds=("left",))
    assert [t.id for t in a] == [t.id for t in make_tasks([robot], n=2, seed=0, kinds=("left",))]
    assert len({t.id for t in a + make_tasks([robot], n=2, seed=1, kinds=("left",)) + make_tasks([robot], n=2, seed=0, kinds=("right",))}) == 6


def test_running_the_same_batch_again_skips_every_done_task(reference, tmp_path):
    out = tmp_path / "again"
    shutil.copytree(reference[0], out)
    summary = run_batch(out=out, jobs=2, **BATCH)
    assert (summary.skipped, summary.ran, summary.rows) == (2, 0, 2)
    assert len(ResultStore(out).rows()) == 2


class _Abort(Exception):
    """Stands for the batch being killed after its first task."""


def _abort(progress):
    raise _Abort


def test_a_batch_aborted_midway_and_resumed_has_the_rows_of_an_uninterrupted_one(reference, tmp_path):
    out = tmp_path / "resumed"
    with pytest.raises(_Abort):
        run_batch(out=out, jobs=1, progress=_abort, **BATCH)
    assert len(ResultStore(out).rows()) == 1, "the finished task is recorded, the others are not"
    assert not list(out.rglob("*.tmp")), "no half-written file"
    summary = run_batch(out=out, jobs=1, **BATCH)
    assert (summary.skipped, summary.ran) == (1, 1)
    ref_rows = ResultStore(reference[0]).rows()
    assert _stable(ResultStore(out).rows()) == _stable(ref_rows)
    for r in ref_rows:
        if r["proven"]:
            np.testing.assert_array_equal(read_trajectory(out / r["trajectory"]).q, read_trajectory(reference[0] / r["trajectory"]).q)


def _cheap_row(task):
    row = failed_row(task, "", tries=1)
    row["status"] = "unproven"
    return row


def _prone_kills_its_worker(task, *, store_root, rise_options):
    if task.kind == "prone":
        os._exit(3)
    return _cheap_row(task)


def _supine_raises_once(task, *, store_root, rise_options):
    marker = Path(store_root) / f"tried-{task.id}"
    if task.kind == "supine" and not marker.exists():
        marker.touch()
        raise RuntimeError("flaky worker")
    return _cheap_row(task)


def test_a_task_that_kills_its_worker_is_retried_once_then_recorded_failed(tmp_path):
    summary = run_batch(out=tmp_path / "s", jobs=2, execute=_prone_kills_its_worker, **BATCH)
    rows = {r["kind"]: r for r in ResultStore(tmp_path / "s").rows()}
    assert summary.failed == 1
    assert (rows["prone"]["status"], rows["prone"]["tries"]) == ("failed", 2)
    assert "worker process died" in rows["prone"]["reason"]
    assert (rows["supine"]["status"], rows["supine"]["tries"]) == ("unproven", 1) or rows["supine"]["tries"] == 2


def test_a_task_that_raises_once_succeeds_on_its_retry(tmp_path):
    summary = run_batch(out=tmp_path / "s", jobs=1, execute=_supine_raises_once, **BATCH)
    rows = {r["kind"]: r for r in ResultStore(tmp_path / "s").rows()}
    assert summary.failed == 0
    assert (rows["supine"]["status"], rows["supine"]["tries"]) == ("unproven", 2)
    assert rows["prone"]["tries"] == 1


def test_batch_summary_json_counts_the_rows_of_the_store(reference, capsys):
    assert main(["batch", "summary", str(reference[0]), "--json"]) == 0
    groups = json.loads(capsys.readouterr().out)
    rows = ResultStore(reference[0]).rows()
    assert [g["kind"] for g in groups] == ["prone", "supine", "all"]
    assert groups[-1]["tasks"] == 2 and groups[-1]["proven"] == sum(r["proven"] for r in rows)


@pytest.mark.parametrize("fmt", ["csv", "npz", "parquet"])
def test_export_writes_every_proven_trajectory_as_one_table(reference, tmp_path, fmt, capsys):
    out = tmp_path / f"all.{fmt}"
    assert main(["export", str(reference[0]), "--format", fmt, "--out", str(out)]) == 0
    proven = [r for r in ResultStore(reference[0]).rows() if r["proven"]]
    if fmt == "npz":
        data = np.load(out)
        ids, t, q, names = data["id"], data["t"], data["q"], list(data["joint_names"])
    else:
        import pyarrow.csv as pcsv
        import pyarrow.parquet as pq

        table = (pcsv.read_csv(out) if fmt == "csv" else pq.read_table(out)).to_pydict()
        first = read_trajectory(reference[0] / proven[0]["trajectory"])
        names = list(first.joint_names)
        ids, t, q = np.array(table["id"]), np.array(table["t"]), np.column_stack([table[n] for n in names])
    for r in proven:
        tr = read_trajectory(reference[0] / r["trajectory"])
        mask = ids == r["id"]
        assert names == list(tr.joint_names)
        np.testing.assert_allclose(t[mask], tr.t, atol=1e-6)
        np.testing.assert_allclose(q[mask], tr.q, atol=1e-6)
    assert mask.sum() < len(ids) or len(proven) == 1


def test_ray_in_local_mode_gives_the_rows_of_the_local_pool(reference, tmp_path):
    pytest.importorskip("ray")
    out = tmp_path / "ray"
    summary = run_batch(out=out, jobs=2, ray="local", **BATCH)
    assert summary.ran == 2 and summary.backend == "ray local"
    assert _stable(ResultStore(out).rows()) == _stable(ResultStore(reference[0]).rows())
