"""The import benchmark: every published robot file we have, and a synthetic file per import feature.

Per file: imported or the one-line reason, the body's mass against what the file declares,
collision geoms kept, roles found, the standing posture, seconds of wall time (one process,
one core). The import issue's bar: every file imports, mass within 1 %, every collision geom
kept, under 60 s each.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from robot_rise.bench.import_cases import CASES, SERVO, write_case
from robot_rise.errors import RobotRiseError
from robot_rise.robot_import import import_robot

__all__ = ["ImportRow", "PublishedRobot", "PUBLISHED_ROBOTS", "bench_import", "format_import_table"]


@dataclass(frozen=True)
class PublishedRobot:
    """A robot file of ``../shared/robots`` and what a user gives with it."""

    name: str
    model: str  # relative to the robots directory
    servos: str = ""  # servo map, relative to the robots directory
    servo_model: str = ""  # else every joint this servo


PUBLISHED_ROBOTS = (
    PublishedRobot("bez1", "bez1/bez1.xml", servo_model="MX-28"),
    PublishedRobot("wolfgang", "wolfgang/wolfgang.xml", servo_model="MX-106"),
    PublishedRobot("poppy", "poppy/robots/Poppy_Humanoid.URDF", servos="poppy/poppy_servos.toml"),
    PublishedRobot("wolfgang_ros", "wolfgang_ros/wolfgang_description/urdf/robot.urdf", servos="wolfgang_ros/servos.toml"),
)


@dataclass(frozen=True)
class ImportRow:
    """One file's import."""

    name: str
    kind: str  # "published" or "synthetic"
    imported: bool
    reason: str  # the one-line error ('' when imported)
    mass_kg: float
    declared_mass_kg: float
    collision_geoms: int
    declared_collision_geoms: int
    roles: int
    missing_roles: tuple[str, ...]
    stand: str
    seconds: float

    @property
    def mass_kept(self) -> bool:
        return self.declared_mass_kg > 0 and abs(self.mass_kg - self.declared_mass_kg) <= 0.01 * self.declared_mass_kg

    @property
    def geoms_kept(self) -> bool:
        return self.collision_geoms >= self.declared_collision_geoms


@contextmanager
def _env(values: dict[str, str]) -> Iterator[None]:
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _row(name: str, kind: str, run: Callable[[], object]) -> ImportRow:
    t0 = time.perf_counter()
    try:
        r = run()
    except RobotRiseError as e:
        return ImportRow(name, kind, False, str(e), 0.0, 0.0, 0, 0, 0, (), "", time.perf_counter() - t0)
    seconds = time.perf_counter() - t0
    return ImportRow(
        name, kind, True, "", r.mass_kg, r.declared_mass_kg, r.collision_geoms, r.declared_collision_geoms,  # type: ignore[attr-defined]
        len(r.roles), r.missing_roles, r.stand.removeprefix("standing posture: "), seconds,  # type: ignore[attr-defined]
    )  # fmt: skip


def bench_import(robots_dir: Path | None, *, synthetic: bool = True, progress: Callable[[str], None] | None = None) -> list[ImportRow]:
    """Import every published robot under ``robots_dir`` (skipped if None or absent) and every synthetic case."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="robot_rise_bench_import_") as scratch:
        out = Path(scratch)
        if robots_dir is not None and robots_dir.is_dir():
            for robot in PUBLISHED_ROBOTS:
                if not (robots_dir / robot.model).is_file():
                    continue
                if progress:
                    progress(f"importing {robot.name} ({robot.model})")
                rows.append(_row(robot.name, "published", lambda r=robot: import_robot(
                    robots_dir / r.model, out / r.name,
                    servos=robots_dir / r.servos if r.servos else None,
                    servo_models={"*": r.servo_model} if not r.servos else None,
                )))  # fmt: skip
        if synthetic:
            for name in CASES:
                if progress:
                    progress(f"importing synthetic case {name}")
                case = write_case(name, out / "cases" / name)
                with _env(case.env):
                    rows.append(_row(f"synthetic:{name}", "synthetic", lambda c=case: import_robot(
                        c.model, out / "imported" / c.name,
                        servos=c.servos, servo_models=None if c.servos else {"*": SERVO}, package_paths=c.package_paths,
                    )))  # fmt: skip
    return rows


def format_import_table(rows: list[ImportRow]) -> str:
    """The table BENCHMARKS.md records."""
    lines = [
        "| file | imported | mass kg (file) | collision geoms kept | roles | stand | s |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        if not r.imported:
            lines.append(f"| {r.name} | no: {r.reason} | | | | | {r.seconds:.1f} |")
            continue
        mass = f"{r.mass_kg:.4f} ({r.declared_mass_kg:.4f}, {100 * (r.mass_kg / r.declared_mass_kg - 1):+.2f} %)"
        geoms = f"{r.collision_geoms} / {r.declared_collision_geoms}"
        lines.append(f"| {r.name} | yes | {mass} | {geoms} | {r.roles} of 20 | {r.stand} | {r.seconds:.1f} |")
    n_ok = sum(r.imported for r in rows)
    kept = sum(r.imported and r.mass_kept and r.geoms_kept for r in rows)
    lines.append("")
    lines.append(f"{n_ok} of {len(rows)} files import; {kept} keep the mass within 1 % and every collision geom; slowest {max((r.seconds for r in rows), default=0):.1f} s")
    return "\n".join(lines)
