"""The servo catalog file (format ``robot-rise/servo-catalog@1``): datasheet figures per servo model.

The one place the servos' physical figures live, each with its source (a ROBOTIS e-manual page or
"estimate: how"): the product's ``configs/servos/catalog.toml`` and, in the same format, a robot
directory's own ``servo_models.toml``. :func:`read_servo_catalog` is the file's only reader;
``robot_rise.servo`` builds the simulator's servo model on it and ``drivers`` the emulated
servos' load model (:func:`product_datasheet`), so the two never hold different figures.

Stall torque and no-load speed are given at a few voltages (the e-manual's 11.1 / 12 / 14.8 V
rows); between rows they are interpolated linearly, outside them the nominal row scales in
proportion to voltage (the DC-motor model, and the only one where a single row is known).
"""

from __future__ import annotations

import itertools
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

from robot_files.errors import RobotFileError
from robot_files.paths import configs_dir
from robot_files.toml_file import read_toml

__all__ = [
    "ServoDatasheet",
    "SERVO_CATALOG_FORMAT",
    "ROBOT_SERVO_MODELS_FILE",
    "TICKS_PER_REV",
    "PWM_LIMIT",
    "product_catalog_path",
    "read_servo_catalog",
    "catalog_stamp",
    "cached_servo_catalog",
    "product_catalog",
    "product_datasheet",
]

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
                raise RobotFileError(f"servo {self.model}: {name} must be > 0")
        if not self.position_p_gain > 0:
            raise RobotFileError(f"servo {self.model}: position_p_gain must be > 0")
        rows = self.performance
        if rows:
            if any(not (v > 0 and t > 0 and w > 0) for v, t, w in rows):
                raise RobotFileError(f"servo {self.model}: performance rows must be positive")
            if any(b[0] <= a[0] for a, b in itertools.pairwise(rows)):
                raise RobotFileError(f"servo {self.model}: performance voltages must increase")
            nominal = [r for r in rows if r[0] == self.nominal_voltage_v]
            if nominal != [(self.nominal_voltage_v, self.stall_torque_nm, self.no_load_speed_rad_s)]:
                raise RobotFileError(f"servo {self.model}: the performance row at the nominal {self.nominal_voltage_v:g} V must be the nominal figures")

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
    """The product's servo catalog, ``<configs>/servos/catalog.toml`` (see :func:`robot_files.paths.configs_dir`)."""
    return configs_dir() / "servos" / "catalog.toml"


def _number(where: str, field: str, value: object, *, positive: bool = True) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or (value <= 0 if positive else value < 0):  # type: ignore[operator]
        raise RobotFileError(f"{where}: {field} must be a number {'> 0' if positive else '>= 0'}, got {value!r}")
    return float(value)  # type: ignore[arg-type]


def _integer(where: str, field: str, value: object, low: int, high: int | None = None) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < low or (high is not None and value > high):
        bound = f"{low} ~ {high}" if high is not None else f">= {low}"
        raise RobotFileError(f"{where}: {field} must be an integer {bound}, got {value!r}")
    return value


def _model(path: Path, name: str, entry: object) -> ServoDatasheet:
    """Validate one ``[models."<name>"]`` table of ``path`` into a :class:`ServoDatasheet`."""
    where = f"{path}: model {name!r}"
    if not name or name != name.strip():
        raise RobotFileError(f"{where}: a model name must be non-empty without surrounding spaces")
    if not isinstance(entry, dict):
        raise RobotFileError(f"{where}: must be a table of figures, got {type(entry).__name__}")
    unknown = sorted(set(entry) - _MODEL_KEYS)
    if unknown:
        raise RobotFileError(f"{where}: unknown field(s) {', '.join(unknown)}; known: {', '.join(sorted(_MODEL_KEYS))}")
    missing = [k for k in _FIGURES if k not in entry]
    if missing:
        raise RobotFileError(f"{where}: missing field(s) {', '.join(missing)}")

    aliases = entry.get("aliases", [])
    if not isinstance(aliases, list) or not all(isinstance(a, str) and a and a == a.strip() for a in aliases):
        raise RobotFileError(f"{where}: aliases must be a list of non-empty names, got {aliases!r}")
    if len({name, *aliases}) != 1 + len(aliases):
        raise RobotFileError(f"{where}: aliases repeat the model name or each other: {aliases!r}")
    notes = entry.get("notes", "")
    if not isinstance(notes, str):
        raise RobotFileError(f"{where}: notes must be a string, got {notes!r}")
    family = entry["control_table_family"]
    if not isinstance(family, str) or not _FAMILY.fullmatch(family):
        raise RobotFileError(f"{where}: control_table_family must be a lower-case name such as \"x\", got {family!r}")
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
        raise RobotFileError(f"{where}: performance must be a non-empty list of {{{', '.join(_ROW_KEYS)}}} rows")
    rows: list[tuple[float, float, float]] = []
    for i, row in enumerate(table):
        field = f"performance[{i}]"
        if not isinstance(row, dict) or set(row) != set(_ROW_KEYS):
            raise RobotFileError(f"{where}: {field} must have exactly the keys {', '.join(_ROW_KEYS)}, got {row!r}")
        v, t, w = (_number(where, f"{field}.{k}", row[k]) for k in _ROW_KEYS)
        if rows and v <= rows[-1][0]:
            raise RobotFileError(f"{where}: {field}.voltage_v must be above the row before it ({rows[-1][0]:g} V), got {v:g}")
        rows.append((v, t, _rpm(w)))
    at_nominal = [r for r in rows if r[0] == nominal_v]
    if not at_nominal:
        raise RobotFileError(f"{where}: nominal_voltage_v {nominal_v:g} is not one of the performance voltages ({', '.join(f'{r[0]:g}' for r in rows)})")

    sources = entry.get("sources")
    if not isinstance(sources, dict):
        raise RobotFileError(f"{where}: missing table sources (one source per figure: an e-manual URL or \"estimate: how\")")
    extra = sorted(set(sources) - set(_FIGURES))
    if extra:
        raise RobotFileError(f"{where}: sources names unknown figure(s) {', '.join(extra)}")
    for figure in _FIGURES:
        src = sources.get(figure)
        if not isinstance(src, str) or not (src.startswith("https://") or (src.startswith("estimate:") and src[9:].strip())):
            raise RobotFileError(f"{where}: sources.{figure} must be an e-manual URL (https://...) or \"estimate: how\", got {src!r}")

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
    except RobotFileError as e:  # the dataclass's own checks (all covered above)
        raise RobotFileError(f"{path}: {e}") from e


def read_servo_catalog(path: str | os.PathLike[str]) -> tuple[ServoDatasheet, ...]:
    """Read and validate one servo catalog file (format ``robot-rise/servo-catalog@1``), uncached.

    Raises:
        RobotFileError: the file is missing or not valid TOML, has another format string, or a model
            has a missing, unknown or out-of-range field or a figure without a source (one line
            naming the file and the model).
    """
    path = Path(path)
    data = read_toml(path, "servo catalog")
    if data.get("format") != SERVO_CATALOG_FORMAT:
        raise RobotFileError(f"{path}: format is {data.get('format')!r}, expected {SERVO_CATALOG_FORMAT!r}")
    unknown = sorted(set(data) - {"format", "models"})
    if unknown:
        raise RobotFileError(f"{path}: unknown top-level key(s) {', '.join(unknown)}; models go in [models.\"<name>\"] tables")
    models = data.get("models", {})
    if not isinstance(models, dict):
        raise RobotFileError(f"{path}: models must be a table of [models.\"<name>\"] tables")
    sheets = tuple(_model(path, name, entry) for name, entry in models.items())
    owner: dict[str, str] = {}
    for sheet in sheets:
        for n in sheet.names:
            if n in owner:
                raise RobotFileError(f"{path}: model {sheet.model!r}: name {n!r} is already taken by model {owner[n]!r}")
            owner[n] = sheet.model
    return sheets


_FILE_CACHE: dict[Path, tuple[tuple[int, int], tuple[ServoDatasheet, ...]]] = {}


def catalog_stamp(path: Path) -> tuple[int, int] | None:
    """(modification time [ns], size) of a catalog file, None if there is none: what the cache keys on."""
    try:
        st = path.stat()
    except FileNotFoundError:
        return None
    return (st.st_mtime_ns, st.st_size)


def cached_servo_catalog(path: Path, stamp: tuple[int, int]) -> tuple[ServoDatasheet, ...]:
    """:func:`read_servo_catalog` of ``path``, read again only when its ``stamp`` changes."""
    hit = _FILE_CACHE.get(path)
    if hit is not None and hit[0] == stamp:
        return hit[1]
    sheets = read_servo_catalog(path)
    _FILE_CACHE[path] = (stamp, sheets)
    return sheets


def product_catalog() -> tuple[Path, tuple[int, int]]:
    """The product catalog's resolved path and its :func:`catalog_stamp`.

    Raises:
        RobotFileError: there is no product catalog.
    """
    path = product_catalog_path().resolve()
    stamp = catalog_stamp(path)
    if stamp is None:
        raise RobotFileError(f"missing servo catalog {path}", hint="reinstall robot-rise, or point ROBOT_RISE_CONFIGS at a configs directory with servos/catalog.toml")
    return path, stamp


def product_datasheet(model: str) -> ServoDatasheet:
    """The product catalog's datasheet of ``model`` (its name or an alias).

    Raises:
        RobotFileError: the catalog is missing or malformed, or has no such model.
    """
    path, stamp = product_catalog()
    for sheet in cached_servo_catalog(path, stamp):
        if model in sheet.names:
            return sheet
    raise RobotFileError(f"{path}: no servo model {model!r}")
