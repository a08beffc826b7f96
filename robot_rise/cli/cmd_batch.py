"""robot-rise batch: many proven get-ups into a results store; ``batch summary STORE`` prints one."""

from __future__ import annotations

import argparse
import math
import sys

from robot_rise.cli._common import Formatter, Progress, print_json
from robot_rise.errors import RobotRiseError

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "batch",
        help="rise from many sampled postures into a results store (local pool or Ray), resumable",
        formatter_class=Formatter,
        description="Samples N lying postures per robot, scene and kind, rises from each and records every\n"
        "outcome in STORE: results.parquet (one row per task) and trajectories/<id>.json for each\n"
        "proven one. Task ids come from the inputs (robot files, scene, kind, seed, index): running\n"
        "the same command again skips what is done and resumes what is not. Needs pyarrow\n"
        "(pip install 'robot-rise[batch]'); --ray needs Ray (pip install 'robot-rise[ray]').",
        epilog="examples:\n"
        "  robot-rise batch --n 250 --seed 0 --out store/\n"
        "  robot-rise batch --n 10 --seed 1 --kinds supine,prone --scenes flat,slope --out store/ --ray local\n"
        "  robot-rise batch summary store/",
    )
    p.add_argument("--n", type=int, metavar="N", help="postures per robot, scene and kind")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="batch seed: postures and planner (default: 0)")
    p.add_argument("--kinds", default="supine,prone,left,right", metavar="K,...", help="lying kinds (default: supine,prone,left,right)")
    p.add_argument("--scenes", default="flat", metavar="S,...", help="shipped scene names or MJCF files (default: flat)")
    p.add_argument("--robot", action="append", metavar="DIR", help="robot directory, repeatable (default: the embedded OP3-class robot)")
    p.add_argument("--out", metavar="STORE", help="results store directory (created; resumed if it exists)")
    p.add_argument("--jobs", type=int, metavar="K", help="worker processes (default: all cores); with --ray local, its CPUs")
    p.add_argument("--ray", metavar="local|ADDRESS", help="run on Ray: 'local' starts a local cluster, an address joins one")
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
    bar = Progress("batch", 1)

    def show(p) -> None:
        eta = "?" if math.isnan(p.eta_s) else f"{p.eta_s:.0f} s"
        if bar.enabled:
            bar.label = f"batch {3600 * p.rate_per_s:.0f}/h ETA {eta}"
            bar(p.done, p.total)
        else:
            print(f"batch: {p.done}/{p.total} done, {p.proven} proven, {p.failed} failed, {3600 * p.rate_per_s:.0f}/h, ETA {eta}", file=sys.stderr, flush=True)

    return show


def run(args: argparse.Namespace) -> int:
    from robot_rise.batch import run_batch, summarize, summary_table
    from robot_rise.batch.store import ResultStore

    if args.n is None or args.out is None:
        raise RobotRiseError("batch needs --n N and --out STORE", hint="robot-rise batch --n 10 --seed 0 --out store/ (or: robot-rise batch summary STORE)")
    split = lambda text: tuple(x.strip() for x in text.split(",") if x.strip())  # noqa: E731
    result = run_batch(
        n=args.n, seed=args.seed, out=args.out, kinds=split(args.kinds), scenes=split(args.scenes),
        robots=tuple(args.robot) if args.robot else (None,), jobs=args.jobs, ray=args.ray, progress=_progress_printer(),
    )
    print(f"{result.store}: {result.tasks} tasks, {result.skipped} already done, {result.ran} run "
          f"({result.proven} proven, {result.failed} failed) in {result.wall_s:.1f} s on {result.backend}; {result.rows} rows")
    print(summary_table(summarize(ResultStore(result.store).rows())))
    return 0 if result.failed == 0 else 1


def run_summary(args: argparse.Namespace) -> int:
    from robot_rise.batch import ResultStore, summarize, summary_table

    groups = summarize(ResultStore(args.store).rows())
    if args.json:
        print_json(groups)
    else:
        print(summary_table(groups))
    return 0
