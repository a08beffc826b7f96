"""robot-rise export-csv: a trajectory as CSV, in radians per joint or as its servos see it (ticks per servo ID, at the executor's rate)."""

from __future__ import annotations

import argparse
import csv
import io
from pathlib import Path

import numpy as np

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg, print_json
from robot_rise.errors import ConfigError
from robot_rise.fileio import write_text_atomic
from robot_rise.trajectory import read_trajectory, write_csv


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export-csv",
        help="write a trajectory as CSV: radians per joint, or ticks per servo ID at the executor's rate",
        formatter_class=Formatter,
        description="Reads TRAJ (robot-rise/trajectory@1) and writes CSV, atomically.\n"
        "--units rad (default): 't,<joint>,...' with the file's rows (or resampled with --rate).\n"
        "--units ticks: 't,<servo id>,...' as the servos see it: each joint through the robot's servo map\n"
        "(direction, zero offset, resolution), sampled at the executor's rate (--rate, default 100 Hz).",
        epilog="examples:\n  robot-rise export-csv out/demo/rise.json --out out/demo/rise.csv\n"
        "  robot-rise export-csv out/demo/rise.json --units ticks --rate 100 --out rise_ticks.csv",
    )
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory file (robot-rise/trajectory@1)")
    p.add_argument("--out", metavar="FILE", help="CSV file to write (default: TRAJ with .csv)")
    p.add_argument("--units", choices=("rad", "ticks"), default="rad", help="radians per joint, or servo ticks per servo ID (default: rad)")
    p.add_argument("--rate", type=float, metavar="HZ", help="resample at this rate (default: the file's rows for rad, 100 Hz for ticks)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text")
    add_robot_args(p, scene=False)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from drivers import load_servo_map
    from drivers.executor import DEFAULT_RATE_HZ

    tr = read_trajectory(args.trajectory)
    out = Path(args.out) if args.out else Path(args.trajectory).with_suffix(".csv")
    if args.units == "rad" and args.rate is None:
        write_csv(out, tr)
        if args.json:
            print_json({"file": str(out), "units": "rad", "rows": len(tr.t), "rate_hz": None,
                        "columns": list(tr.joint_names), "duration_s": tr.duration_s})
        else:
            print(f"wrote {out}: {len(tr.t)} rows x {len(tr.joint_names)} joints [rad], {tr.duration_s:.2f} s")
        return 0
    rate = args.rate if args.rate is not None else DEFAULT_RATE_HZ
    t = np.arange(0.0, tr.duration_s + 0.5 / rate, 1.0 / rate)
    t = np.minimum(t, tr.duration_s)
    q = tr.sample(t)
    buf = io.StringIO(newline="")
    w = csv.writer(buf, lineterminator="\n")
    if args.units == "rad":
        w.writerow(["t", *tr.joint_names])
        for ti, row in zip(t, q):
            w.writerow([f"{ti:.6f}", *(f"{x:.6f}" for x in row)])
        what = f"{len(tr.joint_names)} joints [rad]"
        columns_out = list(tr.joint_names)
    else:
        robot = load_robot_arg(args)
        if tr.robot != robot.name:
            raise ConfigError(f"{args.trajectory}: trajectory of robot {tr.robot!r}, not {robot.name!r}", hint="pass --robot DIR of its robot")
        servo_map = load_servo_map(robot.directory / "servos.toml")
        missing = [j for j in servo_map.joint_names if j not in tr.joint_names]
        if missing:
            raise ConfigError(f"{args.trajectory}: no targets for the servos of {', '.join(missing)}")
        columns = [tr.joint_names.index(j) for j in servo_map.joint_names]
        ticks = servo_map.to_ticks(q[:, columns])
        w.writerow(["t", *(str(i) for i in servo_map.ids)])
        for ti, row in zip(t, ticks):
            w.writerow([f"{ti:.6f}", *(str(int(x)) for x in row)])
        what = f"{len(servo_map.ids)} servos [ticks]"
        columns_out = [str(i) for i in servo_map.ids]
    write_text_atomic(out, buf.getvalue())
    if args.json:
        print_json({"file": str(out), "units": args.units, "rows": len(t), "rate_hz": rate, "columns": columns_out,
                    "duration_s": tr.duration_s})
        return 0
    print(f"wrote {out}: {len(t)} rows at {rate:g} Hz x {what}, {tr.duration_s:.2f} s")
    return 0
