"""robot_files: the files ``robot_rise`` and ``drivers`` both read, each with one reader and one writer.

- :mod:`~robot_files.servo_map` -- ``servos.toml`` (``robot-rise/servos@1``): the servo map.
- :mod:`~robot_files.servo_catalog` -- ``configs/servos/catalog.toml`` and a robot's
  ``servo_models.toml`` (``robot-rise/servo-catalog@1``): the servos' datasheet figures.
- :mod:`~robot_files.toml_file` -- reading TOML in one line whatever the file holds; the one
  TOML writer (``tomli-w``).
- :mod:`~robot_files.paths` -- where the shipped configs live.

The core (SI units, radians) and the drivers (ticks, bytes) never import each other; both import
this package, which imports neither. Errors are :class:`~robot_files.errors.RobotFileError`,
re-raised by each side as its own.
"""

from robot_files.errors import RobotFileError
from robot_files.paths import configs_dir
from robot_files.servo_catalog import SERVO_CATALOG_FORMAT, ServoDatasheet, product_datasheet, read_servo_catalog
from robot_files.servo_map import (
    SERVO_MAP_FORMAT,
    BusSettings,
    ServoMapFile,
    ServoRow,
    read_servo_map,
    write_servo_map,
)
from robot_files.toml_file import read_toml, write_toml

__all__ = [
    "RobotFileError",
    "configs_dir",
    "SERVO_CATALOG_FORMAT",
    "ServoDatasheet",
    "product_datasheet",
    "read_servo_catalog",
    "SERVO_MAP_FORMAT",
    "BusSettings",
    "ServoMapFile",
    "ServoRow",
    "read_servo_map",
    "write_servo_map",
    "read_toml",
    "write_toml",
]
