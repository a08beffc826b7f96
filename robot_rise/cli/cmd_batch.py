"""robot-rise batch: many proven get-ups into a results store; ``batch summary STORE`` prints one."""

from __future__ import annotations

import argparse
import sys

from robot_rise.cli._common import Formatter, Progress, print_json
from robot_rise.constants import ENVELOPE_MARGIN
from robot_rise.errors import RobotRiseError
from robot_rise.rise import DEFAULT_CANDIDATES

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "batch",
        help="rise from many sampled postures into a results store (local pool or Ray), resumable",
        formatter_class=Formatter,
        description="Samples N lying postures per robot, scene and kind (or takes the posture files of --postures\n"
        "DIR), rises from each and records every outcome in STORE: results.parquet (one row per task)\n"
        "and trajectories/<id>.json for each proven one. Task ids come from everything that changes a\n"
        "result: robot and library files, scene files, seed, posture (kind and index, or the posture\n"
        "file's content), --budget, --candidates, --margin, --no-ensemble, --composed. Running the same command\n"
        "again skips what is done and resumes what is not; other options are other tasks. A killed\n"
        "batch loses at most its tasks in flight. Every --postures file is checked first: one that is\n"
        "not a posture of the robots refuses the batch (one line per bad file, nothing run); a posture\n"
        "that cannot be risen from is a row with its reason. Exit code 1 if a task crashed twice.\n"
        "Needs pyarrow (pip install 'robot-rise[batch]'); --ray needs Ray (pip install 'robot-rise[ray]').",
        epilog="examples:\n"
        "  robot-rise batch --n 250 --seed 0 --out store/\n"
        "  robot-rise batch --n 10 --seed 1 --kinds supine,prone --scenes flat,slope --out store/ --ray local\n"
        "  robot-rise sample --kind prone --n 20 --seed 4 --out lying/\n"
        "  robot-rise batch --postures lying/ --out store/\n"
        "  robot-rise batch summary store/",
    )
    p.add_argument("--n", type=int, metavar="N", help="sampled postures per robot, scene and kind")
    p.add_argument("--postures", metavar="DIR", help="rise from the posture files (*.json) of DIR instead of sampling")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="batch seed: postures and planner (default: 0)")
    p.add_argument("--kinds", metavar="K,...", help="lying kinds of sampled postures (default: supine,prone,left,right)")
    p.add_argument("--scenes", default="flat", metavar="S,...", help="shipped scene names or MJCF files (default: flat)")
    p.add_argument("--robot", action="append", metavar="DIR", help="robot directory, repeatable (default: the embedded OP3-class robot)")
    p.add_argument("--out", metavar="STORE", help="results store directory (created; resumed if it exists)")
    p.add_argument("--jobs", type=int, metavar="K", help="worker processes (default: all cores); with --ray local, its CPUs")
    p.add_argument("--ray", metavar="local|ADDRESS", help="run on Ray: 'local' starts a local cluster, an address joins one")
    p.add_argument("--budget", type=float, default=30.0, metavar="SECONDS", help="planning budget per candidate (default: 30)")
    p.add_argument("--candidates", type=int, default=DEFAULT_CANDIDATES, metavar="K", help=f"library motions to try (default: {DEFAULT_CANDIDATES})")
    p.add_argument("--margin", type=float, default=ENVELOPE_MARGIN, metavar="M", help=f"torque envelope margin (default: {ENVELOPE_MARGIN:.2f})")
    p.add_argument("--no-ensemble", action="store_true",
                   help="prove on the nominal model only, not on every model variant (about 3x faster; weaker proof)")
    p.add_argument("--composed", action="store_true",
                   help="prove each get-up by composition with the library motions' start proofs where it applies "
                        "(about 5x less CPU per posture after a one-off ~3 s per motion and worker; get-ups join each "
                        "motion at its start: ~0.2 s longer at the median), whole otherwise")
    p.add_argument("--json", action="store_true", help="print the run and the summary as JSON")
    p.set_defaults(func=run)
    inner = p.add_subparsers(dest="batch_command", metavar="COMMAND")
    s = inner.add_parser(
        "summary",
        help="print the table of a results store (per robot, scene and kind)",
        formatter_class=Formatter,
        description="Per robot, scene and kind: tasks, proven, failed, success, get-up duration (median, p90)\n"
        "and the worst ensemble margins of the proven rows.",
        epilog="example:\n  robot-rise batch summary store/ --json",
    )
    s.add_argument("store", metavar="STORE", help="results store directory")
    s.add_argument("--json", action="store_true", help="print JSON instead of the table")
    s.set_defaults(func=run_summary)


def _progress_printer():
    bar = Progress("batch", unit="task")

    def show(p) -> None:
        bar(p.done, p.total, info=f"{p.proven} proven, {p.failed} failed, {3600 * p.rate_per_s:.0f}/h")

    return show


def rise_options(args: argparse.Namespace) -> dict:
    """The rise options of the command line (each is part of the task ids)."""
    from robot_rise.filter import FilterConfig
    from robot_rise.proof import ProofConfig

    if args.budget <= 0:
        raise RobotRiseError(f"--budget must be positive, got {args.budget}")
    if args.candidates < 1:
        raise RobotRiseError(f"--candidates must be at least 1, got {args.candidates}")
    if not 0 <= args.margin < 1:
        raise RobotRiseError(f"--margin must be in [0, 1), got {args.margin}")
    if args.composed and args.no_ensemble:
        raise RobotRiseError("--composed composes the ensemble proof: it cannot go with --no-ensemble")
    return {"budget_s": args.budget, "candidates": args.candidates,
            "filter_config": FilterConfig(proof=ProofConfig(envelope_margin=args.margin, ensemble=not args.no_ensemble)),
            **({"composed": True} if args.composed else {})}


def run(args: argparse.Namespace) -> int:
    from robot_rise.batch import run_batch, summarize, summary_table
    from robot_rise.batch.store import ResultStore

    if args.n is not None and args.postures is not None:
        raise RobotRiseError("batch takes either --n N (sampled postures) or --postures DIR, not both")
    if args.out is None or (args.n is None and args.postures is None):
        raise RobotRiseError("batch needs --out STORE and either --n N or --postures DIR",
                             hint="robot-rise batch --n 10 --seed 0 --out store/ (or: robot-rise batch summary STORE)")
    if args.postures is not None and args.kinds is not None:
        raise RobotRiseError("--kinds applies to sampled postures (--n), not to --postures DIR")
    split = lambda text: tuple(x.strip() for x in text.split(",") if x.strip())  # noqa: E731
    result = run_batch(
        n=args.n, postures=args.postures, seed=args.seed, out=args.out, kinds=split(args.kinds or "supine,prone,left,right"),
        scenes=split(args.scenes), robots=tuple(args.robot) if args.robot else (None,), jobs=args.jobs, ray=args.ray,
        progress=_progress_printer(), rise_options=rise_options(args),
    )
    groups = summarize(ResultStore(result.store).rows())
    if args.json:
        print_json({"run": {**result.__dict__, "store": str(result.store)}, "summary": groups})
        return 0 if result.failed == 0 else 1
    print(f"{result.store}: {result.tasks} tasks, {result.skipped} already done, {result.ran} run "
          f"({result.proven} proven, {result.failed} failed) in {result.wall_s:.1f} s on {result.backend}; {result.rows} rows")
    print(summary_table(groups))
    return 0 if result.failed == 0 else 1


def run_summary(args: argparse.Namespace) -> int:
    from robot_rise.batch import ResultStore, summarize, summary_table

    groups = summarize(ResultStore(args.store).rows())
    if args.json:
        print_json(groups)
    else:
        print(summary_table(groups))
    return 0


def register_bench(bsub: argparse._SubParsersAction) -> None:
    """``robot-rise bench batch``: throughput 1 vs 2 workers, Ray vs the local pool, kill-twice-and-resume, memory vs N."""
    from robot_rise.bench.batch import SECTIONS

    b = bsub.add_parser(
        "batch",
        help="batch throughput (1 vs 2 workers), Ray vs the local pool, kill twice and resume, memory vs N",
        formatter_class=Formatter,
        description="Runs `robot-rise batch` in child processes and prints, per run: postures, workers, wall time,\n"
        "postures per hour per core and the peak RSS of the batch process and of its workers. Sections:\n"
        "throughput (the same postures on 1 and on 2 workers; ratio), ray (the same postures on a simulated\n"
        "Ray cluster of two 1-CPU nodes, rows compared with the local pool's), resume (N postures: an\n"
        "uninterrupted run, then a run SIGKILLed at two random moments and resumed; rows, duplicates,\n"
        "trajectory files, temporary files and the deterministic columns compared), memory (peak RSS\n"
        "for each --memory-n). Run it under `nice -n 19` on a shared machine.",
        epilog="examples:\n"
        "  nice -n 19 robot-rise bench batch --sections throughput,ray --n-per-kind 6\n"
        "  nice -n 19 robot-rise bench batch --sections resume --resume-n 1000 --no-ensemble",
    )
    b.add_argument("--sections", default=",".join(SECTIONS), metavar="S,...", help=f"what to measure (default: {','.join(SECTIONS)})")
    b.add_argument("--n-per-kind", type=int, default=6, metavar="N", help="throughput and ray: postures per lying kind (default: 6)")
    b.add_argument("--resume-n", type=int, default=100, metavar="N", help="resume: postures; N/4 per lying kind (N/2 of supine, prone if 4 does not divide N) (default: 100)")
    b.add_argument("--memory-n", default="50,200", metavar="N,...", help="memory: batch sizes (default: 50,200)")
    b.add_argument("--jobs", type=int, default=2, metavar="K", help="workers of the resume and memory runs (default: 2)")
    b.add_argument("--seed", type=int, default=0)
    b.add_argument("--no-ensemble", action="store_true", help="pass --no-ensemble to every batch (nominal proof only, ~3x faster)")
    b.add_argument("--work-dir", metavar="DIR", help="where the stores go (default: a temporary directory, removed)")
    b.add_argument("--json", action="store_true", help="print every figure as JSON")
    b.set_defaults(func=run_bench)


def run_bench(args: argparse.Namespace) -> int:
    from robot_rise.bench.batch import SECTIONS, bench_batch, report_lines

    sections = tuple(s.strip() for s in args.sections.split(",") if s.strip())
    unknown = [s for s in sections if s not in SECTIONS]
    if unknown:
        raise RobotRiseError(f"unknown section {unknown[0]!r}; choose from {', '.join(SECTIONS)}")
    memory_n = tuple(int(x) for x in args.memory_n.split(",") if x.strip())
    result = bench_batch(sections=sections, n_per_kind=args.n_per_kind, resume_n=args.resume_n, memory_n=memory_n, jobs=args.jobs,
                         seed=args.seed, ensemble=not args.no_ensemble, work_dir=args.work_dir,
                         say=lambda line: print(line, file=sys.stderr, flush=True))
    if args.json:
        print_json(result)
    else:
        print("\n".join(report_lines(result)))
    return 0 if result["ok"] else 1
