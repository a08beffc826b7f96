"""Batch generation into a results store (robot_rise.batch, robot-rise batch / export).

Tasks rise with the nominal filter only (no ensemble, the CLI's --no-ensemble) to stay fast; the
product runs the ensemble. The kill test runs the CLI in a child process and SIGKILLs it twice
while a task is in flight (about 15 s on an idle 2-core machine).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from robot_rise.batch import ResultStore, make_tasks, run_batch
from robot_rise.batch.tasks import read_posture_dir
from robot_rise.batch.worker import execute_task, failed_row
from robot_rise.bench.batch import alive, check_store, process_tree
from robot_rise.cli import main
from robot_rise.errors import RobotRiseError
from robot_rise.filter import FilterConfig
from robot_rise.proof import ProofConfig
from robot_rise.model import load_robot
from robot_rise.posture import posture_to_dict, stand_posture
from robot_rise.trajectory import read_trajectory

pytest.importorskip("pyarrow")

FAST = {"filter_config": FilterConfig(proof=ProofConfig(ensemble=False))}
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
    tasks = make_tasks([load_robot(None)], n=1, seed=3, kinds=("supine", "prone"), rise_options=FAST)
    assert summary.ran == 2 and summary.rows == 2
    assert sorted(r["id"] for r in rows) == sorted(t.id for t in tasks)
    assert {r["options"] for r in rows} == {tasks[0].options} and '"ensemble":false' in tasks[0].options
    assert {r["kind"] for r in rows} == {"supine", "prone"}
    proven = [r for r in rows if r["proven"]]
    assert proven, "no task was proven"
    for r in proven:
        tr = read_trajectory(out / r["trajectory"])
        assert tr.report["proven"] and tr.report["batch_task"] == r["id"]
        assert r["duration_s"] > 0 and 0 < r["peak_torque_ratio"] <= 1
    assert sorted(p.stem for p in (out / "trajectories").glob("*.json")) == sorted(r["id"] for r in proven)
    assert not list((out / "parts").iterdir()), "parts are merged at the end"


def test_task_ids_depend_on_every_input_and_on_nothing_else(tmp_path):
    robot = load_robot(None)
    a = make_tasks([robot], n=2, seed=0, kinds=("left",))
    assert [t.id for t in a] == [t.id for t in make_tasks([robot], n=2, seed=0, kinds=("left",))]
    # naming a default explicitly is the same task
    assert [t.id for t in a] == [t.id for t in make_tasks([robot], n=2, seed=0, kinds=("left",), rise_options={"budget_s": 30.0, "filter_config": FilterConfig()})]
    others = [
        make_tasks([robot], n=2, seed=1, kinds=("left",)),
        make_tasks([robot], n=2, seed=0, kinds=("right",)),
        make_tasks([robot], n=2, seed=0, kinds=("left",), scenes=("slope",)),
        make_tasks([robot], n=2, seed=0, kinds=("left",), rise_options=FAST),
        make_tasks([robot], n=2, seed=0, kinds=("left",), rise_options={"filter_config": FilterConfig(proof=ProofConfig(envelope_margin=0.2))}),
        make_tasks([robot], n=2, seed=0, kinds=("left",), rise_options={"budget_s": 10.0}),
        make_tasks([robot], n=2, seed=0, kinds=("left",), rise_options={"candidates": 1}),
        make_tasks([robot], n=2, seed=0, kinds=("left",), rise_options={"composed": True}),
    ]
    # an option added later leaves the ids of stores written before it as they were, at its default
    assert '"composed"' not in a[0].options
    assert [t.id for t in a] == [t.id for t in make_tasks([robot], n=2, seed=0, kinds=("left",), rise_options={"composed": False})]
    assert len({t.id for t in a} | {t.id for tasks in others for t in tasks}) == 2 * (1 + len(others))
    # the scene's content, not only its name: a copy of flat.xml that differs by one byte is another scene
    flat = (Path(robot.directory).parent.parent / "scenes" / "flat.xml").read_text()
    scene = tmp_path / "scene.xml"
    scene.write_text(flat)
    (before,) = make_tasks([robot], n=1, seed=0, kinds=("left",), scenes=(str(scene),))
    scene.write_text(flat.replace("</mujoco>", "<!-- edited --></mujoco>"))
    (after,) = make_tasks([robot], n=1, seed=0, kinds=("left",), scenes=(str(scene),))
    assert before.scene_digest != after.scene_digest and before.id != after.id
    with pytest.raises(RobotRiseError, match="not a batch option"):
        make_tasks([robot], n=1, seed=0, rise_options={"progress": print})


def test_a_composed_batch_proves_by_composition_and_the_whole_check_agrees(tmp_path):
    from robot_rise.proof import COMPOSED_KEY, check

    out = tmp_path / "composed"
    summary = run_batch(out=out, n=1, seed=3, kinds=("prone",), rise_options={"composed": True}, jobs=1)
    (row,) = ResultStore(out).rows()
    assert summary.ran == 1 and row["proven"], row["reason"]
    tr = read_trajectory(out / row["trajectory"])
    assert COMPOSED_KEY in tr.report and tr.report["connecting_frame"] == 0
    assert check(load_robot(None), tr).proven  # every variant replayed whole: the same verdict


def test_a_rerun_with_other_options_runs_again_instead_of_skipping(tmp_path):
    out = tmp_path / "s"
    assert run_batch(out=out, execute=_cheap, jobs=1, **BATCH).ran == 2
    assert run_batch(out=out, execute=_cheap, jobs=1, **BATCH).skipped == 2
    other = {**BATCH, "rise_options": {"filter_config": FilterConfig(proof=ProofConfig(ensemble=False, envelope_margin=0.2))}}
    summary = run_batch(out=out, execute=_cheap, jobs=1, **other)
    assert (summary.skipped, summary.ran, summary.rows) == (0, 2, 4)


def _write_posture(path, p, **extra):
    obj = {**posture_to_dict(p), **extra}
    path.write_text(json.dumps(obj, indent=2))


def test_posture_files_are_tasks_named_by_their_content(tmp_path):
    robot = load_robot(None)
    d = tmp_path / "postures"
    d.mkdir()
    stand = stand_posture(robot)
    _write_posture(d / "a.json", stand)
    (d / "same_as_a.json").write_text(json.dumps(posture_to_dict(stand)))  # other spelling, same content
    _write_posture(d / "b.json", stand.with_joints({robot.joint_names[0]: 0.1}))
    (d / "notes.txt").write_text("not a posture file")
    files = read_posture_dir(d, [robot])
    assert [f.name for f in files] == ["a.json", "b.json", "same_as_a.json"]
    tasks = make_tasks([robot], seed=0, postures=files)
    assert len(tasks) == 2 and [t.posture_file for t in tasks] == ["a.json", "b.json"]
    (d / "b.json").rename(d / "renamed.json")  # the name is not part of the id
    renamed = make_tasks([robot], seed=0, postures=read_posture_dir(d, [robot]))
    assert {t.id for t in renamed} == {t.id for t in tasks}
    # run: the upright stand posture is a row with its reason (or proven), the batch goes on
    summary = run_batch(out=tmp_path / "s", postures=d, seed=0, jobs=1, execute=_cheap, rise_options=FAST)
    rows = ResultStore(tmp_path / "s").rows()
    assert summary.ran == 2 and sorted(r["posture_file"] for r in rows) == ["a.json", "renamed.json"]
    assert all(r["posture_digest"] and r["scene_digest"] for r in rows)


def test_bad_posture_files_refuse_the_batch_before_anything_runs_one_line_each(tmp_path, capsys):
    robot = load_robot(None)
    d = tmp_path / "postures"
    d.mkdir()
    _write_posture(d / "good.json", stand_posture(robot))
    (d / "broken.json").write_text('{"format": ')
    _write_posture(d / "other_robot.json", stand_posture(robot), robot="bez1")
    _write_posture(d / "far_out.json", stand_posture(robot).with_joints({robot.joint_names[0]: 99.0}))
    store = tmp_path / "s"
    assert main(["batch", "--postures", str(d), "--out", str(store)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert "3 of 4 files are not postures" in err[0] and "nothing was run" in err[0]
    assert [line.split(":")[0].strip() for line in err[1:4]] == [str(d / n) for n in ("broken.json", "far_out.json", "other_robot.json")]
    assert not store.exists()


def test_two_batches_never_write_one_store_at_once(tmp_path):
    store = ResultStore(tmp_path / "s")
    with store.writing(), pytest.raises(RobotRiseError, match="another batch is writing"):
        run_batch(out=store.root, execute=_cheap, jobs=1, **BATCH)
    assert run_batch(out=store.root, execute=_cheap, jobs=1, **BATCH).ran == 2


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


@pytest.mark.slow
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


KILLED = {"n": 2, "seed": 5, "kinds": ("supine", "prone", "left")}  # 6 postures


def _rows_recorded(store: Path) -> int:
    return len(ResultStore(store).done_ids()) if store.exists() else 0


def _sigkill_after_rows(store: Path, rows: int) -> None:
    """Start `robot-rise batch` on one worker; SIGKILL it (the batch process only) once ``rows`` rows are recorded."""
    argv = [sys.executable, "-m", "robot_rise", "batch", "--n", str(KILLED["n"]), "--seed", str(KILLED["seed"]),
            "--kinds", ",".join(KILLED["kinds"]), "--jobs", "1", "--no-ensemble", "--out", str(store)]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 90
        workers: set[int] = set()
        while _rows_recorded(store) < rows:
            assert proc.poll() is None, "the batch finished before it was killed"
            assert time.monotonic() < deadline, "no row recorded in 90 s"
            workers.update(process_tree(proc.pid))
            time.sleep(0.05)
        workers.update(process_tree(proc.pid))
        assert workers, "no worker process seen"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    deadline = time.monotonic() + 10
    while any(alive(p) for p in workers):
        assert time.monotonic() < deadline, "a worker outlived the killed batch"
        time.sleep(0.05)
    # what the kill left: whole files only (a write in progress is a *.tmp file, never a result)
    s = ResultStore(store)
    for path in s.trajectories_dir.glob("*.json"):
        json.loads(path.read_text())
    for path in s.parts_dir.glob("*.parquet"):
        import pyarrow.parquet as pq

        pq.read_table(path)
    leftovers = [p for p in store.rglob("*") if p.is_file() and p.name != ".lock" and p.suffix not in (".json", ".parquet", ".tmp")]
    assert not leftovers, leftovers


@pytest.mark.slow
def test_a_batch_sigkilled_twice_mid_run_and_resumed_has_the_rows_of_an_uninterrupted_one(tmp_path):
    """The CLI in a child process, SIGKILLed while a task is in flight (twice), then run again to the end."""
    store = tmp_path / "killed"
    _sigkill_after_rows(store, 1)
    first = _rows_recorded(store)
    _sigkill_after_rows(store, first + 1)
    assert first < _rows_recorded(store) < 6
    done = subprocess.run([sys.executable, "-m", "robot_rise", "batch", "--n", str(KILLED["n"]), "--seed", str(KILLED["seed"]),
                           "--kinds", ",".join(KILLED["kinds"]), "--jobs", "1", "--no-ensemble", "--out", str(store)],
                          check=False, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    ref = tmp_path / "ref"
    run_batch(out=ref, jobs=2, rise_options=FAST, **KILLED)  # the CLI's --no-ensemble is FAST: the same task ids
    check = check_store(store, 6)
    assert check["ok"], check  # 6 rows, no duplicate id, no part or temporary file left, one readable trajectory per proven row
    assert _stable(ResultStore(store).rows()) == _stable(ResultStore(ref).rows())
    for r in ResultStore(ref).rows():
        if r["proven"]:
            np.testing.assert_array_equal(read_trajectory(store / r["trajectory"]).q, read_trajectory(ref / r["trajectory"]).q)


def _cheap_row(task):
    row = failed_row(task, "", tries=1)
    row["status"] = "unproven"
    return row


def _cheap(task, *, store_root, rise_options):
    return _cheap_row(task)


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


@pytest.mark.slow
def test_ray_in_local_mode_gives_the_rows_of_the_local_pool(reference, tmp_path):
    pytest.importorskip("ray")
    out = tmp_path / "ray"
    summary = run_batch(out=out, jobs=2, ray="local", **BATCH)
    assert summary.ran == 2 and summary.backend == "ray local"
    assert _stable(ResultStore(out).rows()) == _stable(ResultStore(reference[0]).rows())
