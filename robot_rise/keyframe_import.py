"""A user's own get-up read from keyframes: a CSV of joint angles over time, or MuJoCo keyframes.

Two readers, one value (:class:`ImportedKeyframes`, the targets in the robot's joint order):

- **CSV** (:func:`read_keyframes_csv`, format :data:`KEYFRAMES_CSV_FORMAT`): a header
  ``time_s,<joint>,<joint>,...`` (``t`` is taken for ``time_s``, as ``export-csv`` writes it), then
  one row per keyframe: its time [s] and the joint targets [rad; degrees with ``degrees=True``].
  Columns by joint name, in any order; every driven joint of the robot present, no other column.
  Leading ``#`` lines are comments; one that names a ``robot-rise/...`` format must name this one.
- **MuJoCo keyframes** (:func:`read_mujoco_keyframes`, the format
  :mod:`robot_rise.keyframe_export` writes, :data:`~robot_rise.keyframe_export.KEYFRAMES_FORMAT`):
  ``<mujoco><keyframe><key time=".." qpos=".."/>...</keyframe></mujoco>`` for the robot's own
  MJCF, qpos in that model's order (the root free joint first where the model has one, then the
  joints): each driven joint read at its qpos address. Passive joints (``robot.toml``
  ``passive``), ``ctrl`` and the other attributes MuJoCo knows are not targets and are ignored; an
  attribute MuJoCo does not know is refused, as MuJoCo refuses it. The leading comment the exporter
  writes (format and robot) is checked when present; a file without it is read the same.

Either way: times finite, from 0 up, strictly increasing (a first keyframe after 0 is held from 0:
the robot lies in it at rest when the motion starts); at least two keyframes; every angle finite
and within the joint's limits (up to ``LIMIT_CLAMP_TOLERANCE_RAD`` past one is clamped into it).
A file that breaks a rule raises :class:`~robot_rise.errors.FormatError` with one line naming the
file, the row or key, and the joints.

The start posture is the first keyframe's joints with a lying root: the MuJoCo file's first key
root where the model has a free joint (:meth:`ImportedKeyframes.start_posture`); otherwise the
caller settles the first keyframe on the floor (``robot-rise library add --lying KIND`` does it as
the library's own motions are settled) and :meth:`ImportedKeyframes.trajectory` makes the
trajectory of the targets from it.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import mujoco
import numpy as np

from robot_rise.errors import ConfigError, FormatError, mujoco_reason
from robot_rise.keyframe_export import KEYFRAMES_FORMAT
from robot_rise.model import Robot
from robot_rise.posture import LIMIT_CLAMP_TOLERANCE_RAD, Posture
from robot_rise.trajectory import MAX_TRAJECTORY_S, Trajectory

__all__ = ["KEYFRAMES_CSV_FORMAT", "ImportedKeyframes", "read_keyframes", "read_keyframes_csv", "read_mujoco_keyframes"]

KEYFRAMES_CSV_FORMAT = "robot-rise/keyframes-csv@1"
_TIME_COLUMNS = ("time_s", "t")
# the attributes MuJoCo's <key> takes (its MJCF reference); any other it refuses, and so do we
_KEY_ATTRIBUTES = frozenset({"name", "time", "qpos", "qvel", "act", "mpos", "mquat", "ctrl"})
_EXPORT_ROBOT = re.compile(r"for robot (\S+?)'s ")  # the exporter's comment: "... for robot op3's op3.xml ..."


@dataclass(frozen=True)
class ImportedKeyframes:
    """Keyframes read from a user's file, in the robot's joint order.

    Attributes:
        source: the file read.
        format: :data:`KEYFRAMES_CSV_FORMAT` or the MuJoCo keyframes' ``KEYFRAMES_FORMAT``.
        robot: the robot's name.
        joint_names: the robot's driven joints (column order of ``q``), shape (n,).
        time_s: keyframe times [s], shape (K,), strictly increasing from 0, K >= 2.
        q: joint targets [rad], shape (K, n), within the joint limits.
        root_pose: the first key's root x, y, z [m], qw, qx, qy, qz (unit), shape (7,); None when
            the file has no root (a CSV, or a model without a free joint).
    """

    source: str
    format: str
    robot: str
    joint_names: tuple[str, ...]
    time_s: np.ndarray
    q: np.ndarray
    root_pose: np.ndarray | None = None

    def first_joints(self) -> dict[str, float]:
        """The first keyframe's joint targets [rad] by name: what the start posture holds."""
        return {j: float(v) for j, v in zip(self.joint_names, self.q[0])}

    def start_posture(self) -> Posture | None:
        """The first key as a posture (its root and joints); None when the file gives no root."""
        if self.root_pose is None:
            return None
        return Posture(self.robot, self.root_pose[:3], self.root_pose[3:], self.first_joints())

    def trajectory(self, start: Posture, *, report: dict[str, Any] | None = None) -> Trajectory:
        """The targets as a trajectory from ``start`` (rows: the keyframes, linear between them)."""
        return Trajectory(self.robot, self.joint_names, self.time_s, self.q, start, dict(report or {}))


def read_keyframes(path: str | os.PathLike[str], robot: Robot, *, degrees: bool = False) -> ImportedKeyframes:
    """Read keyframes by the file's suffix: ``.csv`` (:func:`read_keyframes_csv`) or ``.xml``
    (:func:`read_mujoco_keyframes`; ``degrees`` is for CSV only: MuJoCo's qpos is in radians).

    Raises:
        FormatError: an unknown suffix, or as the reader.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        return read_keyframes_csv(path, robot, degrees=degrees)
    if suffix == ".xml":
        if degrees:
            raise FormatError(f"{path}: MuJoCo keyframes hold radians (qpos); --degrees is for a CSV")
        return read_mujoco_keyframes(path, robot)
    raise FormatError(f"{path}: keyframes are read from a .csv (time_s and joint angles) or a .xml (MuJoCo keyframes), not {suffix or 'a file without suffix'!r}")


def _read_text(path: str | os.PathLike[str], what: str) -> str:
    try:
        return Path(path).read_text()
    except FileNotFoundError:
        raise FormatError(f"{path}: no such {what}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise FormatError(f"{path}: cannot read the {what}: {getattr(e, 'strerror', None) or e}") from None


def read_keyframes_csv(path: str | os.PathLike[str], robot: Robot, *, degrees: bool = False) -> ImportedKeyframes:
    """Read a CSV of keyframes (see the module docstring).

    Args:
        path: the CSV file.
        robot: the robot the angles are for (its driven joints and limits).
        degrees: the angles are in degrees (times stay in seconds).

    Raises:
        FormatError: one line naming the file and the problem (missing or unknown joints, a time
            out of order, a value that is not a finite number, an angle past its limit).
    """
    text = _read_text(path, "keyframe CSV")
    lines = text.splitlines()
    body = 0
    while body < len(lines) and (lines[body].lstrip().startswith("#") or not lines[body].strip()):
        named = re.search(r"robot-rise/[\w.-]+@\d+", lines[body])
        if named and named.group(0) != KEYFRAMES_CSV_FORMAT:
            raise FormatError(f"{path}: format is {named.group(0)!r}, expected {KEYFRAMES_CSV_FORMAT!r}")
        body += 1
    rows = [r for r in csv.reader(io.StringIO("\n".join(lines[body:]))) if any(c.strip() for c in r)]
    if not rows:
        raise FormatError(f"{path}: empty; expected a header 'time_s,<joint>,...' and a row per keyframe")
    header = [c.strip() for c in rows[0]]
    if header[0] not in _TIME_COLUMNS:
        raise FormatError(f"{path}: the first column must be 'time_s' (seconds), not {header[0]!r}")
    columns = header[1:]
    doubled = sorted({c for c in columns if columns.count(c) > 1})
    if doubled:
        raise FormatError(f"{path}: joints named twice in the header: {', '.join(doubled)}")
    _check_joint_names(path, robot, columns)
    values = np.empty((len(rows) - 1, len(header)))
    for k, row in enumerate(rows[1:]):
        line = k + body + 2  # 1-based, the header counted
        if len(row) != len(header):
            raise FormatError(f"{path}: line {line} has {len(row)} values, the header {len(header)}")
        for c, cell in enumerate(row):
            try:
                values[k, c] = float(cell)
            except ValueError:
                raise FormatError(f"{path}: line {line}, column {header[c]}: {cell.strip()!r} is not a number") from None
    angles = np.radians(values[:, 1:]) if degrees else values[:, 1:]
    order = [columns.index(j) for j in robot.joint_names]
    time_s, q = _checked(path, robot, values[:, 0], angles[:, order], [f"line {k + body + 2}" for k in range(len(values))])
    return ImportedKeyframes(str(path), KEYFRAMES_CSV_FORMAT, robot.name, robot.joint_names, time_s, q)


def read_mujoco_keyframes(path: str | os.PathLike[str], robot: Robot) -> ImportedKeyframes:
    """Read MuJoCo keyframes of ``robot``'s own MJCF (see the module docstring).

    Raises:
        FormatError: one line naming the file and the problem (not MuJoCo keyframes, another
            robot's or format's, a qpos of the wrong length, a time out of order, NaN, an angle
            past its limit).
        ConfigError: the robot's MJCF cannot be loaded.
    """
    text = _read_text(path, "MuJoCo keyframe file")
    try:
        root = ElementTree.fromstring(text, parser=ElementTree.XMLParser(target=ElementTree.TreeBuilder(insert_comments=True)))
    except ElementTree.ParseError as e:
        raise FormatError(f"{path}: not XML: {e}") from None
    if root.tag != "mujoco":
        raise FormatError(f"{path}: the root element is <{root.tag}>, expected <mujoco> (MuJoCo keyframes)")
    for comment in (c for c in root if c.tag is ElementTree.Comment):
        named = re.search(r"robot-rise/[\w.-]+@\d+", comment.text or "")
        if named and named.group(0) != KEYFRAMES_FORMAT:
            raise FormatError(f"{path}: format is {named.group(0)!r}, expected {KEYFRAMES_FORMAT!r}")
        whose = _EXPORT_ROBOT.search(comment.text or "") if named else None
        if whose and whose.group(1) != robot.name:
            raise FormatError(f"{path}: keyframes of robot {whose.group(1)!r}, not {robot.name!r}", hint="pass --robot DIR of its robot")
    keys = [k for block in root.iter("keyframe") for k in block if k.tag is not ElementTree.Comment]
    if not keys:
        raise FormatError(f"{path}: no <keyframe><key .../></keyframe> in it")
    m = _robot_model(robot)
    where = [f"key {k} ({key.get('name')})" if key.get("name") else f"key {k}" for k, key in enumerate(keys)]
    qpos = np.empty((len(keys), m.nq))
    times = np.empty(len(keys))
    for k, key in enumerate(keys):
        unknown = sorted(set(key.attrib) - _KEY_ATTRIBUTES) if key.tag == "key" else []
        if key.tag != "key" or unknown:
            what = f"<{key.tag}>" if key.tag != "key" else f"attribute {', '.join(unknown)}"
            raise FormatError(f"{path}: {where[k]}: MuJoCo's <keyframe> takes <key> with {', '.join(sorted(_KEY_ATTRIBUTES))}, not {what}")
        if "qpos" not in key.attrib:
            raise FormatError(f"{path}: {where[k]}: no qpos (the posture is the target)")
        try:
            times[k] = float(key.get("time", "0"))
            row = np.array([float(x) for x in key.get("qpos", "").split()])
        except ValueError as e:
            raise FormatError(f"{path}: {where[k]}: time and qpos must be numbers ({e})") from None
        if row.shape != (m.nq,):
            raise FormatError(f"{path}: {where[k]}: qpos has {row.size} numbers, {robot.xml_path.name} has nq = {m.nq}",
                              hint="MuJoCo keyframes are of one model: export them for this robot (robot-rise export-keyframes)")
        qpos[k] = row
    adr = [int(m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)]) for j in robot.joint_names]
    time_s, q = _checked(path, robot, times, qpos[:, adr], where)
    root_pose = None
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, robot.root_body)
    free = int(m.body_jntadr[body]) if body >= 0 else -1
    if free >= 0 and int(m.jnt_type[free]) == mujoco.mjtJoint.mjJNT_FREE:
        a = int(m.jnt_qposadr[free])
        root_pose = np.array(qpos[0, a:a + 7])
        norm = float(np.linalg.norm(root_pose[3:]))
        if not (np.all(np.isfinite(root_pose)) and norm > 0.0):
            raise FormatError(f"{path}: {where[0]}: the root pose (qpos {a}..{a + 6}) is not finite with a quaternion")
        root_pose[3:] /= norm  # unit length, as MuJoCo makes a key's on loading
    return ImportedKeyframes(str(path), KEYFRAMES_FORMAT, robot.name, robot.joint_names, time_s, q, root_pose)


def _robot_model(robot: Robot) -> mujoco.MjModel:
    """The robot's MJCF compiled alone: the model the exporter orders qpos for."""
    try:
        m = mujoco.MjSpec.from_file(str(robot.xml_path)).compile()
    except Exception as e:  # mujoco raises ValueError with the parser message
        raise ConfigError(f"{robot.xml_path}: cannot load MJCF: {mujoco_reason(e)}") from e
    missing = [j for j in robot.joint_names if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) < 0]
    if missing:
        raise ConfigError(f"{robot.xml_path.name} has no joint {', '.join(missing)}")
    return m


def _check_joint_names(path: str | os.PathLike[str], robot: Robot, columns: list[str]) -> None:
    """Every driven joint present and no other column, in one line naming them."""
    missing = [j for j in robot.joint_names if j not in columns]
    unknown = [c for c in columns if c not in robot.joint_names]
    problems = []
    if missing:
        problems.append(f"missing joints {', '.join(missing)}")
    if unknown:
        passive = [c for c in unknown if c in robot.passive_joints]
        other = [c for c in unknown if c not in passive]
        if other:
            problems.append(f"unknown joints {', '.join(other)}")
        if passive:
            problems.append(f"passive joints {', '.join(passive)} (solved from the driven ones, not targets)")
    if problems:
        raise FormatError(f"{path}: {'; '.join(problems)} (robot {robot.name}'s driven joints: {', '.join(robot.joint_names)})")


def _checked(path: str | os.PathLike[str], robot: Robot, times: np.ndarray, q: np.ndarray, where: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Times and targets validated (see the module docstring); a first keyframe after 0 held from 0.

    Returns:
        (times [s], shape (K,); targets [rad] clamped into the limits, shape (K, n)).
    """
    if len(times) < 2:
        raise FormatError(f"{path}: {len(times)} keyframe(s); a get-up needs at least two (the lying start and where it goes)")
    for k in range(len(times)):
        bad = [robot.joint_names[c] for c in np.flatnonzero(~np.isfinite(q[k]))]
        if not math.isfinite(times[k]) or bad:
            raise FormatError(f"{path}: {where[k]}: not a finite number: {'time' if not math.isfinite(times[k]) else ', '.join(bad)}")
    if times[0] < 0.0:
        raise FormatError(f"{path}: {where[0]}: time {times[0]:g} s; keyframe times start at 0 or later")
    step = np.diff(times)
    if np.any(step <= 0.0):
        k = int(np.flatnonzero(step <= 0.0)[0]) + 1
        raise FormatError(f"{path}: {where[k]}: time {times[k]:g} s after {times[k - 1]:g} s; times must increase strictly")
    if times[-1] > MAX_TRAJECTORY_S:
        raise FormatError(f"{path}: lasts {times[-1]:g} s; a get-up lasts at most {MAX_TRAJECTORY_S:g} s")
    inside = np.clip(q, robot.joint_lower, robot.joint_upper)
    excess = np.abs(inside - q)
    if excess.max(initial=0.0) > LIMIT_CLAMP_TOLERANCE_RAD:
        k, c = np.unravel_index(int(np.argmax(excess)), excess.shape)
        j = robot.joint_names[c]
        raise FormatError(f"{path}: {where[k]}: {j} = {q[k, c]:.4f} rad lies past its limits "
                          f"[{robot.joint_lower[c]:.4f}, {robot.joint_upper[c]:.4f}] rad",
                          hint=f"up to {LIMIT_CLAMP_TOLERANCE_RAD * 1e3:.2f} mrad past a limit is clamped; angles in degrees need --degrees")
    if times[0] > 0.0:
        times, inside = np.concatenate([[0.0], times]), np.vstack([inside[:1], inside])
    return times, inside
