"""The servo map (``servos.toml``, format ``robot-rise/servos@1``) and radians <-> ticks.

This is the only place where joint angles become servo angles and ticks:
``servo = direction * (angle + zero_offset)`` (the servo frame, radians) and
``ticks = center + servo / rad_per_tick`` with the model's resolution: ``2048 + servo * 4096 /
(2 pi)`` on the X and MX series, ``512 + servo * 1023 / 300 deg`` on AX/RX.

``[bus] protocol`` is 2.0 (default) or 1.0; it selects the control tables (``MX-28`` on a 1.0
bus is the MX-28 with its 1.0 firmware) and, in :mod:`drivers.session`, the bus driver. A 1.0
bus may mix models (MX and AX, as the Poppy Humanoid's MX-28/MX-64 body and AX-18A head).
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from drivers.control_table import BAUD_INDEX_BY_RATE, ControlTable, control_table
from drivers.control_table1 import BAUD_INDEX_BY_RATE_1
from drivers.errors import ControlTableError, ServoMapError

__all__ = [
    "SERVO_MAP_FORMAT",
    "BusSpec",
    "ServoSpec",
    "ServoMap",
    "load_servo_map",
    "parse_servo_map",
    "with_protocol",
]

SERVO_MAP_FORMAT = "robot-rise/servos@1"
_DEFAULT_LIMIT_RAD = 3.14  # [rad] default joint limit: just inside one turn of position mode
_SUPPORTED_BAUDS = tuple(BAUD_INDEX_BY_RATE)
_SUPPORTED_BAUDS_1 = tuple(sorted(BAUD_INDEX_BY_RATE_1))
PROTOCOLS = (1.0, 2.0)  # the Dynamixel protocols [bus] protocol may name


@dataclass(frozen=True)
class BusSpec:
    """Bus settings.

    Attributes:
        baud_rate: [bit/s].
        return_delay_time_us: servo reply delay [us] (control table unit is 2 us).
        supply_voltage_v: the servos' supply [V] (e.g. 14.8 for a 4S LiPo): what the robot's
            simulation models them at (robot_rise.model reads the same key).
        protocol: Dynamixel protocol of the bus, 2.0 or 1.0.
    """

    baud_rate: int = 1_000_000
    return_delay_time_us: float = 0.0
    supply_voltage_v: float = 12.0
    protocol: float = 2.0

    def __post_init__(self) -> None:
        if self.protocol not in PROTOCOLS:
            raise ServoMapError(f"protocol {self.protocol} is not a Dynamixel protocol",
                                hint="use protocol = 2.0 or protocol = 1.0")
        bauds = _SUPPORTED_BAUDS_1 if self.protocol == 1.0 else _SUPPORTED_BAUDS
        if self.baud_rate not in bauds:
            raise ServoMapError(
                f"baud_rate {self.baud_rate} is not a Dynamixel Protocol {self.protocol:.1f} baud rate",
                hint="use one of " + ", ".join(map(str, bauds)),
            )
        if not 0 <= self.return_delay_time_us <= 508:
            raise ServoMapError(f"return_delay_time_us {self.return_delay_time_us} outside 0..508")
        if not 5.0 <= self.supply_voltage_v <= 30.0:  # as robot_rise.model.SUPPLY_RANGE_V (drivers import no core)
            raise ServoMapError(f"supply_voltage_v {self.supply_voltage_v} outside 5..30 V")

    @property
    def baud_index(self) -> int:
        """Value of the Baud Rate register for ``baud_rate``."""
        return (BAUD_INDEX_BY_RATE_1 if self.protocol == 1.0 else BAUD_INDEX_BY_RATE)[self.baud_rate]

    @property
    def return_delay_units(self) -> int:
        """Value of the Return Delay Time register (2 us units)."""
        return int(round(self.return_delay_time_us / 2.0))


@dataclass(frozen=True)
class ServoSpec:
    """One servo of the map.

    Attributes:
        id: bus ID 0..252.
        joint: joint name in the robot model.
        model: servo model name (see ``drivers.control_table.SUPPORTED_MODELS``).
        direction: +1 or -1.
        zero_offset: [rad] added to the joint angle before conversion.
        min: lower joint limit [rad].
        max: upper joint limit [rad].
        protocol: the bus's protocol (the servo map's ``[bus] protocol``): which control table
            ``model`` names.
    """

    id: int
    joint: str
    model: str
    direction: int = 1
    zero_offset: float = 0.0
    min: float = -_DEFAULT_LIMIT_RAD
    max: float = _DEFAULT_LIMIT_RAD
    protocol: float = 2.0

    def __post_init__(self) -> None:
        if not 0 <= self.id <= 252:
            raise ServoMapError(f"servo id {self.id} outside 0..252 (joint {self.joint!r})")
        if self.direction not in (1, -1):
            raise ServoMapError(f"direction of servo {self.id} must be 1 or -1, not {self.direction}")
        if not self.min < self.max:
            raise ServoMapError(f"servo {self.id} ({self.joint}): min {self.min} must be < max {self.max}")
        try:
            table = control_table(self.model, self.protocol)
        except ControlTableError as e:
            raise ServoMapError(f"servo {self.id} ({self.joint}): {e}", hint=e.hint) from None
        lo, hi = sorted((self.to_ticks(self.min), self.to_ticks(self.max)))
        if lo < 0 or hi > table.max_ticks:
            raise ServoMapError(
                f"servo {self.id} ({self.joint}): limits map to ticks {lo}..{hi}, outside 0..{table.max_ticks}",
                hint="check zero_offset and limits (position mode covers one turn"
                     + ("; AX/RX cover 300 deg)" if table.max_ticks < 4095 else ")"),
            )

    @property
    def table(self) -> ControlTable:
        return control_table(self.model, self.protocol)

    @property
    def label(self) -> str:
        """How messages name this servo: ``joint (id N)``."""
        return f"{self.joint} (id {self.id})"

    def to_servo_frame(self, angle_rad: float) -> float:
        """Servo-frame angle [rad] (the shaft's own, 0 at 2048 ticks) for joint angle ``angle_rad``."""
        return self.direction * (angle_rad + self.zero_offset)

    def from_servo_frame(self, servo_rad: float) -> float:
        """Joint angle [rad] for servo-frame angle ``servo_rad``."""
        return self.direction * servo_rad - self.zero_offset

    def to_ticks(self, angle_rad: float) -> int:
        """Goal position ticks for joint angle ``angle_rad`` [rad]."""
        t = self.table
        return int(round(t.center_ticks + self.to_servo_frame(angle_rad) / t.rad_per_tick))

    def to_radians(self, ticks: int) -> float:
        """Joint angle [rad] for ``ticks``."""
        t = self.table
        return self.from_servo_frame((ticks - t.center_ticks) * t.rad_per_tick)

    @property
    def limit_ticks(self) -> tuple[int, int]:
        """(min, max) position limits in ticks, for the EEPROM position-limit registers."""
        a, b = self.to_ticks(self.min), self.to_ticks(self.max)
        return (min(a, b), max(a, b))


@dataclass(frozen=True)
class ServoMap:
    """All servos of one bus, in file order.

    Attributes:
        robot: robot name.
        bus: :class:`BusSpec`.
        servos: tuple of :class:`ServoSpec`, in file order (this order defines the joint vector
            order of every array in ``drivers``).
    """

    robot: str
    bus: BusSpec
    servos: tuple[ServoSpec, ...]

    def __post_init__(self) -> None:
        if not self.servos:
            raise ServoMapError("servo map has no [[servo]] rows")
        ids = [s.id for s in self.servos]
        joints = [s.joint for s in self.servos]
        for what, values in (("id", ids), ("joint", joints)):
            dup = sorted({v for v in values if values.count(v) > 1}, key=str)
            if dup:
                raise ServoMapError(f"duplicate servo {what}(s) in servo map: {dup}")
        other = [s.label for s in self.servos if s.protocol != self.bus.protocol]
        if other:
            raise ServoMapError(f"servo(s) {other} are specified for another protocol than the bus "
                                f"(Protocol {self.bus.protocol:.1f})")

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(s.id for s in self.servos)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(s.joint for s in self.servos)

    def __len__(self) -> int:
        return len(self.servos)

    def by_id(self, servo_id: int) -> ServoSpec:
        for s in self.servos:
            if s.id == servo_id:
                return s
        raise ServoMapError(f"no servo with id {servo_id}", hint=f"ids in the map: {list(self.ids)}")

    def by_joint(self, joint: str) -> ServoSpec:
        for s in self.servos:
            if s.joint == joint:
                return s
        raise ServoMapError(f"no servo drives joint {joint!r}", hint="joints: " + ", ".join(self.joint_names))

    def index_of(self, joint_names: Sequence[str]) -> NDArray[np.intp]:
        """Column indices mapping a trajectory's ``joint_names`` onto map order.

        Returns:
            Array shape (len(self),): ``q_map = q_traj[..., idx]``.

        Raises:
            ServoMapError: a mapped joint is missing from ``joint_names``.
        """
        pos = {name: k for k, name in enumerate(joint_names)}
        missing = [j for j in self.joint_names if j not in pos]
        if missing:
            raise ServoMapError(
                f"trajectory lacks joint(s) {missing} driven by servos",
                hint="the trajectory must name every joint of the servo map",
            )
        return np.array([pos[j] for j in self.joint_names], dtype=np.intp)

    # ---- vectorised conversions (map order) ----------------------------------------
    @property
    def lower_rad(self) -> NDArray[np.float64]:
        """Lower joint limits [rad], shape (n,)."""
        return np.array([s.min for s in self.servos])

    @property
    def upper_rad(self) -> NDArray[np.float64]:
        """Upper joint limits [rad], shape (n,)."""
        return np.array([s.max for s in self.servos])

    @property
    def protocol(self) -> float:
        """The bus's Dynamixel protocol (2.0 or 1.0)."""
        return self.bus.protocol

    @cached_property
    def _direction_offset(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        d = np.array([s.direction for s in self.servos], dtype=float)
        off = np.array([s.zero_offset for s in self.servos])
        d.setflags(write=False)
        off.setflags(write=False)
        return d, off

    @cached_property
    def _resolution(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(centre ticks, rad per tick), shape (n,) each: the models' position resolution."""
        tables = [s.table for s in self.servos]
        center = np.array([t.center_ticks for t in tables], dtype=float)
        step = np.array([t.rad_per_tick for t in tables])
        center.setflags(write=False)
        step.setflags(write=False)
        return center, step

    def _dir_off(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self._direction_offset

    def to_ticks(self, q_rad: NDArray[np.float64]) -> NDArray[np.int64]:
        """Joint angles [rad], shape (..., n) -> goal ticks, same shape (int64)."""
        d, off = self._dir_off()
        center, step = self._resolution
        return np.rint(center + d * (np.asarray(q_rad) + off) / step).astype(np.int64)

    def to_radians(self, ticks: NDArray[np.int64]) -> NDArray[np.float64]:
        """Ticks, shape (..., n) -> joint angles [rad], same shape."""
        d, off = self._dir_off()
        center, step = self._resolution
        return d * (np.asarray(ticks, dtype=float) - center) * step - off

    def velocity_to_rad_s(self, raw: NDArray[np.int64]) -> NDArray[np.float64]:
        """Present Velocity raw units, shape (..., n) -> joint velocity [rad/s]."""
        from drivers.control_table import VELOCITY_UNIT_RAD_S

        d, _ = self._dir_off()
        return d * np.asarray(raw, dtype=float) * VELOCITY_UNIT_RAD_S


def parse_servo_map(data: Mapping[str, object], *, source: str = "servo map") -> ServoMap:
    """Build a :class:`ServoMap` from parsed TOML ``data``."""
    fmt = data.get("format")
    if fmt != SERVO_MAP_FORMAT:
        raise ServoMapError(
            f"{source}: format is {fmt!r}, expected {SERVO_MAP_FORMAT!r}",
            hint="start the file with format = \"robot-rise/servos@1\"",
        )
    bus_raw = data.get("bus", {})
    if not isinstance(bus_raw, Mapping):
        raise ServoMapError(f"{source}: [bus] must be a table")
    try:
        protocol = float(bus_raw.get("protocol", 2.0))
        bus = BusSpec(
            baud_rate=int(bus_raw.get("baud_rate", 1_000_000)),
            return_delay_time_us=float(bus_raw.get("return_delay_time_us", 0.0)),
            supply_voltage_v=float(bus_raw.get("supply_voltage_v", 12.0)),
            protocol=protocol,
        )
    except (TypeError, ValueError) as e:
        raise ServoMapError(f"{source}: [bus] has a value that is not a number ({e})") from None
    except ServoMapError as e:
        raise ServoMapError(f"{source}: [bus] {e}", hint=e.hint) from None
    rows = data.get("servo")
    if not isinstance(rows, list):
        raise ServoMapError(f"{source}: no [[servo]] rows")
    allowed = {"id", "joint", "model", "direction", "zero_offset", "min", "max"}
    servos = []
    for k, row in enumerate(rows):
        if not isinstance(row, Mapping):
            raise ServoMapError(f"{source}: servo row {k} is not a table")
        unknown = set(row) - allowed
        if unknown:
            raise ServoMapError(f"{source}: servo row {k} has unknown key(s) {sorted(unknown)}",
                                hint="allowed keys: " + ", ".join(sorted(allowed)))
        for key in ("id", "joint", "model"):
            if key not in row:
                raise ServoMapError(f"{source}: servo row {k} lacks {key!r}")
        servos.append(ServoSpec(
            id=int(row["id"]), joint=str(row["joint"]), model=str(row["model"]),
            direction=int(row.get("direction", 1)), zero_offset=float(row.get("zero_offset", 0.0)),
            min=float(row.get("min", -_DEFAULT_LIMIT_RAD)), max=float(row.get("max", _DEFAULT_LIMIT_RAD)),
            protocol=bus.protocol,
        ))
    return ServoMap(robot=str(data.get("robot", "")), bus=bus, servos=tuple(servos))


def load_servo_map(path: str | Path) -> ServoMap:
    """Read a ``servos.toml`` file.

    Raises:
        ServoMapError: missing file, TOML syntax error or invalid content.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ServoMapError(f"servo map {path} not found", hint="pass the robot's servos.toml") from None
    except tomllib.TOMLDecodeError as e:
        raise ServoMapError(f"{path}: {e}") from e
    return parse_servo_map(data, source=str(path))


def with_protocol(servo_map: ServoMap, protocol: float,
                  model: str | None = None) -> tuple[ServoMap, list[tuple[str, str]]]:
    """The map on a ``protocol`` bus (for an emulator or a test rig): every servo keeps its model
    where that model speaks ``protocol``, others become ``model`` (default MX-28 on 1.0,
    XM430-W350 on 2.0). Returns the map and the ``(old, new)`` model of each servo replaced.

    Raises:
        ServoMapError: ``model`` does not speak ``protocol``, or a limit leaves its range.
    """
    import dataclasses

    substitute = model or ("MX-28" if protocol == 1.0 else "XM430-W350")
    try:
        control_table(substitute, protocol)
    except ControlTableError as e:
        raise ServoMapError(str(e), hint=e.hint) from None
    servos, replaced = [], []
    for s in servo_map.servos:
        try:
            control_table(s.model, protocol)
            name = s.model
        except ControlTableError:
            name = substitute
            replaced.append((s.model, substitute))
        servos.append(dataclasses.replace(s, model=name, protocol=protocol))
    bus = dataclasses.replace(servo_map.bus, protocol=protocol)
    return ServoMap(servo_map.robot, bus, tuple(servos)), replaced
