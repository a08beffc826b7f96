"""Start proofs kept on disk: a library motion proven from rest once per robot, scene, library and code.

A :class:`robot_rise.proof.composed.StartProof` costs 3-5 s of CPU per motion (every variant
replays the motion, plus the noisy and spread replays), so a process that composes proofs (the
guard, ``rise --composed``, batch workers) started 45 s late. Each is kept in one JSON file
(``format`` ``robot-rise/start-proof@1``) named by a SHA-256 key over everything it rests on: the
robot's files (``Robot.digest``), the scene file, the motion's rows and start, the filter's
configuration, the variants, the MuJoCo and NumPy versions and the source of the ``robot_rise``
package (so a code change proves again; stale proofs are never read, only left behind: delete the
directory to reclaim them).

Where: ``$ROBOT_RISE_CACHE`` if set (``off`` turns the cache off), else
``$XDG_CACHE_HOME/robot_rise``, else ``~/.cache/robot_rise``. Files are written whole (a process
killed mid-write leaves at most its own ``*.tmp`` file, never half a proof); a file that does not read is proven again and replaced; a cache
that cannot be written is warned about once and then done without.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import logging
import os
from pathlib import Path

import mujoco
import numpy as np

from robot_rise.fileio import write_text_atomic
from robot_rise.proof.composed import StartProof
from robot_rise.proof.config import ProofConfig
from robot_rise.proof.verdict import scene_digest
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.sim.variants import ENSEMBLE
from robot_rise.trajectory import Trajectory

__all__ = ["START_PROOF_FORMAT", "CACHE_ENV", "cache_directory", "start_proof_key", "load_start_proof", "save_start_proof"]

log = logging.getLogger(__name__)

START_PROOF_FORMAT = "robot-rise/start-proof@1"
CACHE_ENV = "ROBOT_RISE_CACHE"
_warned = False


def cache_directory() -> Path | None:
    """Where start proofs are kept (None: the cache is off)."""
    value = os.environ.get(CACHE_ENV)
    if value is not None:
        return None if value.strip().lower() in ("", "off", "0", "no") else Path(value).expanduser().resolve() / "start_proofs"
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "robot_rise" / "start_proofs"


@functools.lru_cache(maxsize=1)
def _source_digest() -> str:
    """SHA-256 over the package's Python source (relative path and bytes of each file)."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def start_proof_key(robot: Robot, scene: str | os.PathLike[str] | None, motion: str, motion_trajectory: Trajectory,
                    start: Posture, config: ProofConfig) -> str:
    """The SHA-256 key of a start proof (see the module docstring) of ``motion`` played from ``start``."""
    h = hashlib.sha256()
    for part in (START_PROOF_FORMAT, robot.digest(), scene_digest(scene), motion, repr(dataclasses.astuple(config)),
                 repr([v.to_dict() for v in ENSEMBLE]), mujoco.__version__, np.__version__, _source_digest()):
        h.update(part.encode())
        h.update(b"\0")
    for array in (motion_trajectory.t, motion_trajectory.q, start.root_pos, start.root_quat_wxyz,
                  np.array([start.joints[j] for j in sorted(start.joints)])):
        h.update(np.ascontiguousarray(array, dtype=float).tobytes())
    h.update(repr(tuple(motion_trajectory.joint_names)).encode())
    return h.hexdigest()


def _path(key: str, directory: Path | None) -> Path | None:
    directory = directory if directory is not None else cache_directory()
    return None if directory is None else directory / f"{key}.json"


def load_start_proof(key: str, *, directory: Path | None = None) -> StartProof | None:
    """The start proof kept under ``key`` (None: none, the cache is off, or the file does not read)."""
    path = _path(key, directory)
    if path is None:
        return None
    try:
        if not path.is_file():
            return None
        obj = json.loads(path.read_text())
        if obj.get("format") != START_PROOF_FORMAT or obj.get("key") != key:
            raise ValueError("another format or key")
        return StartProof.from_dict(obj["start_proof"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
        log.warning("start proof cache: %s does not read (%s); proving again", path, e)
        return None


def save_start_proof(key: str, proof: StartProof, *, directory: Path | None = None) -> None:
    """Keep ``proof`` under ``key`` (a cache that cannot be written is warned about once)."""
    global _warned
    path = _path(key, directory)
    if path is None:
        return
    try:
        write_text_atomic(path, json.dumps({"format": START_PROOF_FORMAT, "key": key, "start_proof": proof.to_dict()}))
    except OSError as e:
        if not _warned:
            log.warning("start proof cache: cannot write %s (%s); going on without it", path.parent, e)
            _warned = True
