"""The servo map (``servos.toml``, format ``robot-rise/servos@1``) and radians <-> ticks.

This is the only place where joint angles become servo angles and ticks:
``servo = direction * (angle + zero_offset)`` (the servo frame, radians) and
``ticks = center + servo / rad_per_tick`` with the model's resolution: ``2048 + servo * 4096 /
(2 pi)`` on the X and MX series, ``512 + servo * 1023 / 300 deg`` on AX/RX.

``[bus] protocol`` is 2.0 (default) or 1.0; it selects the control tables (``MX-28`` on a 1.0
bus is the MX-28 with its 1.0 firmware) and, in :mod:`drivers.session`, the bus driver. A 1.0
bus may mix models (MX and AX, as the Poppy Humanoid's MX-28/MX-64 body and AX-18A head).

The file has one reader, :func:`robot_files.servo_map.read_servo_map` (the robot's simulation
reads it there too): :class:`BusSpec`, :class:`ServoSpec` and :class:`ServoMap` are its values
with what only the bus knows on top: the control table of each model on this protocol, the
protocol's baud rates, limits that fit in ticks. A row without ``min``/``max`` gets
``DEFAULT_LIMIT_RAD`` here (a bus rig's map); a robot directory's map must give them.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from drivers.control_table import BAUD_INDEX_BY_RATE, ControlTable, control_table
from drivers.control_table1 import BAUD_INDEX_BY_RATE_1
from drivers.errors import ControlTableError, ServoMapError
from robot_files.errors import RobotFileError
from robot_files.servo_map import (
    DEFAULT_LIMIT_RAD,
    SERVO_MAP_FORMAT,
    BusSettings,
    ServoMapFile,
    ServoRow,
    parse_servo_map_data,
    read_servo_map,
)

__all__ = [
    "SERVO_MAP_FORMAT",
    "BusSpec",
    "ServoSpec",
    "ServoMap",
    "load_servo_map",
    "parse_servo_map",
    "with_protocol",
]

_SUPPORTED_BAUDS = tuple(BAUD_INDEX_BY_RATE)
_SUPPORTED_BAUDS_1 = tuple(sorted(BAUD_INDEX_BY_RATE_1))


@contextmanager
def _as_servo_map_error() -> Iterator[None]:
    """The file reader's errors as ``ServoMapError`` (drivers' callers catch their own errors)."""
    try:
        yield
    except RobotFileError as e:
        raise ServoMapError(str(e), hint=e.hint) from None


@dataclass(frozen=True)
class BusSpec(BusSettings):
    """Bus settings (:class:`robot_files.servo_map.BusSettings`) on a Dynamixel bus.

    Attributes:
        baud_rate: [bit/s], one the protocol has.
        return_delay_time_us: servo reply delay [us] (control table unit is 2 us).
        supply_voltage_v: the servos' supply [V] (e.g. 14.8 for a 4S LiPo): what the robot's
            simulation models them at.
        protocol: Dynamixel protocol of the bus, 2.0 or 1.0.
        extra: the file's other [bus] settings, kept as given.
    """

    def __post_init__(self) -> None:
        with _as_servo_map_error():
            super().__post_init__()
        bauds = _SUPPORTED_BAUDS_1 if self.protocol == 1.0 else _SUPPORTED_BAUDS
        if self.baud_rate not in bauds:
            raise ServoMapError(
                f"baud_rate {self.baud_rate} is not a Dynamixel Protocol {self.protocol:.1f} baud rate",
                hint="use one of " + ", ".join(map(str, bauds)),
            )

    @property
    def baud_index(self) -> int:
        """Value of the Baud Rate register for ``baud_rate``."""
        return (BAUD_INDEX_BY_RATE_1 if self.protocol == 1.0 else BAUD_INDEX_BY_RATE)[self.baud_rate]

    @property
    def return_delay_units(self) -> int:
        """Value of the Return Delay Time register (2 us units)."""
        return int(round(self.return_delay_time_us / 2.0))


@dataclass(frozen=True)
class ServoSpec(ServoRow):
    """One servo of the map (a :class:`robot_files.servo_map.ServoRow` on a bus).

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

    protocol: float = 2.0

    def __post_init__(self) -> None:
        with _as_servo_map_error():
            super().__post_init__()
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
class ServoMap(ServoMapFile):
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
        with _as_servo_map_error():
            super().__post_init__()
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


def _on_the_bus(file: ServoMapFile, source: str) -> ServoMap:
    """``file``'s values as the bus's (control tables, baud rates, ticks checked)."""
    b = file.bus
    try:
        bus = BusSpec(b.baud_rate, b.return_delay_time_us, b.supply_voltage_v, b.protocol, b.extra)
    except ServoMapError as e:
        raise ServoMapError(f"{source}: [bus] {e}", hint=e.hint) from None
    try:
        servos = tuple(ServoSpec(s.id, s.joint, s.model, s.direction, s.zero_offset, s.min, s.max, protocol=bus.protocol)
                       for s in file.servos)
        return ServoMap(robot=file.robot, bus=bus, servos=servos)
    except ServoMapError as e:
        raise ServoMapError(f"{source}: {e}", hint=e.hint) from None


def parse_servo_map(data: Mapping[str, object], *, source: str = "servo map") -> ServoMap:
    """Build a :class:`ServoMap` from parsed TOML ``data`` (rows without limits get +-``DEFAULT_LIMIT_RAD``).

    Raises:
        ServoMapError: one line naming ``source`` and the problem.
    """
    with _as_servo_map_error():
        file = parse_servo_map_data(data, source=source, default_limit_rad=DEFAULT_LIMIT_RAD)
    return _on_the_bus(file, source)


def load_servo_map(path: str | Path) -> ServoMap:
    """Read a ``servos.toml`` file (:func:`robot_files.servo_map.read_servo_map`).

    Raises:
        ServoMapError: missing file, TOML syntax error or invalid content (one line naming the file).
    """
    with _as_servo_map_error():
        file = read_servo_map(path, default_limit_rad=DEFAULT_LIMIT_RAD)
    return _on_the_bus(file, str(path))


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
