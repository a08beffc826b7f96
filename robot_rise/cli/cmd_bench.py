"""robot-rise bench: print the figures BENCHMARKS.md records.

Other CLI modules can add benchmark sub-commands by exposing ``register_bench(subparsers)``.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg, print_json


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench",
        help="run a benchmark and print its figures",
        formatter_class=Formatter,
        epilog="example:\n  robot-rise bench validity --scene flat --scene table",
    )
    bsub = p.add_subparsers(dest="bench", metavar="BENCHMARK", required=True)
    v = bsub.add_parser("validity", help="validity checks per second on one core", formatter_class=Formatter,
                        epilog="example:\n  robot-rise bench validity --n 20000")
    v.add_argument("--scene", action="append", help="scene(s) to measure (default: flat and table)")
    v.add_argument("--n", type=int, default=20000, help="queries per scene (default: 20000)")
    v.add_argument("--seed", type=int, default=0)
    v.add_argument("--json", action="store_true", help="print JSON")
    add_robot_args(v, scene=False)
    v.set_defaults(func=run_validity)
    import robot_rise.cli as cli_pkg

    for info in pkgutil.iter_modules(cli_pkg.__path__):
        if info.name.startswith("cmd_") and info.name != "cmd_bench":
            module = importlib.import_module(f"robot_rise.cli.{info.name}")
            if hasattr(module, "register_bench"):
                module.register_bench(bsub)


def run_validity(args: argparse.Namespace) -> int:
    from robot_rise.benchmarks import bench_validity

    robot = load_robot_arg(args)
    results = [bench_validity(robot, s, n=args.n, seed=args.seed) for s in (args.scene or ["flat", "table"])]
    if args.json:
        print_json([r.__dict__ for r in results])
    else:
        for r in results:
            print(f"validity checks, scene {r.scene}: {r.checks_per_second:,.0f} checks/s on one core ({r.checks} queries in {r.seconds:.2f} s, {100 * r.valid_fraction:.0f}% valid)")
    return 0
