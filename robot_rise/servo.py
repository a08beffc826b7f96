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
:func:`servo_catalog` reads both (cached per file and modification time), :func:`servo_datasheet`
looks one model up by its name or an alias (``MX-28(2.0)`` is ``MX-28``).

Stall torque and no-load speed are given at a few voltages (the e-manual's 11.1 / 12 / 14.8 V
rows); between rows they are interpolated linearly, outside them the nominal row scales in
proportion to voltage (the DC-motor model, and the only one where a single row is known).
"""

from __future__ import annotations

import itertools
import logging
import math
import os
import re
import tomllib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_rise.errors import ConfigError
from robot_rise.paths import configs_dir

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

TICKS_PER_REV = 4096  # position resolution of X-series / MX(2.0) servos
PWM_LIMIT = 885  # PWM register value for 100 % duty
SERVO_CATALOG_FORMAT = "robot-rise/servo-catalog@1"
ROBOT_SERVO_MODELS_FILE = "servo_models.toml"  # a robot directory's own servo models (same format)


@dataclass(frozen=True)
class ServoDatasheet:
    """Performance of one servo model.

    Attributes:
        model: model name as ROBOTIS writes it.
        nominal_voltage_v: voltage of the single-voltage figures below [V].
        stall_torque_nm: stall torque at nominal voltage [N m].
        no_load_speed_rad_s: no-load speed at nominal voltage [rad/s].
        gear_ratio: gearbox reduction.
        position_p_gain: default Position P Gain register value (Kp = P / 128 PWM per tick).
        position_d_gain: default Position D Gain register value (Kd = D / 16).
        armature_kg_m2: reflected rotor + gear inertia [kg m^2] (estimate, see notes).
        friction_loss_nm: Coulomb friction of the gear train [N m].
        viscous_damping_nm_s: gear-train viscous damping beyond back-EMF [N m s / rad].
        notes: where the numbers come from.
        resolution_ticks_per_rev: encoder ticks per output revolution.
        control_table_family: register layout ("x": X series and MX with Protocol 2.0 firmware).
        aliases: other names of the model (``MX-28(2.0)`` for ``MX-28``).
        performance: (voltage [V], stall torque [N m], no-load speed [rad/s]) rows, voltage
            increasing, one of them at ``nominal_voltage_v``; empty: the nominal figures only.
        sources: (figure, source) pairs: an e-manual URL or "estimate: how" per figure.
    """

    model: str
    nominal_voltage_v: float
    stall_torque_nm: float
    no_load_speed_rad_s: float
    gear_ratio: float
    position_p_gain: int
    position_d_gain: int
    armature_kg_m2: float
    friction_loss_nm: float
    viscous_damping_nm_s: float
    notes: str = ""
    resolution_ticks_per_rev: int = TICKS_PER_REV
    control_table_family: str = "x"
    aliases: tuple[str, ...] = ()
    performance: tuple[tuple[float, float, float], ...] = ()
    sources: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        for name in ("nominal_voltage_v", "stall_torque_nm", "no_load_speed_rad_s", "gear_ratio", "resolution_ticks_per_rev"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"servo {self.model}: {name} must be > 0")
        if not self.position_p_gain > 0:
            raise ConfigError(f"servo {self.model}: position_p_gain must be > 0")
        rows = self.performance
        if rows:
            if any(not (v > 0 and t > 0 and w > 0) for v, t, w in rows):
                raise ConfigError(f"servo {self.model}: performance rows must be positive")
            if any(b[0] <= a[0] for a, b in itertools.pairwise(rows)):
                raise ConfigError(f"servo {self.model}: performance voltages must increase")
            nominal = [r for r in rows if r[0] == self.nominal_voltage_v]
            if nominal != [(self.nominal_voltage_v, self.stall_torque_nm, self.no_load_speed_rad_s)]:
                raise ConfigError(f"servo {self.model}: the performance row at the nominal {self.nominal_voltage_v:g} V must be the nominal figures")

    @property
    def names(self) -> tuple[str, ...]:
        """The model name and its aliases."""
        return (self.model, *self.aliases)

    def source(self, figure: str) -> str:
        """Where ``figure`` (a catalog field name, e.g. ``"gear_ratio"``) comes from ("" if unknown)."""
        return dict(self.sources).get(figure, "")

    def _at(self, voltage_v: float, column: int, nominal_value: float) -> float:
        rows = self.performance
        if len(rows) >= 2 and rows[0][0] <= voltage_v <= rows[-1][0]:
            for lo, hi in itertools.pairwise(rows):
                if voltage_v <= hi[0]:
                    if voltage_v == hi[0]:
                        return hi[column]
                    return lo[column] + (voltage_v - lo[0]) / (hi[0] - lo[0]) * (hi[column] - lo[column])
        return nominal_value * voltage_v / self.nominal_voltage_v

    def stall_torque_at(self, voltage_v: float) -> float:
        """Stall torque [N m] at ``voltage_v``: linear between datasheet rows, else proportional to voltage."""
        return self._at(voltage_v, 1, self.stall_torque_nm)

    def no_load_speed_at(self, voltage_v: float) -> float:
        """No-load speed [rad/s] at ``voltage_v``: linear between datasheet rows, else proportional to voltage."""
        return self._at(voltage_v, 2, self.no_load_speed_rad_s)

    @property
    def back_emf_damping_nm_s(self) -> float:
        """Viscous coefficient of the back-EMF, tau_stall / w_noload [N m s / rad]."""
        return self.stall_torque_nm / self.no_load_speed_rad_s

    def position_gain_nm_per_rad(self, voltage_v: float, p_gain: int | None = None) -> float:
        """Effective stiffness of the position loop before PWM saturation [N m / rad]."""
        p = self.position_p_gain if p_gain is None else p_gain
        kp_pwm_per_tick = p / 128.0
        return kp_pwm_per_tick * (self.resolution_ticks_per_rev / (2 * math.pi)) * self.stall_torque_at(voltage_v) / PWM_LIMIT

    def saturation_error_rad(self, p_gain: int | None = None) -> float:
        """Position error at which the PWM duty saturates [rad]."""
        p = self.position_p_gain if p_gain is None else p_gain
        return PWM_LIMIT / (p / 128.0) * 2 * math.pi / self.resolution_ticks_per_rev


def _rpm(x: float) -> float:
    return x * 2 * math.pi / 60.0


# --- the catalog file ---------------------------------------------------------------------------

# figures every model states, each with a source (performance: its voltage rows as a whole)
_FIGURES = (
    "control_table_family",
    "resolution_ticks_per_rev",
    "gear_ratio",
    "nominal_voltage_v",
    "performance",
    "position_p_gain",
    "position_d_gain",
    "armature_kg_m2",
    "friction_loss_nm",
    "viscous_damping_nm_s",
)
_MODEL_KEYS = frozenset(_FIGURES) | {"aliases", "notes", "sources"}
_ROW_KEYS = ("voltage_v", "stall_torque_nm", "no_load_speed_rpm")
_GAIN_MAX = 16383  # Position P/D Gain register range (0 ~ 16,383)
_FAMILY = re.compile(r"[a-z0-9][a-z0-9_-]*")


def product_catalog_path() -> Path:
    """The product's servo catalog, ``<configs>/servos/catalog.toml`` (see :func:`robot_rise.paths.configs_dir`)."""
    return configs_dir() / "servos" / "catalog.toml"


def _number(where: str, field: str, value: object, *, positive: bool = True) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or (value <= 0 if positive else value < 0):  # type: ignore[operator]
        raise ConfigError(f"{where}: {field} must be a number {'> 0' if positive else '>= 0'}, got {value!r}")
    return float(value)  # type: ignore[arg-type]


def _integer(where: str, field: str, value: object, low: int, high: int | None = None) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < low or (high is not None and value > high):
        bound = f"{low} ~ {high}" if high is not None else f">= {low}"
        raise ConfigError(f"{where}: {field} must be an integer {bound}, got {value!r}")
    return value


def _model(path: Path, name: str, entry: object) -> ServoDatasheet:
    """Validate one ``[models."<name>"]`` table of ``path`` into a :class:`ServoDatasheet`."""
    where = f"{path}: model {name!r}"
    if not name or name != name.strip():
        raise ConfigError(f"{where}: a model name must be non-empty without surrounding spaces")
    if not isinstance(entry, dict):
        raise ConfigError(f"{where}: must be a table of figures, got {type(entry).__name__}")
    unknown = sorted(set(entry) - _MODEL_KEYS)
    if unknown:
        raise ConfigError(f"{where}: unknown field(s) {', '.join(unknown)}; known: {', '.join(sorted(_MODEL_KEYS))}")
    missing = [k for k in _FIGURES if k not in entry]
    if missing:
        raise ConfigError(f"{where}: missing field(s) {', '.join(missing)}")

    aliases = entry.get("aliases", [])
    if not isinstance(aliases, list) or not all(isinstance(a, str) and a and a == a.strip() for a in aliases):
        raise ConfigError(f"{where}: aliases must be a list of non-empty names, got {aliases!r}")
    if len({name, *aliases}) != 1 + len(aliases):
        raise ConfigError(f"{where}: aliases repeat the model name or each other: {aliases!r}")
    notes = entry.get("notes", "")
    if not isinstance(notes, str):
        raise ConfigError(f"{where}: notes must be a string, got {notes!r}")
    family = entry["control_table_family"]
    if not isinstance(family, str) or not _FAMILY.fullmatch(family):
        raise ConfigError(f"{where}: control_table_family must be a lower-case name such as \"x\", got {family!r}")
    resolution = _integer(where, "resolution_ticks_per_rev", entry["resolution_ticks_per_rev"], 1)
    gear_ratio = _number(where, "gear_ratio", entry["gear_ratio"])
    nominal_v = _number(where, "nominal_voltage_v", entry["nominal_voltage_v"])
    p_gain = _integer(where, "position_p_gain", entry["position_p_gain"], 1, _GAIN_MAX)
    d_gain = _integer(where, "position_d_gain", entry["position_d_gain"], 0, _GAIN_MAX)
    armature = _number(where, "armature_kg_m2", entry["armature_kg_m2"], positive=False)
    friction = _number(where, "friction_loss_nm", entry["friction_loss_nm"], positive=False)
    viscous = _number(where, "viscous_damping_nm_s", entry["viscous_damping_nm_s"], positive=False)

    table = entry["performance"]
    if not isinstance(table, list) or not table:
        raise ConfigError(f"{where}: performance must be a non-empty list of {{{', '.join(_ROW_KEYS)}}} rows")
    rows: list[tuple[float, float, float]] = []
    for i, row in enumerate(table):
        field = f"performance[{i}]"
        if not isinstance(row, dict) or set(row) != set(_ROW_KEYS):
            raise ConfigError(f"{where}: {field} must have exactly the keys {', '.join(_ROW_KEYS)}, got {row!r}")
        v, t, w = (_number(where, f"{field}.{k}", row[k]) for k in _ROW_KEYS)
        if rows and v <= rows[-1][0]:
            raise ConfigError(f"{where}: {field}.voltage_v must be above the row before it ({rows[-1][0]:g} V), got {v:g}")
        rows.append((v, t, _rpm(w)))
    at_nominal = [r for r in rows if r[0] == nominal_v]
    if not at_nominal:
        raise ConfigError(f"{where}: nominal_voltage_v {nominal_v:g} is not one of the performance voltages ({', '.join(f'{r[0]:g}' for r in rows)})")

    sources = entry.get("sources")
    if not isinstance(sources, dict):
        raise ConfigError(f"{where}: missing table sources (one source per figure: an e-manual URL or \"estimate: how\")")
    extra = sorted(set(sources) - set(_FIGURES))
    if extra:
        raise ConfigError(f"{where}: sources names unknown figure(s) {', '.join(extra)}")
    for figure in _FIGURES:
        src = sources.get(figure)
        if not isinstance(src, str) or not (src.startswith("https://") or (src.startswith("estimate:") and src[9:].strip())):
            raise ConfigError(f"{where}: sources.{figure} must be an e-manual URL (https://...) or \"estimate: how\", got {src!r}")

    try:
        return ServoDatasheet(
            model=name,
            nominal_voltage_v=nominal_v,
            stall_torque_nm=at_nominal[0][1],
            no_load_speed_rad_s=at_nominal[0][2],
            gear_ratio=gear_ratio,
            position_p_gain=p_gain,
            position_d_gain=d_gain,
            armature_kg_m2=armature,
            friction_loss_nm=friction,
            viscous_damping_nm_s=viscous,
            notes=notes,
            resolution_ticks_per_rev=resolution,
            control_table_family=family,
            aliases=tuple(aliases),
            performance=tuple(rows),
            sources=tuple((f, sources[f]) for f in _FIGURES),
        )
    except ConfigError as e:  # the dataclass's own checks (all covered above)
        raise ConfigError(f"{path}: {e}") from e


def read_servo_catalog(path: str | os.PathLike[str]) -> tuple[ServoDatasheet, ...]:
    """Read and validate one servo catalog file (format ``robot-rise/servo-catalog@1``), uncached.

    Raises:
        ConfigError: the file is missing or not valid TOML, has another format string, or a model
            has a missing, unknown or out-of-range field or a figure without a source (one line
            naming the file and the model).
    """
    path = Path(path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise ConfigError(f"missing servo catalog {path}") from None
    except OSError as e:
        raise ConfigError(f"{path}: cannot read servo catalog: {e.strerror or e}") from e
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML: {e}") from e
    if data.get("format") != SERVO_CATALOG_FORMAT:
        raise ConfigError(f"{path}: format is {data.get('format')!r}, expected {SERVO_CATALOG_FORMAT!r}")
    unknown = sorted(set(data) - {"format", "models"})
    if unknown:
        raise ConfigError(f"{path}: unknown top-level key(s) {', '.join(unknown)}; models go in [models.\"<name>\"] tables")
    models = data.get("models", {})
    if not isinstance(models, dict):
        raise ConfigError(f"{path}: models must be a table of [models.\"<name>\"] tables")
    sheets = tuple(_model(path, name, entry) for name, entry in models.items())
    owner: dict[str, str] = {}
    for sheet in sheets:
        for n in sheet.names:
            if n in owner:
                raise ConfigError(f"{path}: model {sheet.model!r}: name {n!r} is already taken by model {owner[n]!r}")
            owner[n] = sheet.model
    return sheets


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


_FILE_CACHE: dict[Path, tuple[tuple[int, int], tuple[ServoDatasheet, ...]]] = {}
_CATALOG_CACHE: dict[tuple, ServoCatalog] = {}


def _stamp(path: Path) -> tuple[int, int] | None:
    try:
        st = path.stat()
    except FileNotFoundError:
        return None
    return (st.st_mtime_ns, st.st_size)


def _cached_read(path: Path, stamp: tuple[int, int]) -> tuple[ServoDatasheet, ...]:
    hit = _FILE_CACHE.get(path)
    if hit is not None and hit[0] == stamp:
        return hit[1]
    sheets = read_servo_catalog(path)
    _FILE_CACHE[path] = (stamp, sheets)
    return sheets


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
    product = product_catalog_path().resolve()
    product_stamp = _stamp(product)
    if product_stamp is None:
        raise ConfigError(f"missing servo catalog {product}", hint="reinstall robot-rise, or point ROBOT_RISE_CONFIGS at a configs directory with servos/catalog.toml")
    extra = Path(extra_catalog).resolve() if extra_catalog is not None else None
    extra_stamp = _stamp(extra) if extra is not None else None
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
