"""The servo map file (``servos.toml``, format ``robot-rise/servos@1``): its one reader and writer.

Which Dynamixel servo drives which joint, in SI units and radians (ticks are ``drivers``' own)::

    format = "robot-rise/servos@1"
    robot = "op3"                      # optional

    [bus]                              # optional; these are the defaults
    protocol = 2.0                     # Dynamixel protocol: 2.0 or 1.0
    baud_rate = 1000000                # [bit/s]
    return_delay_time_us = 0.0         # [us], 0..508
    supply_voltage_v = 12.0            # [V], 5..30: what the simulation models the servos at
    # other plain settings (a number, text or true/false) are kept as given

    [[servo]]                          # one or more
    id = 1                             # bus ID, 0..252
    joint = "r_sho_pitch"              # joint name in the robot model
    model = "XM430-W350"               # servo model (configs/servos/catalog.toml)
    direction = 1                      # 1 or -1: 1 when the servo turns the joint the model's way
    zero_offset = 0.0                  # [rad] added to the joint angle before conversion
    min = -2.7925                      # [rad] joint limits (required unless a reader gives defaults)
    max = 2.7925

:func:`read_servo_map` is the only reader: ``robot_rise`` (the robot directory, the importer) and
``drivers`` (the bus) read the file through it, so they never disagree about one. It checks the
file alone: keys, types, ranges, duplicates. What the file must also agree with is checked
where that lives: the model's joints and ranges and the servo catalog in ``robot_rise``, the
control tables (model on this protocol, baud rates, limits in ticks) in ``drivers``.
:func:`write_servo_map` is the only writer (``tomli-w``); what it writes reads back equal.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_files.errors import RobotFileError
from robot_files.toml_file import read_toml, write_toml

__all__ = [
    "SERVO_MAP_FORMAT",
    "SERVO_MAP_FILE",
    "PROTOCOLS",
    "SUPPLY_RANGE_V",
    "SUPPLY_VOLTAGE_V",
    "DEFAULT_LIMIT_RAD",
    "SERVO_MAP_COMMENTS",
    "MIN_SERVO_ID",
    "MAX_SERVO_ID",
    "BusSettings",
    "ServoRow",
    "ServoMapFile",
    "check_supply_voltage",
    "parse_servo_map_data",
    "read_servo_map",
    "servo_map_data",
    "write_servo_map",
]

SERVO_MAP_FORMAT = "robot-rise/servos@1"
SERVO_MAP_FILE = "servos.toml"  # the servo map's name in a robot directory
PROTOCOLS = (1.0, 2.0)  # the Dynamixel protocols [bus] protocol may name
SUPPLY_VOLTAGE_V = 12.0  # [V] the servos' supply unless [bus] supply_voltage_v gives one
SUPPLY_RANGE_V = (5.0, 30.0)  # [V] Dynamixels run on 5-24 V (XL330 5 V to MX/XH 14.8 V 4S LiPo, 24 V Pro): a typo guard
RETURN_DELAY_MAX_US = 508.0  # [us] Return Delay Time register: 0..254 in 2 us units
MIN_SERVO_ID, MAX_SERVO_ID = 0, 252  # Dynamixel IDs (253 is reserved, 254 broadcasts)
DEFAULT_LIMIT_RAD = 3.14  # [rad] a row's limits where a reader allows none: just inside one turn of position mode

_BUS_KEYS = ("protocol", "baud_rate", "return_delay_time_us", "supply_voltage_v")
_ROW_KEYS = ("id", "joint", "model", "direction", "zero_offset", "min", "max")
SERVO_MAP_COMMENTS = (  # what write_servo_map heads a file with
    "Servo map: which servo drives which joint (IDs, models, directions, zero offsets, limits in radians).",
    "[bus] supply_voltage_v: the servos' supply (12.0 for a 3S LiPo at 4 V a cell, 14.8 for a 4S at its",
    "nominal): every simulation models the servos' torque and speed at it.",
)

Setting = str | int | float | bool


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _float(value: Any) -> Any:
    """A number as a float; anything else as it is."""
    return float(value) if _is_number(value) else value


def _whole(value: object) -> int | None:
    """``value`` as an int if it is a whole number (``3`` or ``3.0``, not ``true``), else None."""
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return None


def check_supply_voltage(value: object, where: str) -> float:
    """``value`` as a servo supply [V].

    Raises:
        RobotFileError: not a number in ``SUPPLY_RANGE_V`` (the message starts with ``where``).
    """
    lo, hi = SUPPLY_RANGE_V
    if not (_is_number(value) and lo <= value <= hi):  # type: ignore[operator]
        raise RobotFileError(f"{where} must be a number of volts in {lo:g}..{hi:g}, not {value!r}")
    return float(value)  # type: ignore[arg-type]


@dataclass(frozen=True)
class BusSettings:
    """``[bus]``: the bus and the servos' supply.

    Attributes:
        baud_rate: [bit/s], > 0 (which rates a protocol has is ``drivers``' to check).
        return_delay_time_us: servo reply delay [us], 0..508 (the register counts 2 us).
        supply_voltage_v: the servos' supply [V] (e.g. 14.8 for a 4S LiPo): what the robot's
            simulation models them at.
        protocol: Dynamixel protocol of the bus, 2.0 or 1.0.
        extra: other settings of the table, kept as given: (key, number, text or bool) pairs.
    """

    baud_rate: int = 1_000_000
    return_delay_time_us: float = 0.0
    supply_voltage_v: float = SUPPLY_VOLTAGE_V
    protocol: float = 2.0
    extra: tuple[tuple[str, Setting], ...] = ()

    def __post_init__(self) -> None:
        if self.protocol not in PROTOCOLS or isinstance(self.protocol, bool):
            raise RobotFileError(f"protocol {self.protocol!r} is not a Dynamixel protocol", hint="use protocol = 2.0 or protocol = 1.0")
        if isinstance(self.baud_rate, bool) or not isinstance(self.baud_rate, int) or self.baud_rate <= 0:
            raise RobotFileError(f"baud_rate must be a whole number of bit/s above 0, not {self.baud_rate!r}")
        if not (_is_number(self.return_delay_time_us) and 0 <= self.return_delay_time_us <= RETURN_DELAY_MAX_US):
            raise RobotFileError(f"return_delay_time_us must be a number in 0..{RETURN_DELAY_MAX_US:g}, not {self.return_delay_time_us!r}")
        check_supply_voltage(self.supply_voltage_v, "supply_voltage_v")
        odd = [str(k) for k, v in self.extra if k in _BUS_KEYS or not isinstance(k, str) or not k.replace("_", "").isalnum() or not isinstance(v, Setting)]
        if odd:
            raise RobotFileError(f"keys must be plain settings (number or text); not: {', '.join(odd)}")


@dataclass(frozen=True)
class ServoRow:
    """One ``[[servo]]`` row. Angles in radians.

    Attributes:
        id: bus ID, 0..252.
        joint: joint name in the robot model.
        model: servo model name (the servo catalog's, e.g. ``"XM430-W350"``).
        direction: +1 or -1.
        zero_offset: [rad] added to the joint angle before conversion.
        min: lower joint limit [rad].
        max: upper joint limit [rad], above ``min``.
    """

    id: int
    joint: str
    model: str
    direction: int = 1
    zero_offset: float = 0.0
    min: float = -DEFAULT_LIMIT_RAD
    max: float = DEFAULT_LIMIT_RAD

    def __post_init__(self) -> None:
        where = _label(self.id, self.joint)
        if isinstance(self.id, bool) or not isinstance(self.id, int) or not MIN_SERVO_ID <= self.id <= MAX_SERVO_ID:
            raise RobotFileError(f"{where}: id must be a whole number in {MIN_SERVO_ID}..{MAX_SERVO_ID} (Dynamixel IDs), not {self.id!r}")
        if not isinstance(self.joint, str) or not self.joint:
            raise RobotFileError(f"{where}: joint must name a joint of the model")
        if not isinstance(self.model, str) or not self.model:
            raise RobotFileError(f"{where}: model must name a servo model (e.g. \"MX-28\")")
        if not _is_number(self.direction) or self.direction not in (1, -1):
            raise RobotFileError(f"{where}: direction must be 1 or -1, not {self.direction!r}")
        for key in ("zero_offset", "min", "max"):
            value = getattr(self, key)
            if not _is_number(value) or not math.isfinite(value):
                raise RobotFileError(f"{where}: {key} must be a number of radians, not {value!r}")
        if not self.min < self.max:
            raise RobotFileError(f"{where}: min {self.min} must be below max {self.max}")

    @property
    def label(self) -> str:
        """How messages name this servo: ``joint (id N)``."""
        return f"{self.joint} (id {self.id})"


def _label(sid: object, joint: object) -> str:
    return f"servo {sid!r} ({joint!r})"


@dataclass(frozen=True)
class ServoMapFile:
    """A servo map as its file holds it.

    Attributes:
        robot: robot name ("" if the file names none).
        bus: :class:`BusSettings`.
        servos: the ``[[servo]]`` rows in file order, one or more, no id or joint twice.
    """

    robot: str
    bus: BusSettings
    servos: tuple[ServoRow, ...]

    def __post_init__(self) -> None:
        if not self.servos:
            raise RobotFileError("no [[servo]] rows")
        ids: set[int] = set()
        joints: set[str] = set()
        for s in self.servos:
            if s.id in ids:
                raise RobotFileError(f"{_label(s.id, s.joint)}: id {s.id} appears twice (duplicate servo id)")
            if s.joint in joints:
                raise RobotFileError(f"{_label(s.id, s.joint)}: joint {s.joint} appears twice (duplicate servo joint)")
            ids.add(s.id)
            joints.add(s.joint)


def _bus(raw: object, source: str) -> BusSettings:
    if not isinstance(raw, Mapping):
        raise RobotFileError(f"{source}: [bus] must be a table")
    baud = raw.get("baud_rate", 1_000_000)
    try:  # numbers as their field's type; anything else for BusSettings to refuse by name
        return BusSettings(
            baud_rate=baud if _whole(baud) is None else _whole(baud),  # type: ignore[arg-type]
            return_delay_time_us=_float(raw.get("return_delay_time_us", 0.0)),
            supply_voltage_v=_float(raw.get("supply_voltage_v", SUPPLY_VOLTAGE_V)),
            protocol=_float(raw.get("protocol", 2.0)),
            extra=tuple((k, v) for k, v in raw.items() if k not in _BUS_KEYS),
        )
    except RobotFileError as e:
        raise RobotFileError(f"{source}: [bus] {e}", hint=e.hint) from None


def _row(k: int, raw: object, source: str, default_limit_rad: float | None) -> ServoRow:
    if not isinstance(raw, Mapping):
        raise RobotFileError(f"{source}: servo row {k + 1} is not a table")
    where = f"{source}: {_label(raw.get('id'), raw.get('joint'))}"
    unknown = sorted(set(raw) - set(_ROW_KEYS))
    if unknown:
        raise RobotFileError(f"{where}: unknown key(s) {', '.join(unknown)}", hint="allowed keys: " + ", ".join(_ROW_KEYS))
    required = ("id", "joint", "model") + (("min", "max") if default_limit_rad is None else ())
    missing = [key for key in required if key not in raw]
    if missing:
        raise RobotFileError(f"{where}: lacks {', '.join(missing)}", hint="every [[servo]] gives " + ", ".join(required))
    sid, direction = _whole(raw["id"]), _whole(raw.get("direction", 1))
    limit = DEFAULT_LIMIT_RAD if default_limit_rad is None else default_limit_rad  # (None: min and max are required above)
    try:  # numbers as their field's type; anything else for ServoRow to refuse by name
        return ServoRow(
            id=raw["id"] if sid is None else sid,
            joint=raw["joint"],
            model=raw["model"],
            direction=raw.get("direction", 1) if direction is None else direction,
            zero_offset=_float(raw.get("zero_offset", 0.0)),
            min=_float(raw.get("min", -limit)),
            max=_float(raw.get("max", limit)),
        )
    except RobotFileError as e:
        raise RobotFileError(f"{source}: {e}", hint=e.hint) from None


def parse_servo_map_data(data: Mapping[str, Any], *, source: str = "servo map", default_limit_rad: float | None = None) -> ServoMapFile:
    """Validate the parsed TOML ``data`` of a servo map into a :class:`ServoMapFile`.

    Args:
        data: the file's tables (``tomllib``).
        source: how messages name the file (its path).
        default_limit_rad: None: every row must give ``min`` and ``max`` (a robot directory, an
            import); a number L: a row without them gets [-L, L] (``drivers`` on a bus rig:
            :data:`DEFAULT_LIMIT_RAD`).

    Raises:
        RobotFileError: one line naming ``source`` and the problem.
    """
    fmt = data.get("format")
    if fmt != SERVO_MAP_FORMAT:
        raise RobotFileError(f"{source}: format is {fmt!r}, expected {SERVO_MAP_FORMAT!r}", hint=f'start the file with format = "{SERVO_MAP_FORMAT}"')
    robot = data.get("robot", "")
    if not isinstance(robot, str):
        raise RobotFileError(f"{source}: robot must be the robot's name (text), not {robot!r}")
    bus = _bus(data.get("bus", {}), source)
    rows = data.get("servo")
    if not isinstance(rows, list) or not rows:
        raise RobotFileError(f"{source}: no [[servo]] rows", hint="give each servo a [[servo]] table: id, joint, model, min, max")
    servos = tuple(_row(k, row, source, default_limit_rad) for k, row in enumerate(rows))
    try:
        return ServoMapFile(robot=robot, bus=bus, servos=servos)
    except RobotFileError as e:
        raise RobotFileError(f"{source}: {e}", hint=e.hint) from None


def read_servo_map(path: str | os.PathLike[str], *, default_limit_rad: float | None = None) -> ServoMapFile:
    """Read and validate a ``servos.toml`` file (see :func:`parse_servo_map_data`).

    Raises:
        RobotFileError: missing file, not TOML, or invalid content (one line naming the file).
    """
    data = read_toml(path, "servo map", hint="a robot directory needs robot.toml, robot.xml and servos.toml")
    return parse_servo_map_data(data, source=str(path), default_limit_rad=default_limit_rad)


def servo_map_data(servo_map: ServoMapFile) -> dict[str, Any]:
    """The TOML tables of ``servo_map`` (what :func:`write_servo_map` writes)."""
    b = servo_map.bus
    bus: dict[str, Setting] = {
        "protocol": b.protocol,
        "baud_rate": b.baud_rate,
        "return_delay_time_us": b.return_delay_time_us,
        "supply_voltage_v": b.supply_voltage_v,
    }
    bus.update(b.extra)
    return {
        "format": SERVO_MAP_FORMAT,
        "robot": servo_map.robot,
        "bus": bus,
        "servo": [{key: getattr(s, key) for key in _ROW_KEYS} for s in servo_map.servos],
    }


def write_servo_map(path: str | os.PathLike[str], servo_map: ServoMapFile, *, comments: Sequence[str] = SERVO_MAP_COMMENTS) -> None:
    """Write ``servo_map`` to ``path`` (``tomli-w``); :func:`read_servo_map` reads it back equal."""
    write_toml(Path(path), servo_map_data(servo_map), comments=comments)
