"""robot-rise export-csv: a trajectory file as CSV (t, then one column per joint, radians)."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_rise.cli._common import Formatter
from robot_rise.trajectory import read_trajectory, write_csv


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export-csv",
        help="write a trajectory's joint targets as CSV (t [s], then one column per joint [rad])",
        formatter_class=Formatter,
        description="Reads TRAJ (robot-rise/trajectory@1) and writes its rows as CSV with a header\n"
        "line 't,<joint>,...': for spreadsheets and plotting tools. The file is written atomically.",
        epilog="example:\n  robot-rise export-csv out/demo/rise.json --out out/demo/rise.csv",
    )
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory file (robot-rise/trajectory@1)")
    p.add_argument("--out", metavar="FILE", help="CSV file to write (default: TRAJ with .csv)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    tr = read_trajectory(args.trajectory)
    out = Path(args.out) if args.out else Path(args.trajectory).with_suffix(".csv")
    write_csv(out, tr)
    print(f"wrote {out}: {len(tr.t)} rows x {len(tr.joint_names)} joints, {tr.duration_s:.2f} s")
    return 0
