"""servos.toml has one reader and one writer (robot_files.servo_map): the core and the bus read it the same way."""

from __future__ import annotations

import json
import shutil
import tomllib
from pathlib import Path

import jsonschema
import pytest

from drivers.errors import ServoMapError
from drivers.servo_map import load_servo_map, parse_servo_map
from robot_files.errors import RobotFileError
from robot_files.servo_map import (
    DEFAULT_LIMIT_RAD,
    SERVO_MAP_FORMAT,
    BusSettings,
    ServoMapFile,
    ServoRow,
    parse_servo_map_data,
    read_servo_map,
    servo_map_data,
    write_servo_map,
)
from robot_files.toml_file import read_toml, toml_text, write_toml
from robot_rise.errors import ConfigError
from robot_rise.model import load_robot
from robot_rise.paths import configs_dir, default_robot_dir
from robot_rise.robot_import.directory import write_servos

OP3_MAP = default_robot_dir() / "servos.toml"
SHARED = Path(__file__).resolve().parents[2] / "shared" / "robots"
SCHEMA = json.loads((configs_dir() / "schemas" / "servos@1.schema.json").read_text())


def _maps() -> list[Path]:
    maps = [OP3_MAP, Path(__file__).parent / "data" / "wolfgang_servos.toml"]
    return maps + sorted(SHARED.glob("*/*servos*.toml"))


@pytest.mark.parametrize("path", _maps(), ids=lambda p: p.name)
def test_a_servo_map_written_reads_back_equal(path: Path, tmp_path: Path) -> None:
    smap = read_servo_map(path)
    out = tmp_path / "servos.toml"
    write_servo_map(out, smap)
    assert read_servo_map(out) == smap
    assert tomllib.loads(out.read_text()) == servo_map_data(smap)  # the file holds exactly the values
    jsonschema.Draft202012Validator(SCHEMA).validate(tomllib.loads(out.read_text()))  # and follows the published schema
    try:  # and the bus reads the same map from it, or refuses both the same way
        on_the_bus = load_servo_map(path)
    except ServoMapError as e:  # wolfgang_ros: an import input whose +-3.1415 is beyond one turn in ticks
        with pytest.raises(ServoMapError) as again:
            load_servo_map(out)
        assert str(again.value).replace(str(out), str(path)) == str(e)
    else:
        assert load_servo_map(out) == on_the_bus


def test_the_bus_settings_a_file_adds_and_the_defaults_survive_the_round_trip(tmp_path: Path) -> None:
    bus = BusSettings(3_000_000, 2.0, 14.8, 1.0, extra=(("port", "/dev/ttyUSB0"), ("latency_timer_ms", 1), ("rs485", True)))
    rows = (ServoRow(1, "a b", "MX-28", -1, 0.012345678901, -1.25, 2.5), ServoRow(252, 'quote"d', "AX-18A"))
    smap = ServoMapFile("with \\ and \"", bus, rows)
    write_servo_map(tmp_path / "s.toml", smap)
    assert read_servo_map(tmp_path / "s.toml") == smap  # every row written with its limits
    assert (tmp_path / "s.toml").read_text().startswith("# Servo map:")


def test_the_importers_servo_map_reads_back_as_written_to_six_decimals(tmp_path: Path) -> None:
    rows = (ServoRow(1, "knee", "MX-28", 1, 0.1234567891, -1.0000004, 1.5), ServoRow(2, "hip", "XM430-W350", -1, 0.0, -0.5, 0.5))
    write_servos(tmp_path / "servos.toml", "mini", rows, BusSettings(supply_voltage_v=11.1, extra=(("gain", 0.33333333),)))
    back = read_servo_map(tmp_path / "servos.toml")
    assert back.robot == "mini" and back.bus.supply_voltage_v == 11.1 and back.bus.extra == (("gain", 0.333333),)
    assert (back.servos[0].zero_offset, back.servos[0].min, back.servos[0].max) == (0.123457, -1.0, 1.5)
    assert back.servos[1] == rows[1]


def test_toml_written_by_the_one_writer_reads_back_equal(tmp_path: Path) -> None:
    data = {"format": "x@1", "name": "r", "passive": ["a"], "limbs": {"torso": ["a", "b"]},
            "roles": {"l knee": {"role": "left.knee", "sign": -1, "neutral": 0.25}}}
    write_toml(tmp_path / "r.toml", data, comments=("first", "", "last"))
    assert read_toml(tmp_path / "r.toml", "file") == data
    assert toml_text(data, comments=("first", "", "last")).startswith("# first\n#\n# last\n")
    with pytest.raises(RobotFileError, match="cannot write TOML"):
        toml_text({"a": None})


# Edits of the OP3's servos.toml and the one-line reason every reader gives for refusing them.
BAD = [
    ('format = "robot-rise/servos@1"', 'format = "robot-rise/servos@2"', "format is 'robot-rise/servos@2', expected 'robot-rise/servos@1'"),
    ("protocol = 2.0", "protocol = 3.0", "[bus] protocol 3.0 is not a Dynamixel protocol"),
    ("protocol = 2.0", "protocol = true", "[bus] protocol True is not a Dynamixel protocol"),
    ("baud_rate = 2000000 ", 'baud_rate = "fast" ', "[bus] baud_rate must be a whole number of bit/s above 0, not 'fast'"),
    ("return_delay_time_us = 2", "return_delay_time_us = 600", "[bus] return_delay_time_us must be a number in 0..508, not 600.0"),
    ("[bus]\n", '[bus]\nsupply_voltage_v = "12"\n', "[bus] supply_voltage_v must be a number of volts in 5..30, not '12'"),
    ("[bus]\n", "[bus]\nport = [1]\n", "[bus] keys must be plain settings (number or text); not: port"),
    ("id = 1\n", "id = 300\n", "servo 300 ('r_sho_pitch'): id must be a whole number in 0..252 (Dynamixel IDs), not 300"),
    ("id = 1\n", "id = 1.5\n", "servo 1.5 ('r_sho_pitch'): id must be a whole number in 0..252 (Dynamixel IDs), not 1.5"),
    ("id = 2\n", "id = 1\n", "servo 1 ('l_sho_pitch'): id 1 appears twice (duplicate servo id)"),
    ('joint = "l_sho_pitch"', 'joint = "r_sho_pitch"', "servo 2 ('r_sho_pitch'): joint r_sho_pitch appears twice"),
    ("direction = 1\n", "direction = 2\n", "servo 1 ('r_sho_pitch'): direction must be 1 or -1, not 2"),
    ("zero_offset = 0.0\n", "zero_ofset = 0.0\n", "servo 1 ('r_sho_pitch'): unknown key(s) zero_ofset"),
    ("zero_offset = 0.0\n", 'zero_offset = "0"\n', "servo 1 ('r_sho_pitch'): zero_offset must be a number of radians, not '0'"),
    ("min = -2.7925\nmax = 2.7925", "min = 2.7925\nmax = -2.7925", "servo 1 ('r_sho_pitch'): min 2.7925 must be below max -2.7925"),
    ('model = "XM430-W350"', "model = 430", "servo 1 ('r_sho_pitch'): model must name a servo model"),
    ('robot = "op3"', "robot = 3", "robot must be the robot's name (text), not 3"),
    ("[[servo]]", "[servo]", "no [[servo]] rows"),
]


def _edited(tmp_path: Path, old: str, new: str) -> Path:
    robot = tmp_path / "op3"
    shutil.copytree(OP3_MAP.parent, robot)
    text = OP3_MAP.read_text()
    assert old in text
    (robot / "servos.toml").write_text(text.replace(old, new, 1) if old != "[[servo]]" else text.split("\n[[servo]]")[0] + "\n[servo]\nid = 1\n")
    return robot


@pytest.mark.parametrize(("old", "new", "reason"), BAD, ids=[b[2][:40] for b in BAD])
def test_the_core_and_the_bus_refuse_a_bad_servo_map_with_the_same_line(tmp_path: Path, old: str, new: str, reason: str) -> None:
    robot = _edited(tmp_path, old, new)
    path = robot / "servos.toml"
    messages = []
    for read, error in ((read_servo_map, RobotFileError), (load_servo_map, ServoMapError), (load_robot, ConfigError)):
        with pytest.raises(error) as e:
            read(robot if read is load_robot else path)
        messages.append(str(e.value))
    assert messages[0] == messages[1] == messages[2], messages
    assert messages[0].startswith(f"{path}: ") and reason in messages[0] and "\n" not in messages[0], messages[0]


def test_a_missing_or_broken_file_is_one_line_naming_it(tmp_path: Path) -> None:
    with pytest.raises(RobotFileError, match=f"missing servo map {tmp_path / 'nope.toml'}"):
        read_servo_map(tmp_path / "nope.toml")
    (tmp_path / "bad.toml").write_text("format = [")
    with pytest.raises(ServoMapError, match=r"bad.toml: not valid TOML: Invalid value"):
        load_servo_map(tmp_path / "bad.toml")
    (tmp_path / "bin.toml").write_bytes(b"\xff\xfe")
    with pytest.raises(RobotFileError, match="not UTF-8 text"):
        read_servo_map(tmp_path / "bin.toml")
    with pytest.raises(RobotFileError, match="cannot read servo map"):
        read_servo_map(tmp_path)


def test_limits_are_required_except_where_a_reader_gives_defaults() -> None:
    doc = {"format": SERVO_MAP_FORMAT, "servo": [{"id": 1, "joint": "a", "model": "XM430-W350", "min": -1.0}]}
    with pytest.raises(RobotFileError, match=r"servo 1 \('a'\): lacks max"):
        parse_servo_map_data(doc)
    spec = parse_servo_map(doc).servos[0]  # a bus rig's map: the drivers' default on the missing side
    assert (spec.min, spec.max) == (-1.0, DEFAULT_LIMIT_RAD)


def test_whole_numbers_and_the_documented_defaults_read_as_before() -> None:
    doc = {"format": SERVO_MAP_FORMAT, "bus": {"protocol": 1, "baud_rate": 1e6}, "servo": [
        {"id": 3.0, "joint": "a", "model": "MX-28", "direction": -1.0, "min": -1, "max": 1}]}
    smap = parse_servo_map(doc)
    assert smap.bus == type(smap.bus)(1_000_000, 0.0, 12.0, 1.0)
    s = smap.servos[0]
    assert (s.id, s.direction, s.zero_offset, s.min, s.max) == (3, -1, 0.0, -1.0, 1.0)
    assert type(s.id) is int and type(s.direction) is int and type(s.min) is float
