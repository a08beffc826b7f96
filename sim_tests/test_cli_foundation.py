from __future__ import annotations

import json

import pytest

from robot_rise.cli import main


def test_sample_then_check_posture_round_trip(tmp_path, capsys):
    assert main(["sample", "--kind", "supine", "--n", "2", "--seed", "3", "--out", str(tmp_path)]) == 0
    files = sorted(tmp_path.glob("supine_3_*.json"))
    assert len(files) == 2
    capsys.readouterr()
    assert main(["check-posture", str(files[0]), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["valid"] is True and report["lying"] == "supine"


def test_check_posture_exits_one_for_an_invalid_posture(tmp_path, capsys):
    main(["sample", "--kind", "prone", "--n", "1", "--seed", "2", "--out", str(tmp_path)])
    posture = next(tmp_path.glob("*.json"))
    obj = json.loads(posture.read_text())
    obj["root_pos"][2] -= 0.02  # push it into the ground
    posture.write_text(json.dumps(obj))
    capsys.readouterr()
    assert main(["check-posture", str(posture)]) == 1
    assert "ground collision" in capsys.readouterr().out


def test_bad_input_is_one_clear_line_without_traceback(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "robot-rise/posture@1", "robot": "op3", "root_pos": [0, 0], "root_quat": [1, 0, 0, 0], "joints": {}}')
    assert main(["check-posture", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "root_pos" in err and "Traceback" not in err
    assert main(["check-posture", str(tmp_path / "missing.json")]) == 2
    assert "no such posture file" in capsys.readouterr().err


def test_every_command_has_help_with_an_example(capsys):
    from robot_rise.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():
        assert "example" in (p.epilog or "").lower(), name


def test_no_command_prints_help_and_exits_with_usage_error(capsys):
    assert main([]) == 2
    assert "COMMAND" in capsys.readouterr().out


@pytest.mark.parametrize("argv", [["sample", "--out", "x", "--n", "0"], ["sample", "--out", "x", "--robot", "/nonexistent"]])
def test_sample_rejects_bad_arguments_cleanly(argv, capsys):
    assert main(argv) == 2
    assert capsys.readouterr().err.startswith("error: ")
