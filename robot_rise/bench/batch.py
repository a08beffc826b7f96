"""Benchmark of ``robot-rise batch`` (issue 18): throughput, Ray vs the local pool, kill-and-resume, memory.

Every batch runs as a child process (``python -m robot_rise batch ... --json``), watched from here:
its wall time is the batch's own (``run.wall_s``: pools, workers' context builds, every task; not the
interpreter's start), its memory the peak resident set (``VmHWM``) of the batch process and of each
of its worker processes, and its CPU time that of the batch process and its workers, both polled
from ``/proc`` (Linux). On a machine shared with other work the wall-time figures depend on what
else runs; the CPU share (CPU time / (wall time x workers)) says how much of its cores a run got,
and postures per CPU-hour what a core of its own would do. Sections:

- ``throughput``: the same postures on 1 and on 2 local workers; postures per hour per core and the
  ratio of the two throughputs; the rows of the two stores compared (deterministic columns).
- ``ray``: the same postures on a simulated Ray cluster (``ray.cluster_utils.Cluster``: two nodes of
  one CPU each, so two Ray worker processes), joined by address as a user joins a real cluster;
  rows compared with the 2-worker local pool's.
- ``resume``: N postures uninterrupted, then the same N in a fresh store SIGKILLed at two random
  moments (uniform in 10-45 % of the uninterrupted wall time after each start) and run a third time
  to the end; checks: N rows, no duplicate id in ``results.parquet``, no part or temporary file left,
  every trajectory file readable and one per proven row, no worker outliving a kill, and the
  deterministic columns (every column but ``wall_s``, ``plan_s``, ``filter_s``) and the trajectories'
  targets identical to the uninterrupted run's.
- ``memory``: a fresh batch for each size N: the batch process's and the workers' peak RSS.

Timings are measured here, never asserted in tests.
"""

from __future__ import annotations

import json
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["SECTIONS", "VOLATILE_COLUMNS", "BatchRun", "alive", "batch_command", "bench_batch", "check_store", "compare_stores",
           "process_tree", "report_lines", "run_batch_process", "split_n"]

SECTIONS = ("throughput", "ray", "resume", "memory")
VOLATILE_COLUMNS = ("wall_s", "plan_s", "filter_s")
"""Row columns that are timings: they differ from run to run; every other column is deterministic."""
KINDS = ("supine", "prone", "left", "right")
POLL_S = 0.2


@dataclass
class BatchRun:
    """One child ``robot-rise batch`` process.

    Attributes:
        label: what it was for.
        postures: tasks of the batch.
        jobs: local workers, or Ray CPUs.
        backend: as the batch reports it ("local (2 jobs)", "ray ADDRESS").
        ran: tasks it ran (the others were done already).
        wall_s: the batch's own wall time (None when killed).
        process_s: from starting the process to its exit or kill.
        parent_rss_mb: peak RSS of the batch process [MiB].
        worker_rss_mb: peak RSS of its largest worker process [MiB] (0: no local worker seen).
        workers_seen: worker processes seen.
        cpu_s: CPU time of the batch process and its workers [s] (polled: the last ~0.2 s of each is missed;
            Ray's workers on other nodes are not counted).
        killed: SIGKILLed at process_s.
        orphans: worker processes still alive 3 s after the kill.
        returncode: the process's exit code.
    """

    label: str
    postures: int
    jobs: int
    backend: str = ""
    ran: int = 0
    wall_s: float | None = None
    process_s: float = 0.0
    parent_rss_mb: float = 0.0
    worker_rss_mb: float = 0.0
    workers_seen: int = 0
    cpu_s: float = 0.0
    killed: bool = False
    orphans: int = 0
    returncode: int | None = None
    summary: list[dict[str, Any]] = field(default_factory=list, repr=False)

    @property
    def per_hour_per_core(self) -> float | None:
        """Postures per hour of wall time, divided by the workers (a loaded machine lowers it)."""
        if not self.wall_s or not self.ran:
            return None
        return 3600.0 * self.ran / self.wall_s / self.jobs

    @property
    def per_cpu_hour(self) -> float | None:
        """Postures per hour of CPU time of the batch and its workers (what a core that is all its own would do)."""
        if not self.cpu_s or not self.ran or self.killed:
            return None
        return 3600.0 * self.ran / self.cpu_s

    @property
    def cpu_share(self) -> float | None:
        """CPU time / (wall time x workers): the share of its cores the batch got (1: each worker had a core)."""
        if not self.wall_s or not self.cpu_s:
            return None
        return self.cpu_s / (self.wall_s * self.jobs)


def split_n(n: int) -> tuple[tuple[str, ...], int]:
    """N postures as (kinds, postures per kind): the four kinds when 4 divides N, else two, else supine."""
    for k in (4, 2, 1):
        if n % k == 0:
            return KINDS[:k], n // k
    raise AssertionError


def _children_map() -> dict[int, list[int]]:
    out: dict[int, list[int]] = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        ppid = int(stat[stat.rindex(")") + 2 :].split()[1])
        out.setdefault(ppid, []).append(int(entry.name))
    return out


def process_tree(pid: int) -> list[int]:
    """The pids of every living descendant of ``pid`` (Linux ``/proc``)."""
    children = _children_map()
    out, todo = [], [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


_TICK = os.sysconf("SC_CLK_TCK")


def _cpu_s(pid: int) -> float:
    """utime + stime of ``pid`` itself [s] (its waited children excluded), 0 when gone."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / _TICK
    except (OSError, IndexError, ValueError):
        return 0.0


def _hwm_kb(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


def alive(pid: int) -> bool:
    """Whether ``pid`` is a living process (not a zombie)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ")[-1][:1] not in ("Z", "X")
    except OSError:
        return False


def _batch_argv(store: Path, *, n: int, seed: int, jobs: int, ensemble: bool, ray: str | None = None) -> list[str]:
    kinds, per_kind = split_n(n)
    argv = [sys.executable, "-m", "robot_rise", "batch", "--n", str(per_kind), "--kinds", ",".join(kinds), "--seed", str(seed),
            "--out", str(store), "--jobs", str(jobs), "--json"]
    if not ensemble:
        argv.append("--no-ensemble")
    if ray:
        argv += ["--ray", ray]
    return argv


def batch_command(store: Path | str, *, n: int, seed: int, jobs: int, ensemble: bool, ray: str | None = None) -> str:
    """The ``robot-rise batch`` command line a run of this benchmark is (for the record)."""
    argv = _batch_argv(Path(store), n=n, seed=seed, jobs=jobs, ensemble=ensemble, ray=ray)
    return " ".join(["robot-rise", *argv[3:]])


def run_batch_process(label: str, store: Path, *, n: int, seed: int, jobs: int, ensemble: bool, ray: str | None = None,
                      kill_after_s: float | None = None) -> BatchRun:
    """Run one batch as a child process (SIGKILLed after ``kill_after_s`` if given) and watch its memory."""
    argv = _batch_argv(store, n=n, seed=seed, jobs=jobs, ensemble=ensemble, ray=ray)
    run = BatchRun(label, n, jobs)
    hwm: dict[int, int] = {}
    cpu: dict[int, float] = {}
    t0 = time.monotonic()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(argv, stdout=out, stderr=err, stdin=subprocess.DEVNULL)
        stop = threading.Event()

        def watch() -> None:
            while not stop.is_set():
                for pid in [proc.pid, *process_tree(proc.pid)]:
                    hwm[pid] = max(hwm.get(pid, 0), _hwm_kb(pid))
                    cpu[pid] = max(cpu.get(pid, 0.0), _cpu_s(pid))
                stop.wait(POLL_S)

        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()
        try:
            proc.wait(timeout=kill_after_s)
        except subprocess.TimeoutExpired:
            workers = [p for p in hwm if p != proc.pid]
            proc.send_signal(signal.SIGKILL)  # the batch process only: its workers must die with it
            proc.wait()
            run.killed = True
            run.process_s = time.monotonic() - t0
            time.sleep(3.0)
            run.orphans = sum(alive(p) for p in workers)
        else:
            run.process_s = time.monotonic() - t0
        stop.set()
        watcher.join()
        run.returncode = proc.returncode
        out.seek(0), err.seek(0)
        stdout, stderr = out.read(), err.read()
    run.parent_rss_mb = hwm.get(proc.pid, 0) / 1024
    workers = {p: v for p, v in hwm.items() if p != proc.pid and v > 0}
    run.worker_rss_mb = max(workers.values(), default=0) / 1024
    run.workers_seen = len(workers)
    run.cpu_s = sum(cpu.values())
    if not run.killed:
        try:
            doc = json.loads(stdout)
        except json.JSONDecodeError:
            raise RuntimeError(f"{label}: the batch printed no JSON (exit {proc.returncode}):\n{stderr[-2000:]}") from None
        run.backend, run.ran, run.wall_s, run.summary = doc["run"]["backend"], doc["run"]["ran"], doc["run"]["wall_s"], doc["summary"]
    return run


def _stable(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: v for k, v in r.items() if k not in VOLATILE_COLUMNS} for r in rows]


def compare_stores(a: Path, b: Path, *, trajectories: bool = False) -> dict[str, Any]:
    """How store ``b`` differs from store ``a`` in its deterministic columns (and, optionally, trajectory targets)."""
    import numpy as np

    from robot_rise.batch import ResultStore, summarize
    from robot_rise.trajectory import read_trajectory

    ra, rb = ResultStore(a).rows(), ResultStore(b).rows()
    sa, sb = {r["id"]: r for r in _stable(ra)}, {r["id"]: r for r in _stable(rb)}
    differing = sorted({k for i in sa.keys() & sb.keys() for k in sa[i] if sa[i][k] != sb[i].get(k)})
    strip = lambda groups: [{k: v for k, v in g.items() if k != "wall_median_s"} for g in groups]
    out: dict[str, Any] = {
        "rows": (len(ra), len(rb)),
        "same_ids": sa.keys() == sb.keys(),
        "rows_differing": sum(sa[i] != sb[i] for i in sa.keys() & sb.keys()),
        "columns_differing": differing,
        "proven": (sum(r["proven"] for r in ra), sum(r["proven"] for r in rb)),
        "same_summary": strip(summarize(ra)) == strip(summarize(rb)),
    }
    out["identical"] = out["same_ids"] and out["rows_differing"] == 0 and out["same_summary"]
    if trajectories:
        same = 0
        for i, r in sa.items():
            if r["proven"] and i in sb and sb[i]["trajectory"]:
                ta, tb = read_trajectory(a / r["trajectory"]), read_trajectory(b / sb[i]["trajectory"])
                same += bool(np.array_equal(ta.t, tb.t) and np.array_equal(ta.q, tb.q))
        out["trajectories_identical"] = same
        out["identical"] = out["identical"] and same == out["proven"][0]
    return out


def check_store(store: Path, n: int) -> dict[str, Any]:
    """The store after a killed-and-resumed batch: rows, duplicates, leftovers, trajectory files."""
    import pyarrow.parquet as pq

    from robot_rise.batch import ResultStore
    from robot_rise.trajectory import read_trajectory

    s = ResultStore(store)
    ids = pq.read_table(s.results_path, columns=["id"]).column("id").to_pylist()
    rows = s.rows()
    proven = {r["id"]: r for r in rows if r["proven"]}
    files = sorted(s.trajectories_dir.glob("*.json"))
    unreadable = 0
    for path in files:
        try:
            read_trajectory(path)
        except Exception:  # noqa: BLE001 - counted, whatever it is
            unreadable += 1
    out = {
        "expected": n,
        "rows": len(ids),
        "duplicates": len(ids) - len(set(ids)),
        "parts_left": len(list(s.parts_dir.glob("*"))) if s.parts_dir.is_dir() else 0,
        "temporaries_left": len(s.temporaries()),
        "trajectory_files": len(files),
        "unreadable_trajectories": unreadable,
        "proven_rows": len(proven),
        "proven_without_file": sum(not (store / r["trajectory"]).is_file() for r in proven.values()),
        "files_without_proven_row": len({p.stem for p in files} - set(proven)),
    }
    out["ok"] = (out["rows"] == n and not out["duplicates"] and not out["parts_left"] and not out["temporaries_left"]
                 and not unreadable and not out["proven_without_file"] and not out["files_without_proven_row"])
    return out


def _after_kill(store: Path) -> dict[str, Any]:
    """What a kill left in the store: whole files only? (temporary files are allowed, not as results)."""
    import pyarrow.parquet as pq

    from robot_rise.batch import ResultStore
    from robot_rise.trajectory import read_trajectory

    s = ResultStore(store)
    bad = 0
    for path in [*s.trajectories_dir.glob("*.json")] if s.trajectories_dir.is_dir() else []:
        try:
            read_trajectory(path)
        except Exception:  # noqa: BLE001
            bad += 1
    parts = sorted(s.parts_dir.glob("*.parquet")) if s.parts_dir.is_dir() else []
    for path in parts + ([s.results_path] if s.results_path.exists() else []):
        try:
            pq.read_table(path)
        except Exception:  # noqa: BLE001
            bad += 1
    return {"rows": len(s.rows()) if s.exists() else 0, "temporaries": len(s.temporaries()), "unreadable": bad}


def bench_batch(
    *,
    sections: Sequence[str] = SECTIONS,
    n_per_kind: int = 6,
    resume_n: int = 100,
    memory_n: Sequence[int] = (50, 200),
    jobs: int = 2,
    seed: int = 0,
    ensemble: bool = True,
    work_dir: str | os.PathLike[str] | None = None,
    say: Callable[[str], None] = lambda line: None,
) -> dict[str, Any]:
    """Run the sections and return every figure (see the module docstring); ``ok`` is false if a check failed."""
    root = Path(work_dir) if work_dir else Path(tempfile.mkdtemp(prefix="bench-batch-"))
    root.mkdir(parents=True, exist_ok=True)
    runs: list[BatchRun] = []
    result: dict[str, Any] = {"ensemble": ensemble, "seed": seed, "runs": runs, "commands": [], "ok": True,
                              "load_before": os.getloadavg(), "cpus": len(os.sched_getaffinity(0))}

    def go(label: str, store: Path, **kw: Any) -> BatchRun:
        result["commands"].append(batch_command(store, seed=seed, ensemble=ensemble, **{k: v for k, v in kw.items() if k != "kill_after_s"}))
        say(f"{label}: {result['commands'][-1]}" + (f" (SIGKILL after {kw['kill_after_s']:.1f} s)" if kw.get("kill_after_s") else ""))
        run = run_batch_process(label, store, seed=seed, ensemble=ensemble, **kw)
        runs.append(run)
        say(f"{label}: " + (f"killed after {run.process_s:.1f} s" if run.killed else f"{run.ran} run in {run.wall_s:.1f} s")
            + f", peak RSS batch {run.parent_rss_mb:.0f} MiB, worker {run.worker_rss_mb:.0f} MiB")
        return run

    try:
        n_tp = n_per_kind * len(KINDS)
        local2: Path | None = None
        if "throughput" in sections:
            one = go("throughput, 1 worker", root / "tp1", n=n_tp, jobs=1)
            two = go("throughput, 2 workers", root / "tp2", n=n_tp, jobs=2)
            local2 = root / "tp2"
            cmp = compare_stores(root / "tp1", local2)
            result["throughput"] = {"postures": n_tp, "per_hour_per_core": [one.per_hour_per_core, two.per_hour_per_core],
                                    "ratio": (two.ran / two.wall_s) / (one.ran / one.wall_s), "same_rows": cmp,
                                    "per_cpu_hour": [one.per_cpu_hour, two.per_cpu_hour], "cpu_share": [one.cpu_share, two.cpu_share]}
            result["ok"] &= cmp["identical"]
        if "ray" in sections:
            if local2 is None:
                local2 = root / "local2"
                go("local pool, 2 workers", local2, n=n_tp, jobs=2)
            from ray.cluster_utils import Cluster

            say("ray: starting a cluster of two nodes of 1 CPU each")
            cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
            try:
                cluster.add_node(num_cpus=1)
                cluster.wait_for_nodes()
                r = go("ray, 2 nodes x 1 CPU", root / "ray", n=n_tp, jobs=2, ray=cluster.address)
                r.backend = "ray cluster (2 nodes x 1 CPU)"
                r.cpu_s = 0.0  # its workers are the raylets' children, not the batch's: not counted
            finally:
                cluster.shutdown()
            cmp = compare_stores(local2, root / "ray")
            lp = next(x for x in runs if x.label.startswith(("throughput, 2", "local pool")))
            result["ray"] = {"postures": n_tp, "per_hour_per_core": [lp.per_hour_per_core, r.per_hour_per_core], "same_rows": cmp}
            result["ok"] &= cmp["identical"]
        if "resume" in sections:
            ref = go(f"resume: uninterrupted {resume_n}", root / "ref", n=resume_n, jobs=jobs)
            rng = random.Random(seed)
            store = root / "killed"
            kills = []
            for k in (1, 2):
                at = rng.uniform(0.10, 0.45) * (ref.wall_s or 60.0)
                run = go(f"resume: run {k}, killed", store, n=resume_n, jobs=jobs, kill_after_s=at)
                kills.append({"after_s": round(at, 1), "killed": run.killed, "orphan_workers": run.orphans, **_after_kill(store)})
            final = go("resume: run 3, to the end", store, n=resume_n, jobs=jobs)
            check = check_store(store, resume_n)
            cmp = compare_stores(root / "ref", store, trajectories=True)
            result["resume"] = {"postures": resume_n, "kills": kills, "final_ran": final.ran, "check": check, "same_as_uninterrupted": cmp,
                                "killed_wall_s": sum(r.process_s for r in runs[-3:-1]) + (final.wall_s or 0), "uninterrupted_wall_s": ref.wall_s}
            result["ok"] &= (check["ok"] and cmp["identical"] and all(k["killed"] and not k["orphan_workers"] and not k["unreadable"] for k in kills))
        if "memory" in sections:
            mem = []
            for n in memory_n:
                run = go(f"memory: {n}", root / f"mem{n}", n=n, jobs=jobs)
                mem.append({"postures": n, "parent_rss_mb": run.parent_rss_mb, "worker_rss_mb": run.worker_rss_mb})
            result["memory"] = mem
    finally:
        result["load_after"] = os.getloadavg()
        if not work_dir:
            shutil.rmtree(root, ignore_errors=True)
    result["runs"] = [{**asdict(r), "per_hour_per_core": r.per_hour_per_core, "per_cpu_hour": r.per_cpu_hour, "cpu_share": r.cpu_share} for r in runs]
    for r in result["runs"]:
        r.pop("summary", None)
    return result


def _f(v: float | None, spec: str) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def report_lines(result: dict[str, Any]) -> list[str]:
    """The figures of :func:`bench_batch` as markdown lines."""
    lines = [(f"proof: {'ensemble (product default)' if result['ensemble'] else 'nominal only (--no-ensemble)'}; seed {result['seed']}; "
              f"{result['cpus']} CPUs; load average before {result['load_before'][0]:.2f}, after {result['load_after'][0]:.2f}"), "",
             "| run | postures | workers | ran | wall [s] | postures/h/core | CPU [s] | CPU share | postures/CPU-h | peak RSS batch [MiB] | peak RSS worker [MiB] |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in result["runs"]:
        wall = f"killed at {r['process_s']:.1f}" if r["killed"] else _f(r["wall_s"], ".1f")
        lines.append(f"| {r['label']} | {r['postures']} | {r['jobs']} | {r['ran'] if not r['killed'] else '-'} | {wall} | "
                     f"{_f(r['per_hour_per_core'], '.0f')} | {r['cpu_s']:.0f} | {_f(r['cpu_share'], '.2f')} | {_f(r['per_cpu_hour'], '.0f')} | "
                     f"{r['parent_rss_mb']:.0f} | {r['worker_rss_mb']:.0f} |")
    lines.append("")
    if "throughput" in result:
        t = result["throughput"]
        lines.append(f"throughput: {_f(t['per_hour_per_core'][0], '.0f')} postures/h/core on 1 worker, {_f(t['per_hour_per_core'][1], '.0f')} "
                     f"on 2; 2 workers = {t['ratio']:.2f}x 1 worker (goal >= 1.7x); CPU share {_f(t['cpu_share'][0], '.2f')} and "
                     f"{_f(t['cpu_share'][1], '.2f')}; postures per CPU-hour {_f(t['per_cpu_hour'][0], '.0f')} and {_f(t['per_cpu_hour'][1], '.0f')}; "
                     f"rows of the two runs identical: {t['same_rows']['identical']}")
    if "ray" in result:
        r = result["ray"]
        lines.append(f"ray (2 nodes x 1 CPU) vs local pool (2 workers): {_f(r['per_hour_per_core'][1], '.0f')} vs "
                     f"{_f(r['per_hour_per_core'][0], '.0f')} postures/h/core; rows identical: {r['same_rows']['identical']} "
                     f"(differing columns: {', '.join(r['same_rows']['columns_differing']) or 'none'})")
    if "resume" in result:
        r = result["resume"]
        c, s = r["check"], r["same_as_uninterrupted"]
        for k, kill in enumerate(r["kills"], 1):
            lines.append(f"kill {k}: SIGKILL after {kill['after_s']} s; {kill['rows']} rows recorded; {kill['temporaries']} temporary files; "
                         f"{kill['unreadable']} unreadable files; {kill['orphan_workers']} workers outlived the kill")
        lines.append(f"resumed: {c['rows']} rows of {c['expected']}, {c['duplicates']} duplicate ids, {c['trajectory_files']} trajectory files "
                     f"({c['unreadable_trajectories']} unreadable) for {c['proven_rows']} proven rows, {c['parts_left']} parts and "
                     f"{c['temporaries_left']} temporary files left; vs uninterrupted: {s['rows_differing']} rows differ "
                     f"(deterministic columns), proven {s['proven'][1]} vs {s['proven'][0]}, {s.get('trajectories_identical', 0)} "
                     f"trajectories bit-identical, summary identical: {s['same_summary']}; wall {r['killed_wall_s']:.0f} s "
                     f"(three runs) vs {_f(r['uninterrupted_wall_s'], '.0f')} s")
    if "memory" in result:
        lines.append("memory: " + "; ".join(f"N={m['postures']}: batch {m['parent_rss_mb']:.0f} MiB, worker {m['worker_rss_mb']:.0f} MiB"
                                            for m in result["memory"]))
    lines.append(f"all checks passed: {result['ok']}")
    return lines
