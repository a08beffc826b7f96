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
import math
import pkgutil
import sys
import traceback
from collections.abc import Callable, Sequence

from robot_rise.errors import RobotRiseError

__all__ = ["main", "build_parser", "parse_args"]

EXIT_OK = 0
EXIT_FAILURE = 1  # the command ran but the answer is "no" (invalid posture, robot did not stand)
EXIT_ERROR = 2  # bad input or an error: nothing was produced


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version  # noqa: PLC0415

    try:
        return version("robot-rise")
    except PackageNotFoundError:  # run from a checkout that is not installed
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every discovered sub-command."""
    parser = argparse.ArgumentParser(
        prog="robot-rise",
        description="Plan, filter and execute get-up motions for Dynamixel humanoids.",
        epilog="Example: robot-rise sample --kind supine --n 5 --seed 1 --out postures/",
    )
    parser.add_argument("--version", action="version", version=f"robot-rise {_version()}")
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


_GLOBAL_FLAGS = ("--debug", "-v", "--verbose", "--version")


def _globals_first(argv: Sequence[str]) -> list[str]:
    """The global flags moved before the command: ``rise ... --debug`` as ``--debug rise ...``.

    No sub-command defines a flag of the same name (sim_tests/test_cli_conventions.py checks it).
    """
    argv = list(argv)
    end = argv.index("--") if "--" in argv else len(argv)
    flags = [a for a in argv[:end] if a in _GLOBAL_FLAGS]
    return flags + [a for a in argv[:end] if a not in _GLOBAL_FLAGS] + argv[end:]


def _positive(x: float) -> bool:
    return math.isfinite(x) and x > 0


def _non_negative(x: float) -> bool:
    return math.isfinite(x) and x >= 0


# flags (by their dest) whose values must mean something, wherever a command has them
_FLAG_RULES: dict[str, tuple[Callable[[float], bool], str]] = {
    "budget": (_positive, "a positive number of seconds"),
    "margin": (lambda x: math.isfinite(x) and 0 <= x < 1, "a fraction in [0, 1)"),
    "width": (lambda x: 16 <= x <= 8192, "a width in 16..8192 pixels"),
    "height": (lambda x: 16 <= x <= 8192, "a height in 16..8192 pixels"),
    "fps": (lambda x: math.isfinite(x) and 0 < x <= 240, "a frame rate in (0, 240]"),
    "jobs": (lambda x: x >= 1, "a whole number of processes, at least 1"),
    "seed": (lambda x: x >= 0, "a non-negative whole number"),
    "n": (lambda x: x >= 1, "a whole number, at least 1"),
    "n_per_kind": (lambda x: x >= 1, "a whole number, at least 1"),
    "variants": (lambda x: x >= 0, "a non-negative whole number"),
    "tolerance": (_non_negative, "a non-negative number of radians"),
    "baud": (_positive, "a positive baud rate"),
    "rate": (_positive, "a positive rate in Hz"),
    "supply_voltage": (_positive, "a positive number of volts"),
}


_ACTION_DESTS = ("robot_command", "library_command", "bench", "servos_cmd", "mockbus_cmd")


def _check_flag_values(args: argparse.Namespace) -> str:
    """Why a flag's value means nothing (a budget of 0, a width of nan), '' if none: a usage error (exit 2)."""
    for dest, (ok, what) in _FLAG_RULES.items():
        value = getattr(args, dest, None)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        if not ok(float(value)):
            command = " ".join(str(v) for k, v in vars(args).items() if k in ("command", *_ACTION_DESTS) and isinstance(v, str))
            return f"{command + ': ' if command else ''}argument --{dest.replace('_', '-')}: must be {what}, not {value!r}"
    return ""


def parse_args(argv: Sequence[str], parser: argparse.ArgumentParser | None = None) -> argparse.Namespace:
    """Parse a command line as :func:`main` does (global flags anywhere); argparse exits on bad usage."""
    return (parser or build_parser()).parse_args(_globals_first(argv))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the process exit code."""
    parser = build_parser()
    args = parse_args(sys.argv[1:] if argv is None else argv, parser)
    bad_flag = _check_flag_values(args)
    if bad_flag:
        print(f"error: {bad_flag}", file=sys.stderr)
        return EXIT_ERROR
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
