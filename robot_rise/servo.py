"""Dynamixel servo parameters per model (data) and the torque-speed envelope (pure functions).

A Dynamixel in position mode runs a P(ID) loop on the position error and drives its DC motor with
the resulting PWM duty u in [-1, 1] (885 = 100 %). A DC motor at duty u and speed w gives

    tau = tau_stall(V) * (u - w / w_noload(V))                                   (DC motor)

so the reachable torque at speed w lies in the envelope
    -tau_stall * (1 + w / w_noload) <= tau <= tau_stall * (1 - w / w_noload).

The position loop: u = clip(Kp_pwm * e_ticks / 885, -1, 1) with Kp_pwm = P / 128 (PWM units per
tick, e-manual). In SI, the torque per radian of error before saturation is

    kp_eff = (P / 128) * (4096 / 2 pi) * tau_stall / 885        [N m / rad]

For the XM430-W350 at 12 V with the default P = 800: 6.25 * 651.9 * 4.1 / 885 = 18.9 N m/rad,
and the duty saturates at 885 / 6.25 = 141.6 ticks = 0.217 rad of error. The back-EMF term is a
viscous torque with coefficient tau_stall / w_noload (independent of voltage, since both scale
with V). In MuJoCo this is exact with one position actuator (kp_eff, force range +-tau_stall)
plus joint damping tau_stall / w_noload: see robot_rise/model.py.

The figures per model are data, not code: the product's catalog ``configs/servos/catalog.toml``
(format ``robot-rise/servo-catalog@1``, every figure with its source: a ROBOTIS e-manual page or
"estimate: how"), plus optionally a robot directory's own ``servo_models.toml`` in the same
format, whose models are added to the product's (or override them, with a logged warning).
The file's one reader and :class:`ServoDatasheet` are :mod:`robot_files.servo_catalog` (``drivers``
reads the same figures for its emulated servos); :func:`servo_catalog` merges the two files
(cached per file and modification time), :func:`servo_datasheet` looks one model up by its name
or an alias (``MX-28(2.0)`` is ``MX-28``).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_files.servo_catalog import (
    PWM_LIMIT,
    ROBOT_SERVO_MODELS_FILE,
    SERVO_CATALOG_FORMAT,
    TICKS_PER_REV,
    ServoDatasheet,
    cached_servo_catalog,
    catalog_stamp,
    product_catalog,
    product_catalog_path,
)
from robot_files.servo_catalog import read_servo_catalog as _read_catalog_file
from robot_rise.errors import ConfigError, as_config_error

__all__ = [
    "ServoDatasheet",
    "ServoCatalog",
    "SERVO_DATASHEETS",
    "SERVO_CATALOG_FORMAT",
    "ROBOT_SERVO_MODELS_FILE",
    "product_catalog_path",
    "read_servo_catalog",
    "servo_catalog",
    "servo_datasheet",
    "TICKS_PER_REV",
    "PWM_LIMIT",
    "torque_limits",
    "envelope_ratio",
    "position_mode_torque",
    "ServoArrays",
    "servo_arrays",
]

log = logging.getLogger(__name__)


def read_servo_catalog(path: str | os.PathLike[str]) -> tuple[ServoDatasheet, ...]:
    """Read and validate one servo catalog file (format ``robot-rise/servo-catalog@1``), uncached
    (:func:`robot_files.servo_catalog.read_servo_catalog`).

    Raises:
        ConfigError: the file is missing or not valid TOML, has another format string, or a model
            has a missing, unknown or out-of-range field or a figure without a source (one line
            naming the file and the model).
    """
    with as_config_error():
        return _read_catalog_file(path)


def _cached_read(path: Path, stamp: tuple[int, int]) -> tuple[ServoDatasheet, ...]:
    with as_config_error():
        return cached_servo_catalog(path, stamp)


class ServoCatalog(Mapping[str, ServoDatasheet]):
    """Servo models by name: iterates over model names; looks up a model name or an alias.

    Attributes:
        files: the catalog files read, product's first.
    """

    def __init__(self, sheets: dict[str, ServoDatasheet], by_name: dict[str, ServoDatasheet], files: tuple[Path, ...]) -> None:
        self._sheets = sheets
        self._by_name = by_name
        self.files = files

    def __getitem__(self, name: str) -> ServoDatasheet:
        return self._by_name[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._sheets)

    def __len__(self) -> int:
        return len(self._sheets)

    def __repr__(self) -> str:
        return f"ServoCatalog({', '.join(self._sheets)})"

    def names(self) -> tuple[str, ...]:
        """Every accepted name (model names and aliases), sorted."""
        return tuple(sorted(self._by_name))

    def describe(self) -> str:
        """The known models, sorted, each with its aliases: ``MX-28 (MX-28(2.0)), XM430-W350``."""
        return ", ".join(
            f"{name} ({', '.join(sheet.aliases)})" if sheet.aliases else name for name, sheet in sorted(self._sheets.items())
        )


_CATALOG_CACHE: dict[tuple, ServoCatalog] = {}


def servo_catalog(extra_catalog: str | os.PathLike[str] | None = None) -> ServoCatalog:
    """The product's servo catalog, plus a robot's own models from ``extra_catalog`` if that file exists.

    A model of ``extra_catalog`` whose name or alias is one of a product model's names replaces
    that product model under all its names (logged as a warning). Files are read once per
    path and modification time.

    Args:
        extra_catalog: a robot directory's ``servo_models.toml`` (same format); a missing file is
            ignored.

    Raises:
        ConfigError: a catalog file is malformed (see :func:`read_servo_catalog`).
    """
    with as_config_error():
        product, product_stamp = product_catalog()
    extra = Path(extra_catalog).resolve() if extra_catalog is not None else None
    extra_stamp = catalog_stamp(extra) if extra is not None else None
    if extra is not None and extra_stamp is not None and not extra.is_file():
        raise ConfigError(f"{extra}: the robot's servo models must be a file ({ROBOT_SERVO_MODELS_FILE})")
    key = (product, product_stamp, extra if extra_stamp is not None else None, extra_stamp)
    hit = _CATALOG_CACHE.get(key)
    if hit is not None:
        return hit

    sheets: dict[str, ServoDatasheet] = {}
    by_name: dict[str, ServoDatasheet] = {}
    for sheet in _cached_read(product, product_stamp):
        sheets[sheet.model] = sheet
        by_name.update(dict.fromkeys(sheet.names, sheet))
    files = (product,)
    if extra is not None and extra_stamp is not None:
        files += (extra,)
        for sheet in _cached_read(extra, extra_stamp):
            replaced = {id(by_name[n]): by_name[n] for n in sheet.names if n in by_name}
            for old in replaced.values():
                log.warning("%s: model %r overrides the product catalog's %s", extra, sheet.model, "/".join(old.names))
                del sheets[old.model]
                by_name.update(dict.fromkeys(old.names, sheet))
            sheets[sheet.model] = sheet
            by_name.update(dict.fromkeys(sheet.names, sheet))
    catalog = ServoCatalog(sheets, by_name, files)
    if len(_CATALOG_CACHE) > 64:
        _CATALOG_CACHE.clear()
    _CATALOG_CACHE[key] = catalog
    return catalog


def servo_datasheet(model: str, *, extra_catalog: str | os.PathLike[str] | None = None) -> ServoDatasheet:
    """Return the datasheet of a servo model (name or alias), or raise ConfigError listing the known models.

    Args:
        model: model name as in a servo map (``XM430-W350``, ``MX-28(2.0)`` ...).
        extra_catalog: a robot directory's ``servo_models.toml`` (see :func:`servo_catalog`).
    """
    catalog = servo_catalog(extra_catalog)
    try:
        return catalog[model]
    except KeyError:
        where = str(extra_catalog) if extra_catalog is not None else f"<robot dir>/{ROBOT_SERVO_MODELS_FILE}"
        raise ConfigError(
            f"unknown servo model {model!r}; known: {catalog.describe()}",
            hint=f"add it to {where} (format {SERVO_CATALOG_FORMAT})",
        ) from None


SERVO_DATASHEETS: ServoCatalog  # the product catalog: provided by __getattr__ below, not bound here


def __getattr__(name: str) -> object:
    # SERVO_DATASHEETS: the product catalog, read on first use (a broken file fails the lookup,
    # not ``import robot_rise``) and re-read when the file changes.
    if name == "SERVO_DATASHEETS":
        return servo_catalog()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def torque_limits(
    stall_torque_nm: np.ndarray, no_load_speed_rad_s: np.ndarray, velocity_rad_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Torque-speed envelope of a DC-motor servo at the given joint velocities.

    Args:
        stall_torque_nm: shape (n,) or broadcastable, [N m].
        no_load_speed_rad_s: shape (n,), [rad/s].
        velocity_rad_s: shape (..., n), [rad/s].

    Returns:
        (lower, upper) torque bounds [N m], each shaped like ``velocity_rad_s``.
    """
    r = np.asarray(velocity_rad_s) / no_load_speed_rad_s
    return -stall_torque_nm * (1.0 + r), stall_torque_nm * (1.0 - r)


def envelope_ratio(
    torque_nm: np.ndarray,
    velocity_rad_s: np.ndarray,
    stall_torque_nm: np.ndarray,
    no_load_speed_rad_s: np.ndarray,
) -> np.ndarray:
    """How much of the available torque is used: |tau| / (limit in tau's direction).

    1.0 means the servo is at its envelope; above 1 is impossible for a real servo. A torque
    against the motion (braking) has more room than stall, which the envelope reflects.

    Returns:
        ratio, shaped like ``torque_nm`` (dimensionless).
    """
    lower, upper = torque_limits(stall_torque_nm, no_load_speed_rad_s, velocity_rad_s)
    tau = np.asarray(torque_nm)
    room = np.where(tau >= 0, upper, -lower)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(room > 1e-9, np.abs(tau) / np.maximum(room, 1e-9), np.where(np.abs(tau) > 1e-9, np.inf, 0.0))
    return ratio


def position_mode_torque(
    goal_rad: np.ndarray,
    position_rad: np.ndarray,
    velocity_rad_s: np.ndarray,
    *,
    kp_nm_per_rad: np.ndarray,
    stall_torque_nm: np.ndarray,
    no_load_speed_rad_s: np.ndarray,
) -> np.ndarray:
    """Torque of a Dynamixel in position mode (P loop -> PWM saturation -> DC motor), [N m].

    All arrays shape (n,) or broadcastable; the result has the broadcast shape.
    """
    duty = np.clip(kp_nm_per_rad * (goal_rad - position_rad) / stall_torque_nm, -1.0, 1.0)
    return stall_torque_nm * (duty - velocity_rad_s / no_load_speed_rad_s)


@dataclass(frozen=True)
class ServoArrays:
    """Per-joint servo numbers at one supply voltage, as arrays (vectorised envelope checks).

    Attributes:
        stall_torque_nm: stall torque per joint at the voltage [N m], shape (n,).
        no_load_speed_rad_s: no-load speed per joint at the voltage [rad/s], shape (n,).
        kp_nm_per_rad: position-loop stiffness per joint [N m / rad], shape (n,).
        back_emf_damping_nm_s: tau_stall / w_noload per joint [N m s / rad], shape (n,).
    """

    stall_torque_nm: np.ndarray
    no_load_speed_rad_s: np.ndarray
    kp_nm_per_rad: np.ndarray
    back_emf_damping_nm_s: np.ndarray

    def motor_torque(self, actuator_force_nm: np.ndarray, velocity_rad_s: np.ndarray) -> np.ndarray:
        """Motor torque [N m] from the position-loop output and the joint speed.

        The MuJoCo position actuator gives ``tau_stall * clip(u)``; the back-EMF (modelled as joint
        damping) subtracts ``tau_stall * w / w_noload``. Shapes (..., n).
        """
        return np.asarray(actuator_force_nm) - self.back_emf_damping_nm_s * np.asarray(velocity_rad_s)

    def ratio(self, motor_torque_nm: np.ndarray, velocity_rad_s: np.ndarray) -> np.ndarray:
        """Torque / envelope ratio per joint (see :func:`envelope_ratio`), shape (..., n)."""
        return envelope_ratio(motor_torque_nm, velocity_rad_s, self.stall_torque_nm, self.no_load_speed_rad_s)


def servo_arrays(specs: tuple[ServoDatasheet, ...] | list[ServoDatasheet], voltage_v: float) -> ServoArrays:
    """Stack the per-joint servo numbers at ``voltage_v`` [V] into :class:`ServoArrays`."""

    def ro(values: list[float]) -> np.ndarray:
        a = np.array(values, dtype=float)
        a.setflags(write=False)
        return a

    return ServoArrays(
        stall_torque_nm=ro([s.stall_torque_at(voltage_v) for s in specs]),
        no_load_speed_rad_s=ro([s.no_load_speed_at(voltage_v) for s in specs]),
        kp_nm_per_rad=ro([s.position_gain_nm_per_rad(voltage_v) for s in specs]),
        back_emf_damping_nm_s=ro([s.back_emf_damping_nm_s for s in specs]),
    )
