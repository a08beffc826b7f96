"""robot-rise schema: the JSON Schemas of robot_rise's file formats, for other tools to validate our files."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_rise.cli._common import Formatter
from robot_rise.errors import ConfigError
from robot_rise.fileio import write_text_atomic
from robot_rise.paths import configs_dir

FORMATS = ("posture@1", "trajectory@1", "servos@1")


def _path(name: str) -> Path:
    return configs_dir() / "schemas" / f"{name}.schema.json"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "schema",
        help="print or write the JSON Schemas of the file formats (posture@1, trajectory@1, servos@1)",
        formatter_class=Formatter,
        description="JSON Schema (draft 2020-12) of each file format robot_rise reads and writes; the servo map's is\n"
        "of servos.toml as parsed from TOML. A schema checks a file's shape; robot_rise's readers check more\n"
        "(a posture against its robot's joints and limits, a trajectory's proof against what it proves).",
        epilog="examples:\n  robot-rise schema trajectory@1 > trajectory.schema.json\n  robot-rise schema --out schemas/",
    )
    p.add_argument("format", nargs="?", choices=FORMATS, help="the format to print (default with --out: all)")
    p.add_argument("--out", metavar="DIR", help="write every schema into DIR as FORMAT.schema.json")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.out is None and args.format is None:
        raise ConfigError("name a format to print, or --out DIR to write them all", hint=f"formats: {', '.join(FORMATS)}")
    if args.out is None:
        print(_path(args.format).read_text(), end="")
        return 0
    for name in [args.format] if args.format else FORMATS:
        write_text_atomic(Path(args.out) / f"{name}.schema.json", _path(name).read_text())
    print(f"wrote {len([args.format] if args.format else FORMATS)} schemas into {args.out}")
    return 0
