"""robot-rise export: the proven trajectories of a results store as one table (parquet, CSV or NPZ)."""

from __future__ import annotations

import argparse

from robot_rise.cli._common import Formatter, print_json

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="write a results store's proven trajectories as one table (parquet, csv, npz)",
        formatter_class=Formatter,
        description="One row per trajectory sample: id (the task), t [s], one column per joint target [rad],\n"
        "root_x, root_y, root_z [m], root_qw, root_qx, root_qy, root_qz (NaN without a planned root).\n"
        "NPZ holds arrays id, t, q (T x joints), root (T x 7) and joint_names. Written atomically.",
        epilog="example:\n  robot-rise export store/ --format parquet --out rises.parquet",
    )
    p.add_argument("store", metavar="STORE", help="results store directory (robot-rise batch --out)")
    p.add_argument("--format", required=True, choices=("parquet", "csv", "npz"), help="table format")
    p.add_argument("--out", required=True, metavar="FILE", help="file to write")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from robot_rise.batch import export_trajectories

    count = export_trajectories(args.store, args.format, args.out)
    if args.json:
        print_json({"file": str(args.out), "format": args.format, "trajectories": count})
    else:
        print(f"wrote {args.out}: {count} proven trajectories")
    return 0
