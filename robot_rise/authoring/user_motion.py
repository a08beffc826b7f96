"""A user's own get-up added to a robot's library (``robot-rise library add``), proven like ours.

The keyframes (:mod:`robot_rise.keyframe_import`: a CSV or MuJoCo keyframes) become a trajectory
of their targets from a lying start: the MuJoCo file's first key where it gives the root, else
the first keyframe settled on flat ground lying as asked (:func:`robot_rise.authoring.lying.settle`,
clamped into the limits, as :func:`~robot_rise.authoring.write.settled_start` settles a strategy's).
It is then proven by the library's own trial, :func:`~robot_rise.authoring.write.prove_for_library`
(standing on the five robustness players within ``TORQUE_BOUND``, then the ensemble proof and seal
of :func:`~robot_rise.authoring.write.with_proof`), its timing kept as the user wrote it. Only a
proven motion is written (:func:`~robot_rise.authoring.write.write_motion`, then its index row,
each file atomically, the index last), unless ``unproven``: then it is written with its reason and
``proven: false`` and no seal, so ``execute`` and ``getup`` refuse it and ``library prove`` can
prove it later. A motion that is not proven is a status (:class:`AddResult`), not an exception.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robot_rise.authoring.lying import settle
from robot_rise.authoring.robustness import robustness_players
from robot_rise.authoring.write import PROOF_SCENE, prove_for_library, write_motion
from robot_rise.errors import ConfigError, FormatError
from robot_rise.fileio import write_text_atomic
from robot_rise.keyframe_import import ImportedKeyframes
from robot_rise.library import LIBRARY_FORMAT, LYING_KINDS
from robot_rise.model import Robot
from robot_rise.posture import clamp_to_limits
from robot_rise.sampling import classify_lying
from robot_rise.seal import sealed
from robot_rise.trajectory import Trajectory

__all__ = ["AddResult", "add_motion", "imported_trajectory"]

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")


@dataclass(frozen=True)
class AddResult:
    """What :func:`add_motion` did.

    Attributes:
        name: the motion.
        directory: the library directory.
        lying: its lying kind.
        proven: it stood on the robustness players and its ensemble proof says proven.
        reason: why not ('' when proven).
        written: its files and index row were written.
        row: its index row (written or, when not written, as it would have been).
        duration_s: its duration as proven (conformed to the command limits) [s].
    """

    name: str
    directory: Path
    lying: str
    proven: bool
    reason: str
    written: bool
    row: dict = field(default_factory=dict)
    duration_s: float = 0.0


def imported_trajectory(robot: Robot, keys: ImportedKeyframes, lying: str | None, *, report: dict | None = None) -> tuple[Trajectory, str]:
    """The keyframes as a trajectory from their lying start, and that lying kind.

    Args:
        robot: the robot.
        keys: the keyframes read.
        lying: ``supine``, ``prone``, ``left`` or ``right``; None: the file's root says (MuJoCo
            keyframes with a free joint only).
        report: entries for the trajectory's report.

    Raises:
        ConfigError: no lying kind for a file without a root, an unknown one, or a start that lies
            another way than asked.
        PostureError: the settled start rests further than the clamp tolerance past a limit.
    """
    if lying is not None and lying not in LYING_KINDS:
        raise ConfigError(f"lying kind {lying!r}; expected one of {', '.join(LYING_KINDS)}")
    start = keys.start_posture()
    if start is None:
        if lying is None:
            raise ConfigError(f"{keys.source}: the file gives no root pose: pass --lying {'|'.join(LYING_KINDS)} for its first keyframe to be settled on the floor")
        start = clamp_to_limits(settle(robot, lying, keys.first_joints()), robot, where=f"{keys.source}: settled start")[0]
    kind = classify_lying(start.root_quat_wxyz)
    if lying is not None and kind != lying:
        how = "settles" if keys.root_pose is None else "lies"
        raise ConfigError(f"{keys.source}: its first keyframe {how} {kind}, not {lying}", hint=f"pass --lying {kind}" if kind in LYING_KINDS else "")
    if kind not in LYING_KINDS:
        raise ConfigError(f"{keys.source}: its first keyframe is {kind}, not lying: a get-up starts lying ({', '.join(LYING_KINDS)})")
    return keys.trajectory(start, report=report), kind


def add_motion(directory: str | Path, robot: Robot, keys: ImportedKeyframes, *, name: str, lying: str | None = None,
               strategy: str = "", connect_until_s: float | None = None, unproven: bool = False) -> AddResult:
    """Prove a user's keyframes as a library motion and write it (see the module docstring).

    Args:
        directory: the library directory (created with its index if missing).
        robot: the robot.
        keys: the keyframes (:func:`robot_rise.keyframe_import.read_keyframes`).
        name: the motion's name (its file stem); not yet in the library.
        lying: its lying kind (see :func:`imported_trajectory`).
        strategy: one line for people (default: where it came from).
        connect_until_s: end of its lying-to-sitting/squatting phase [s], as the user's times
            (default: the last row before the simulated body's head axis comes within 60 degrees
            of vertical, :func:`robot_rise.sampling.classify_lying`).
        unproven: write it even when not proven (``proven: false``, no seal).

    Returns:
        the :class:`AddResult`; not proven is a status there.

    Raises:
        ConfigError: a bad name or one already in the library, another robot's library, a bad
            ``connect_until_s``, or as :func:`imported_trajectory`.
        FormatError: the library index is malformed.
    """
    directory = Path(directory)
    if not _NAME.fullmatch(name):
        raise ConfigError(f"motion name {name!r}: letters, digits, '_', '-' and '.' only, starting with a letter or digit")
    index_path = directory / "index.json"
    index = _read_index(index_path, robot)
    if name in {str(r.get("name")) for r in index["motions"]}:
        raise ConfigError(f"{index_path}: the library has a motion {name!r} already", hint="pick another --name")
    source = Path(keys.source).name
    extra = {"strategy": strategy or f"imported from {source}", "imported_from": {"file": source, "format": keys.format},
             "keyframe_times_s": [float(t) for t in keys.time_s]}
    tr, kind = imported_trajectory(robot, keys, lying, report=extra)
    extra["lying"] = kind
    if connect_until_s is not None and not 0.0 < connect_until_s <= tr.duration_s:
        raise ConfigError(f"--connect-until {connect_until_s:g} s must lie in (0, {tr.duration_s:g}] s, the motion's duration")
    players = robustness_players(robot)
    got = prove_for_library(robot, tr, tr.start, players, clamp_lead=False,
                            connect_until_s=tr.duration_s if connect_until_s is None else connect_until_s, report=extra)
    if isinstance(got, str):
        reason = got
        if not unproven:
            return AddResult(name, directory, kind, False, reason, False, _row(name, kind, extra["strategy"], tr, connect_until_s), tr.duration_s)
        tr = _unproven(robot, tr, players, reason)
    else:
        reason = ""
        tr = got[0]
    if connect_until_s is None:
        tr = tr.with_report(connect_until_s=_lying_until_s(tr))  # not a sealed entry (as prove_for_library sets it)
    row = _row(name, kind, extra["strategy"], tr, float(tr.report["connect_until_s"]))
    directory.mkdir(parents=True, exist_ok=True)
    write_motion(directory, name, tr, tr.start)
    index["motions"].append(row)
    write_text_atomic(index_path, json.dumps(index, indent=1) + "\n")
    return AddResult(name, directory, kind, not reason, reason, True, row, tr.duration_s)


def _read_index(path: Path, robot: Robot) -> dict:
    """The library's index as JSON (a new one when there is none), for this robot."""
    if not path.exists():
        return {"format": LIBRARY_FORMAT, "robot": robot.name, "motions": []}
    try:
        index = json.loads(path.read_text())
    except ValueError as e:
        raise FormatError(f"{path}: not JSON ({e})") from None
    if not isinstance(index, dict) or index.get("format") != LIBRARY_FORMAT or not isinstance(index.get("motions"), list):
        raise FormatError(f"{path}: not a motion library index (format {LIBRARY_FORMAT!r} with a 'motions' list)")
    if index.get("robot", robot.name) != robot.name:
        raise ConfigError(f"{path}: the library of robot {index['robot']!r}, not {robot.name!r}", hint="pass --robot DIR of its robot, or another --dir")
    return index


def _row(name: str, lying: str, strategy: str, tr: Trajectory, connect_until_s: float | None) -> dict:
    return {"name": name, "lying": lying, "strategy": strategy, "trajectory": f"{name}.json", "start": f"{name}.start.json",
            "connect_until_s": None if connect_until_s is None else round(connect_until_s, 6), "duration_s": round(tr.duration_s, 3)}


def _unproven(robot: Robot, tr: Trajectory, players: list, reason: str) -> Trajectory:
    """``tr`` as written when not proven: the nominal play's root per row, ``proven: false`` and
    the reason in its report, no seal (execute, getup and the loader's seal check refuse it)."""
    rec = players[0].play(tr)
    t = np.concatenate([[0.0], rec.t])
    start_pose = np.concatenate([tr.start.root_pos, tr.start.root_quat_wxyz])
    root = np.stack([np.interp(tr.t, t, np.concatenate([[start_pose[i]], rec.root_pose[:, i]])) for i in range(7)], axis=-1)
    root[:, 3:] /= np.linalg.norm(root[:, 3:], axis=1, keepdims=True)
    report = {**tr.report, "proven": False, "problems": [reason], "robot": robot.name, "robot_digest": robot.digest(),
              "scene": PROOF_SCENE, "duration_s": tr.duration_s}
    return sealed(Trajectory(tr.robot, tr.joint_names, tr.t, tr.q, tr.start, report, root))


def _lying_until_s(tr: Trajectory) -> float:
    """The last row's time before the simulated root is upright (head axis within 60 degrees of
    vertical); the motion's end if it never is (a motion that stands is upright at its end)."""
    if tr.root is None:
        return tr.duration_s
    upright = next((k for k in range(1, len(tr.t)) if classify_lying(tr.root[k, 3:]) == "upright"), None)
    if upright is None:
        return tr.duration_s
    return round(float(tr.t[max(upright - 1, 1)]), 6)  # after 0: the index needs a phase
