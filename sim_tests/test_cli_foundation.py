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


def test_that_sample_refuses_to_overwrite_a_posture_file_unless_forced(tmp_path, capsys):
    assert main(["sample", "--kind", "supine", "--n", "2", "--seed", "4", "--out", str(tmp_path)]) == 0
    first, second = sorted(tmp_path.glob("supine_4_*.json"))
    second.unlink()
    first.write_text("mine")
    capsys.readouterr()
    assert main(["sample", "--kind", "supine", "--n", "2", "--seed", "4", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err == f"error: {first} exists: pass --force to replace, or choose another --out or --seed\n"
    assert first.read_text() == "mine" and not second.exists()  # nothing half-written
    # kind "any": the names are known only after sampling; still refused before any file is written
    assert main(["sample", "--kind", "any", "--n", "1", "--seed", "4", "--out", str(tmp_path / "any")]) == 0
    written = next((tmp_path / "any").glob("*.json"))
    written.write_text("mine")
    capsys.readouterr()
    assert main(["sample", "--n", "1", "--seed", "4", "--out", str(tmp_path / "any")]) == 2
    assert written.read_text() == "mine" and "--force" in capsys.readouterr().err
    assert main(["sample", "--kind", "supine", "--n", "2", "--seed", "4", "--out", str(tmp_path), "--force"]) == 0
    assert first.read_text() != "mine" and second.exists()
