"""Trajectories: joint targets over time, with the start posture and a report.

File format (JSON), exactly::

    {"format": "robot-rise/trajectory@1", "robot": "op3", "joint_names": [...], "t": [...],
     "q": [[...], ...], "start": <posture@1 object>, "report": {...}}

Optional ``root``: the planned root pose per row, ``[[x, y, z, qw, qx, qy, qz], ...]``, so a
planned path can be re-checked kinematically. Times in seconds (strictly increasing, from 0),
angles in radians.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from robot_rise.errors import FormatError
from robot_rise.fileio import read_json, write_text_atomic
from robot_rise.posture import Posture, posture_from_dict, posture_to_dict

__all__ = ["Trajectory", "TRAJECTORY_FORMAT", "MAX_TRAJECTORY_S", "rounded_as_written", "jsonable", "read_trajectory", "write_trajectory", "trajectory_from_dict", "trajectory_to_dict", "write_csv"]

TRAJECTORY_FORMAT = "robot-rise/trajectory@1"
MAX_TRAJECTORY_S = 600.0  # a file lasting longer is not a get-up (rises last under 20 s): refused on reading, before any replay


@dataclass(frozen=True)
class Trajectory:
    """Joint targets over time.

    Attributes:
        robot: robot name.
        joint_names: column order of ``q``, shape (n,).
        t: sample times [s], shape (T,), strictly increasing, t[0] == 0.
        q: joint targets [rad], shape (T, n).
        start: the posture the robot is in when the trajectory starts.
        report: free-form results (filter report, timings, verdicts); JSON-serialisable.
        root: optional planned root pose per row, shape (T, 7): x, y, z [m], qw, qx, qy, qz.
    """

    robot: str
    joint_names: tuple[str, ...]
    t: np.ndarray
    q: np.ndarray
    start: Posture
    report: dict[str, Any] = field(default_factory=dict)
    root: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        q = np.asarray(self.q, dtype=float)
        n = len(self.joint_names)
        if t.ndim != 1 or t.size < 1:
            raise FormatError("trajectory: 't' must be a non-empty list of times")
        if q.shape != (t.size, n):
            raise FormatError(f"trajectory: 'q' must have shape ({t.size}, {n}) (rows x joints), got {q.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
            raise FormatError("trajectory: 't' or 'q' contain NaN or infinity")
        if abs(t[0]) > 1e-9:
            raise FormatError(f"trajectory: 't' must start at 0, starts at {t[0]}")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            i = int(np.flatnonzero(np.diff(t) <= 0)[0])
            raise FormatError(f"trajectory: 't' must increase strictly (row {i + 1}: {t[i + 1]} after {t[i]})")
        if len(set(self.joint_names)) != n:
            raise FormatError("trajectory: 'joint_names' has duplicates")
        missing = [j for j in self.joint_names if j not in self.start.joints]
        if missing:
            raise FormatError(f"trajectory: start posture lacks joints {', '.join(missing)}")
        root = None
        if self.root is not None:
            root = np.asarray(self.root, dtype=float)
            if root.shape != (t.size, 7) or not np.all(np.isfinite(root)):
                raise FormatError(f"trajectory: 'root' must have shape ({t.size}, 7) of finite numbers, got {root.shape}")
            root.setflags(write=False)
        t.setflags(write=False)
        q.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "root", root)
        object.__setattr__(self, "joint_names", tuple(self.joint_names))

    @property
    def duration_s(self) -> float:
        return float(self.t[-1])

    def sample(self, times_s: np.ndarray) -> np.ndarray:
        """Linear interpolation of the targets at ``times_s`` (clamped to the ends), shape (len, n)."""
        times_s = np.clip(np.asarray(times_s, dtype=float), 0.0, self.duration_s)
        return np.stack([np.interp(times_s, self.t, self.q[:, j]) for j in range(self.q.shape[1])], axis=-1)

    def with_report(self, **entries: Any) -> Trajectory:
        """Copy with report entries added or replaced."""
        return Trajectory(self.robot, self.joint_names, self.t, self.q, self.start, {**self.report, **entries}, self.root)


def trajectory_to_dict(tr: Trajectory) -> dict[str, Any]:
    obj: dict[str, Any] = {
        "format": TRAJECTORY_FORMAT,
        "robot": tr.robot,
        "joint_names": list(tr.joint_names),
        "t": rounded_as_written(tr.t),
        "q": rounded_as_written(tr.q),
        "start": posture_to_dict(tr.start),
        "report": _jsonable(tr.report),
    }
    if tr.root is not None:
        obj["root"] = rounded_as_written(tr.root)
    return obj


def rounded_as_written(a: np.ndarray) -> list:
    """Times, angles and root rows as the file keeps them: to 6 decimals (1 us, 1 urad), as plain
    floats; the one rounding the file and its seal (:mod:`robot_rise.seal`) share."""
    return np.round(np.asarray(a, dtype=float), 6).tolist()


def jsonable(x: Any) -> Any:
    """A report value as the file writes it: numpy arrays and numbers as lists and plain numbers, NaN and infinity as null."""
    return _jsonable(x)


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _holds_non_numbers(x: Any) -> bool:
    """Text, booleans or nulls among a field's numbers (numpy's float conversion would take "0.1")."""
    try:
        kind = np.asarray(x).dtype.kind
    except ValueError:  # ragged rows: the shape check names them
        return False
    return kind not in "fiu"


def trajectory_from_dict(obj: Any, *, where: str = "trajectory") -> Trajectory:
    """Parse a trajectory@1 object.

    Raises:
        FormatError: naming the field and the problem.
    """
    if not isinstance(obj, dict):
        raise FormatError(f"{where}: expected a JSON object")
    if obj.get("format") != TRAJECTORY_FORMAT:
        raise FormatError(f"{where}: format is {obj.get('format')!r}, expected {TRAJECTORY_FORMAT!r}")
    for key in ("robot", "joint_names", "t", "q", "start"):
        if key not in obj:
            raise FormatError(f"{where}: missing field {key!r}")
    names = obj["joint_names"]
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names) or not names:
        raise FormatError(f"{where}: 'joint_names' must be a non-empty list of strings")
    start = posture_from_dict(obj["start"], where=f"{where}: start")
    report = obj.get("report", {})
    if not isinstance(report, dict):
        raise FormatError(f"{where}: 'report' must be an object")
    for key in ("t", "q", "root"):  # numbers, not numbers written as text ("0.1" would parse)
        if key in obj and obj[key] is not None and _holds_non_numbers(obj[key]):
            raise FormatError(f"{where}: {key!r} must hold numbers only (found text, a boolean or null)")
    try:
        t = np.asarray(obj["t"], dtype=float)
        q = np.asarray(obj["q"], dtype=float)
        root = None if obj.get("root") is None else np.asarray(obj["root"], dtype=float)
    except (TypeError, ValueError) as e:
        raise FormatError(f"{where}: 't', 'q' and 'root' must be numbers ({e})") from None
    if t.size and np.isfinite(t[-1]) and t[-1] > MAX_TRAJECTORY_S:
        raise FormatError(f"{where}: lasts {t[-1]:g} s; a get-up file lasts at most {MAX_TRAJECTORY_S:g} s")
    try:
        return Trajectory(str(obj["robot"]), tuple(names), t, q, start, report, root)
    except FormatError as e:
        raise FormatError(f"{where}: {str(e).removeprefix('trajectory: ')}") from None


def read_trajectory(path: str | os.PathLike[str]) -> Trajectory:
    """Read and validate a trajectory file."""
    path = Path(path)
    obj = read_json(path, "trajectory file")
    return trajectory_from_dict(obj, where=str(path))


def write_trajectory(path: str | os.PathLike[str], tr: Trajectory) -> None:
    """Write a trajectory file atomically (temporary file, then rename)."""
    write_text_atomic(path, json.dumps(trajectory_to_dict(tr)) + "\n")


def write_csv(path: str | os.PathLike[str], tr: Trajectory) -> None:
    """Export t [s] and q [rad] as CSV (header: t, joint names), for spreadsheets and plotting
    tools; written atomically like every file of ours (temporary file, then rename)."""
    buf = io.StringIO(newline="")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["t", *tr.joint_names])
    for ti, row in zip(tr.t, tr.q):
        w.writerow([f"{ti:.6f}", *(f"{x:.6f}" for x in row)])
    write_text_atomic(path, buf.getvalue())
