"""Issue 42: the published JSON Schemas of the file formats accept every file robot_rise ships and
writes, and refuse what its readers refuse."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import jsonschema
import pytest
from referencing import Registry, Resource

from robot_rise.paths import configs_dir

SCHEMAS = {p.name.removesuffix(".schema.json"): json.loads(p.read_text()) for p in (configs_dir() / "schemas").glob("*.schema.json")}
REGISTRY = Registry().with_resources((s["$id"], Resource.from_contents(s)) for s in SCHEMAS.values())


def _validator(name: str) -> jsonschema.Draft202012Validator:
    return jsonschema.Draft202012Validator(SCHEMAS[name], registry=REGISTRY)


def test_every_schema_is_a_valid_draft_2020_12_schema() -> None:
    assert set(SCHEMAS) == {"posture@1", "trajectory@1", "servos@1"}
    for schema in SCHEMAS.values():
        jsonschema.Draft202012Validator.check_schema(schema)


def test_the_shipped_library_and_robot_files_follow_their_schemas() -> None:
    library = configs_dir() / "motions" / "op3"
    for path in sorted(library.glob("*.start.json")):
        _validator("posture@1").validate(json.loads(path.read_text()))
    trajectories = [p for p in library.glob("*.json") if not p.name.endswith(".start.json") and p.name != "index.json"]
    assert len(trajectories) >= 10
    for path in trajectories:
        _validator("trajectory@1").validate(json.loads(path.read_text()))
    _validator("servos@1").validate(tomllib.loads((configs_dir() / "robots" / "op3" / "servos.toml").read_text()))


@pytest.mark.parametrize(
    ("name", "edit"),
    [
        ("trajectory@1", lambda o: o.update(t=[str(x) for x in o["t"]])),
        ("trajectory@1", lambda o: o["t"].__setitem__(-1, 1e6)),
        ("trajectory@1", lambda o: o["start"].pop("root_quat")),
        ("posture@1", lambda o: o.update(format="robot-rise/posture@2")),
        ("posture@1", lambda o: o["joints"].update(l_knee="bent")),
    ],
)
def test_a_malformed_file_fails_its_schema(name: str, edit) -> None:  # type: ignore[no-untyped-def]
    library = configs_dir() / "motions" / "op3"
    path = library / ("prone_elbow_knees.json" if name == "trajectory@1" else "prone_elbow_knees.start.json")
    obj = json.loads(path.read_text())
    edit(obj)
    with pytest.raises(jsonschema.ValidationError):
        _validator(name).validate(obj)


def test_a_servo_map_with_a_bad_id_fails_its_schema() -> None:
    data = tomllib.loads((configs_dir() / "robots" / "op3" / "servos.toml").read_text())
    data["servo"][0]["id"] = 300
    with pytest.raises(jsonschema.ValidationError):
        _validator("servos@1").validate(data)


def test_the_cli_prints_and_writes_the_schemas(tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, "-m", "robot_rise", "schema", "posture@1"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and json.loads(r.stdout)["$id"] == "robot-rise/posture@1"
    r = subprocess.run([sys.executable, "-m", "robot_rise", "schema", "--out", str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and sorted(p.name for p in tmp_path.iterdir()) == [f"{n}.schema.json" for n in sorted(SCHEMAS)]
