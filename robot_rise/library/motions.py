"""The motion library as files: ``index.json`` and the motions it names, read and validated.

A library directory holds ``index.json`` (format ``robot-rise/motion-library@1``) naming, per
motion, a trajectory file (``robot-rise/trajectory@1`` with the simulated ``root`` pose per row), its
start posture file and ``connect_until_s``, the end of the lying-to-sitting/squatting phase.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

from robot_rise.errors import FormatError
from robot_rise.fileio import read_json
from robot_rise.model import Robot
from robot_rise.paths import configs_dir
from robot_rise.posture import Posture, read_posture
from robot_rise.trajectory import Trajectory, read_trajectory
from robot_rise.seal import seal_problem

__all__ = ["LIBRARY_FORMAT", "LYING_KINDS", "MAX_COMBINED_VARIANTS", "MAX_NOISE_REPLAYS", "Motion", "MotionLibrary", "load_library", "default_library_dir", "robot_library_dir", "library_digest"]

LIBRARY_FORMAT = "robot-rise/motion-library@1"
LYING_KINDS = ("supine", "prone", "left", "right")


def default_library_dir(robot_name: str = "op3") -> Path:
    """The shipped library of a robot: ``configs/motions/<robot>``."""
    return configs_dir() / "motions" / robot_name


def robot_library_dir(robot: Robot) -> Path:
    """The library a robot uses (robot.toml's ``library``): a directory of that name in the robot
    directory if there is one (an imported robot's own ``motions``), else the shipped
    ``configs/motions/<library>``."""
    own = robot.directory / robot.library
    shipped = default_library_dir(robot.library)
    return shipped if not own.is_dir() and shipped.is_dir() else own


def library_digest(robot: Robot) -> str:
    """SHA-256 of every file of the library a robot rises with (:func:`robot_library_dir`), '' when it has none.

    Each file by its path relative to the library directory and its bytes, in path order: what
    a batch task's id and the benchmarks' frozen problems name the library by.
    """
    root = robot_library_dir(robot)
    files = sorted(p for p in root.rglob("*") if p.is_file()) if root.is_dir() else []
    if not files:
        return ""
    h = hashlib.sha256()
    for path in files:
        h.update(os.path.relpath(path, root).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


MAX_COMBINED_VARIANTS = 16  # combined variants a motion's proofs may ask for: each is one more replay of every proof
MAX_NOISE_REPLAYS = 24  # noisy replays a motion's proofs may ask for (each ~0.1 s of CPU per proof)


@dataclass(frozen=True)
class Motion:
    """One library motion.

    Attributes:
        name: motion name (file stem).
        lying: ``supine``, ``prone``, ``left`` or ``right``.
        strategy: one line for people.
        trajectory: the joint-target trajectory (with the simulated root pose per row).
        start: the settled lying posture it starts from.
        connect_until_s: end of the lying-to-sitting/squatting phase [s].
        max_stretch: how far it may be slowed and still stand, a multiple of its duration (None:
            no bound of its own; ``robot_rise.library.strategies.KeyframedMotion.max_stretch``).
        combined_variants: combined random variants its proofs replay besides the ensemble
            (``robot_rise.library.strategies.KeyframedMotion.combined_variants``).
        noise_replays: noisy replays its proofs run when more than the filter's (0: the filter's;
            ``robot_rise.library.strategies.KeyframedMotion.noise_replays``).
    """

    name: str
    lying: str
    strategy: str
    trajectory: Trajectory
    start: Posture
    connect_until_s: float
    max_stretch: float | None = None
    combined_variants: int = 0
    noise_replays: int = 0

    @property
    def duration_s(self) -> float:
        return self.trajectory.duration_s


@dataclass(frozen=True)
class MotionLibrary:
    """The motions of one robot, in index order."""

    robot: str
    directory: Path
    motions: tuple[Motion, ...]

    def names(self) -> list[str]:
        return [m.name for m in self.motions]

    def get(self, name: str) -> Motion:
        """The motion called ``name``; FormatError listing the names otherwise."""
        for m in self.motions:
            if m.name == name:
                return m
        raise FormatError(f"no motion {name!r} in {self.directory}; motions: {', '.join(self.names())}")


_SEALS_HELD: set[tuple[str, int, int]] = set()  # (file, mtime ns, size) whose seal held: checked once per process


def _seal_problem_of_file(path: Path, tr: Trajectory) -> str:
    """:func:`robot_rise.seal.seal_problem` of a motion file, remembered while the file is unchanged
    (a guard or a test session loads its library many times)."""
    info = path.stat()
    key = (str(path.resolve()), info.st_mtime_ns, info.st_size)
    if key in _SEALS_HELD:
        return ""
    problem = seal_problem(tr)
    if not problem:
        _SEALS_HELD.add(key)
    return problem


def load_library(directory: str | os.PathLike[str] | None = None, *, robot_name: str = "op3", sealed_only: bool = True) -> MotionLibrary:
    """Read a library directory (default: the shipped one) and validate every file it names.

    A motion whose report says proven must carry its seal, and the seal must hold
    (:mod:`robot_rise.seal`): a hand-edited motion is refused (``sealed_only=False`` reads it
    anyway, for ``library prove`` to prove it again).

    Raises:
        FormatError: the index or a motion file is missing or malformed (the message names it).
    """
    root = Path(directory) if directory is not None else default_library_dir(robot_name)
    path = root / "index.json"
    if not path.exists():
        raise FormatError(
            f"{path}: no motion library index", hint="build the robot's library: robot-rise library build --robot ROBOT_DIR (the shipped OP3's: library author)"
        )
    obj = read_json(path, "motion library index")
    if not isinstance(obj, dict) or obj.get("format") != LIBRARY_FORMAT:
        got = obj.get("format") if isinstance(obj, dict) else None
        raise FormatError(f"{path}: format is {got!r}, expected {LIBRARY_FORMAT!r}")
    rows = obj.get("motions")
    if not isinstance(rows, list) or not rows:
        raise FormatError(f"{path}: 'motions' must be a non-empty list")
    motions = []
    seen: set[str] = set()
    for i, row in enumerate(rows):
        where = f"{path}: motions[{i}]"
        if not isinstance(row, dict):
            raise FormatError(f"{where}: expected an object")
        for key in ("name", "lying", "trajectory", "start", "connect_until_s"):
            if key not in row:
                raise FormatError(f"{where}: missing field {key!r}")
        name = str(row["name"])
        if name in seen:
            raise FormatError(f"{where}: motion name {name!r} appears twice")
        seen.add(name)
        if row["lying"] not in LYING_KINDS:
            raise FormatError(f"{where}: lying is {row['lying']!r}; expected one of {', '.join(LYING_KINDS)}")
        tr = read_trajectory(root / str(row["trajectory"]))
        problem = _seal_problem_of_file(root / str(row["trajectory"]), tr) if sealed_only and tr.report.get("proven") is True else ""
        if problem:
            raise FormatError(f"{root / str(row['trajectory'])}: motion {name!r} is not what was proven: {problem}",
                              hint="re-prove the library: robot-rise library prove --dir DIR (or build it again)")
        start = read_posture(root / str(row["start"]))
        if tr.root is None:
            raise FormatError(f"{root / str(row['trajectory'])}: library motions need the simulated 'root' pose per row")
        cut = float(row["connect_until_s"])
        if not 0.0 < cut <= tr.duration_s:
            raise FormatError(f"{where}: connect_until_s {cut} must lie in (0, {tr.duration_s}]")
        stretch = row.get("max_stretch")
        if stretch is not None and not (isinstance(stretch, (int, float)) and not isinstance(stretch, bool) and stretch >= 1.0):
            raise FormatError(f"{where}: max_stretch {stretch!r} must be a number >= 1 (a multiple of the motion's duration)")
        combined = row.get("combined_variants", 0)
        if not (isinstance(combined, int) and not isinstance(combined, bool) and 0 <= combined <= MAX_COMBINED_VARIANTS):
            raise FormatError(f"{where}: combined_variants {combined!r} must be a whole number in 0..{MAX_COMBINED_VARIANTS}")
        noisy = row.get("noise_replays", 0)
        if not (isinstance(noisy, int) and not isinstance(noisy, bool) and 0 <= noisy <= MAX_NOISE_REPLAYS):
            raise FormatError(f"{where}: noise_replays {noisy!r} must be a whole number in 0..{MAX_NOISE_REPLAYS}")
        motions.append(Motion(name, str(row["lying"]), str(row.get("strategy", "")), tr, start, cut,
                              None if stretch is None else float(stretch), combined, noisy))
    return MotionLibrary(str(obj.get("robot", robot_name)), root, tuple(motions))
