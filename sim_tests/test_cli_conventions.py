"""The CLI's conventions, checked on the real argparse tree of ``robot_rise.cli`` (issue 42).

For every command: the global flags (-v/--verbose, --debug, --version) are accepted after it; every
help example parses with the real parser (parsed only, never run); an example that reads a file
out of the demo's directory names a file the demo writes; every command that reports has
``--json``, and the cheap ones print one JSON object.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
from collections.abc import Iterator

import pytest

from robot_rise.cli import build_parser, main, parse_args
from robot_rise.cli import cmd_demo

PARSER = build_parser()


def _commands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    """Every command path with its parser, sub-commands of sub-commands included (aliases once)."""
    yield path, parser
    seen: set[int] = set()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                if id(sub) not in seen:
                    seen.add(id(sub))
                    yield from _commands(sub, (*path, name))


COMMANDS = dict(_commands(PARSER))
LEAVES = sorted(path for path, p in COMMANDS.items() if p.get_default("func") is not None)


def _minimal_argv(parser: argparse.ArgumentParser) -> list[str]:
    """The fewest arguments the parser accepts: each required positional and option, given a value."""
    argv: list[str] = []
    for group in parser._mutually_exclusive_groups:
        if group.required:
            first = group._group_actions[0]
            argv += [first.option_strings[0], *_values(first)]
    grouped = {id(a) for g in parser._mutually_exclusive_groups for a in g._group_actions}
    for a in parser._actions:
        if id(a) in grouped or isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        if not a.option_strings:
            argv += _values(a)
        elif a.required:
            argv += [a.option_strings[0], *_values(a)]
    return argv


def _values(a: argparse.Action) -> list[str]:
    if a.nargs == 0:
        return []
    value = str(next(iter(a.choices))) if a.choices else "1"  # "1" is a valid str, int, float and path
    return [] if a.nargs in ("?", "*") else [value]


def _examples() -> list[tuple[tuple[str, ...], str]]:
    """(command path, example command line) for every example line of every help epilog."""
    found = []
    for path, p in COMMANDS.items():
        for line in (p.epilog or "").splitlines():
            text = re.sub(r"^\s*examples?:\s*", "", line, flags=re.IGNORECASE).strip()
            text = re.sub(r"^nice -n \d+ ", "", text)
            if text.startswith("robot-rise "):
                found.append((path, text))
    return found


EXAMPLES = _examples()


def _words(example: str) -> list[str]:
    words = shlex.split(example, comments=True)[1:]
    return words[: words.index(">")] if ">" in words else words


def test_the_tree_has_the_commands_people_use():
    for path in [("rise",), ("execute",), ("servos", "scan"), ("library", "list"), ("robot", "show"), ("demo",)]:
        assert path in LEAVES, path
    assert len(EXAMPLES) > 40


def test_that_no_command_defines_a_flag_named_like_a_global_one():
    for path in LEAVES:
        flags = {o for a in COMMANDS[path]._actions for o in a.option_strings}
        assert not flags & {"-v", "--verbose", "--debug", "--version"}, path


@pytest.mark.parametrize("path", LEAVES, ids=" ".join)
def test_that_global_flags_are_accepted_after_the_command(path):
    argv = [*path, *_minimal_argv(COMMANDS[path])]
    assert parse_args(argv, PARSER).func is COMMANDS[path].get_default("func")
    for flags in (["--debug"], ["-v"], ["--verbose"], ["--debug", "-v"]):
        args = parse_args([*argv, *flags], PARSER)
        assert args.debug == ("--debug" in flags) and args.verbose == ("-v" in flags or "--verbose" in flags), (argv, flags)
        assert args.func is COMMANDS[path].get_default("func")


@pytest.mark.parametrize("where", [[], ["rise"], ["library", "list"]], ids=["alone", "after rise", "after library list"])
def test_that_version_prints_the_version_and_exits_zero(where, capsys):
    with pytest.raises(SystemExit) as e:
        main([*where, "--version"])
    assert e.value.code == 0
    assert re.match(r"robot-rise \S+", capsys.readouterr().out)


@pytest.mark.parametrize(("path", "example"), EXAMPLES, ids=[e for _, e in EXAMPLES])
def test_that_every_help_example_parses(path, example):
    words = _words(example)
    try:
        args = parse_args(words, PARSER)
    except SystemExit as e:
        pytest.fail(f"help of {' '.join(path) or 'robot-rise'}: {example!r} does not parse (exit {e.code})")
    assert getattr(args, "func", None) is not None, example


def test_that_examples_read_only_files_the_demo_writes():
    default_out = PARSER._subparsers._group_actions[0].choices["demo"].get_default("out")  # type: ignore[union-attr]
    written = {f"{default_out}/{name}" for name in cmd_demo.WRITES}
    for _, example in EXAMPLES:
        words = _words(example)
        for before, word in zip(["", *words], words):
            if word.startswith(default_out + "/") and before not in ("--out", "--log"):
                assert word in written, f"{example!r} reads {word}, which the demo does not write ({sorted(written)})"


# commands that report nothing a program would read: an interactive window, a schema (itself JSON), a server
NOT_REPORTING = {("view",): "an interactive viewer", ("schema",): "prints a JSON Schema, itself JSON",
                 ("mockbus", "serve"): "a server until Ctrl-C; its device line is for a person"}
# reporting commands still without --json (remove an entry when its --json lands)
JSON_TO_DO: set[tuple[str, ...]] = set()


def _has_json(path: tuple[str, ...]) -> bool:
    return "--json" in {o for a in COMMANDS[path]._actions for o in a.option_strings}


def test_that_every_reporting_command_has_json():
    missing = {path for path in LEAVES if not _has_json(path)}
    assert missing - set(NOT_REPORTING) - JSON_TO_DO == set(), "reporting commands without --json"
    assert JSON_TO_DO - missing == set(), "these have --json now: take them off JSON_TO_DO"


@pytest.mark.parametrize(
    "argv",
    [["library", "list"], ["library", "show", "prone_knees_first"], ["robot", "show"], ["servos", "scan", "--mock"],
     ["servos", "status", "--mock"], ["servos", "torque", "off", "--mock"], ["servos", "reboot", "1", "--mock"]],
    ids=" ".join,
)
def test_that_json_output_is_one_json_object(argv, capsys):
    assert main([*argv, "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert isinstance(obj, dict) and obj


def test_that_library_list_json_has_the_facts_the_text_prints(capsys):
    assert main(["library", "list"]) == 0
    text = capsys.readouterr().out
    assert main(["library", "list", "--json"]) == 0
    motions = json.loads(capsys.readouterr().out)["motions"]
    assert len(motions) == len(text.splitlines()) - 1
    for m in motions:
        assert m["name"] in text and f"{m['duration_s']:8.2f}s" in text
        assert set(m) == {"name", "lying", "duration_s", "peak_envelope_ratio", "strategy"}


def test_that_export_csv_and_read_posture_report_as_json(tmp_path, capsys):
    assert main(["servos", "read-posture", "--mock", "--out", str(tmp_path / "p.json"), "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["file"] == str(tmp_path / "p.json") and (tmp_path / "p.json").exists() and len(obj["joints"]) == 20
    from robot_rise.library import load_library, robot_library_dir
    from robot_rise.model import load_robot
    from robot_rise.trajectory import write_trajectory

    robot = load_robot(None)
    tr = load_library(robot_library_dir(robot)).get("prone_knees_first").trajectory
    write_trajectory(tmp_path / "t.json", tr)
    assert main(["export-csv", str(tmp_path / "t.json"), "--units", "ticks", "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["units"] == "ticks" and obj["rate_hz"] == 100 and len(obj["columns"]) == 20
    assert len((tmp_path / "t.csv").read_text().splitlines()) == obj["rows"] + 1


def test_that_execute_json_on_the_twin_is_one_object_with_no_faults(capsys):
    from robot_rise.paths import configs_dir

    motion = configs_dir() / "motions" / "op3" / "prone_elbow_knees_quick.json"  # shipped, proven
    assert main(["execute", str(motion), "--mock", "--twin", "--yes", "--json"]) == 0
    out, err = capsys.readouterr()
    obj = json.loads(out)  # stdout is the object alone
    assert obj["exit_code"] == 0 and obj["proven"] is True and obj["completed"] is True
    assert obj["faults"] == [] and obj["clamped_cycles"] == 0 and obj["twin"]["upright"] is True
    assert obj["cycles"] > 0 and 0 <= obj["band_used"] < 1 and len(obj["tracking_band_rad"]) == 2
    assert "preflight:" in err and "proven on robot op3" in err  # progress went to stderr
