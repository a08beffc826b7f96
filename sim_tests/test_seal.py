"""Issue 41 (part 1): only what was proven runs. A proven trajectory carries the seal of what its
proof judged; execute, getup and the library loader refuse any edit, before the bus."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from robot_rise.bench.tamper import TAMPERS, tamper_campaign
from robot_rise.errors import FormatError
from robot_rise.library import default_library_dir, load_library
from robot_rise.model import load_robot
from robot_rise.seal import SEAL_KEY, seal_of, seal_problem, sealed
from robot_rise.trajectory import read_trajectory

LIBRARY = default_library_dir("op3")


def test_every_shipped_motion_is_sealed_and_its_seal_holds() -> None:
    for motion in load_library(LIBRARY).motions:
        assert motion.trajectory.report.get(SEAL_KEY) and not seal_problem(motion.trajectory), motion.name


def test_ten_edits_of_each_library_motion_are_refused_and_the_untouched_files_allowed() -> None:
    files = sorted(p for p in LIBRARY.glob("*.json") if not p.name.endswith(".start.json") and p.name != "index.json")
    rows = tamper_campaign(load_robot(), files[:3])
    for row in rows:
        assert row.untouched_allowed, row.untouched_reason
        assert not row.misses, (row.file, row.misses)
    assert all(len(r.refused) == len(TAMPERS) == 10 for r in rows)
    assert "not what was proven" in rows[0].refused["one row +1 mrad"]


def test_a_file_read_back_seals_the_same_and_an_unproven_one_is_not_sealed(tmp_path: Path) -> None:
    from robot_rise.trajectory import write_trajectory

    tr = load_library(LIBRARY).motions[0].trajectory
    write_trajectory(tmp_path / "t.json", tr)
    again = read_trajectory(tmp_path / "t.json")
    assert seal_of(again) == seal_of(tr) == tr.report[SEAL_KEY]
    unproven = sealed(tr.with_report(proven=False))
    assert SEAL_KEY not in unproven.report


def test_execute_refuses_an_edited_file_in_one_line_before_the_bus(tmp_path: Path) -> None:
    path = LIBRARY / "prone_elbow_knees_quick.json"
    obj = json.loads(path.read_text())
    obj["q"][10][3] += 1e-3  # one row, one joint, 1 mrad
    edited = tmp_path / "edited.json"
    edited.write_text(json.dumps(obj))
    r = subprocess.run([sys.executable, "-m", "robot_rise", "execute", str(edited), "--mock", "--yes"],
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "not what was proven" in r.stderr and "proven on robot" not in r.stdout


def test_the_library_loader_refuses_a_hand_edited_motion_until_it_is_proven_again(tmp_path: Path) -> None:
    lib = tmp_path / "lib"
    shutil.copytree(LIBRARY, lib)
    index = json.loads((lib / "index.json").read_text())
    index["motions"] = index["motions"][:1]  # one motion: re-proving it is quick
    (lib / "index.json").write_text(json.dumps(index))
    path = lib / index["motions"][0]["trajectory"]
    obj = json.loads(path.read_text())
    obj["q"][5][0] += 1e-3
    path.write_text(json.dumps(obj))
    with pytest.raises(FormatError, match="is not what was proven"):
        load_library(lib)
    r = subprocess.run([sys.executable, "-m", "robot_rise", "library", "prove", "--dir", str(lib)], capture_output=True, text=True, timeout=900)
    assert "PROVEN" in r.stdout, r.stdout + r.stderr
    motion = load_library(lib).motions[0]
    assert not seal_problem(motion.trajectory) and motion.trajectory.report[SEAL_KEY] != json.loads((LIBRARY / path.name).read_text())["report"][SEAL_KEY]
