"""The ``robot-rise`` command: a thin layer that parses, calls the library, prints.

Sub-commands live in modules named ``cmd_<name>.py`` in this package. Each exposes
``register(subparsers)`` which adds its parser and sets ``func`` (a callable taking the parsed
arguments and returning an exit code). They are discovered at start-up, so adding a command
never edits this file. This is the only room that wires ``robot_rise`` to ``drivers``.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys
import traceback
from collections.abc import Sequence

from robot_rise.errors import RobotRiseError

__all__ = ["main", "build_parser"]

EXIT_OK = 0
EXIT_FAILURE = 1  # the command ran but the answer is "no" (invalid posture, robot did not stand)
EXIT_ERROR = 2  # bad input or an error: nothing was produced


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every discovered sub-command."""
    parser = argparse.ArgumentParser(
        prog="robot-rise",
        description="Plan, filter and execute get-up motions for Dynamixel humanoids.",
        epilog="Example: robot-rise sample --kind supine --n 5 --seed 1 --out postures/",
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks and debug logs")
    parser.add_argument("-v", "--verbose", action="store_true", help="show info logs")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda i: i.name):
        if info.name.startswith("cmd_"):
            module = importlib.import_module(f"{__name__}.{info.name}")
            module.register(sub)
    return parser


def _external_error_types() -> tuple[type[BaseException], ...]:
    """Root errors of sibling packages the CLI wires in (absent ones are skipped)."""
    types: list[type[BaseException]] = [RobotRiseError]
    try:
        from drivers.errors import DriverError  # type: ignore[import-not-found]

        types.append(DriverError)
    except ImportError:
        pass
    return tuple(types)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.DEBUG if args.debug else logging.INFO if args.verbose else logging.WARNING
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_ERROR
    known = _external_error_types()
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except known as e:
        if args.debug:
            traceback.print_exc()
        print(f"error: {e}", file=sys.stderr)
        hint = getattr(e, "hint", "")
        if hint:
            print(f"hint: {hint}", file=sys.stderr)
        return EXIT_ERROR
    except (OSError, ValueError) as e:
        if args.debug:
            traceback.print_exc()
        print(f"error: {e}", file=sys.stderr)
        print("hint: run again with --debug for the traceback", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
