"""The seal of a proven trajectory: one digest of exactly what its proof judged, computed here only.

A proof vouches for particular targets: these times, these rows, this root, this joint order and
start, on this robot and scene (their digests), under this standard (envelope, ensemble,
command limits, the positions the executor should see). The seal is the SHA-256 of all of it as
the trajectory file writes it (times and angles to 6 decimals, so a file read back seals the
same), stored in the report (``report.seal``) by what proves (``rise``, ``library build`` /
``prove``). ``execute``, ``getup`` and the library loader recompute it and refuse a trajectory
whose seal is missing or differs: a target changed by 1 mrad, ``command_limits`` removed, joints
reordered or ``proven`` set by hand all change what the proof would have had to judge.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np

from robot_rise.posture import posture_to_dict
from robot_rise.trajectory import TRAJECTORY_FORMAT, Trajectory, jsonable, rounded_as_written

__all__ = ["SEAL_KEY", "SEAL_FORMAT", "SEALED_REPORT_KEYS", "seal_of", "sealed", "seal_problem"]

SEAL_KEY = "seal"
SEAL_FORMAT = "robot-rise/seal@1"
# the report's entries a proof stands on: its verdict, what it was proven on, the standard
SEALED_REPORT_KEYS = (
    "proven",
    "problems",
    "robot",
    "robot_digest",
    "scene",
    "scene_digest",
    "standing",
    "judge",
    "duration_s",
    "peak_torque_ratio",
    "envelope_limit",
    "ensemble",
    "noise_check",
    "combined_variants",
    "command_limits",
    "predicted",
)


def _plain(x: Any) -> Any:
    """json.dumps's fallback for numpy values in an in-memory report (as the file writes them)."""
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    raise TypeError(f"{type(x).__name__} is not a report value")


def seal_of(trajectory: Trajectory) -> str:
    """The SHA-256 (hex) of the targets, root, joint order, start and proof entries, as written to file."""
    tr = trajectory
    report = {k: tr.report[k] for k in SEALED_REPORT_KEYS if k in tr.report}
    judged = {
        "seal_format": SEAL_FORMAT,
        "format": TRAJECTORY_FORMAT,
        "robot": tr.robot,
        "joint_names": list(tr.joint_names),
        "t": rounded_as_written(tr.t),
        "q": rounded_as_written(tr.q),
        "root": None if tr.root is None else rounded_as_written(tr.root),
        "start": posture_to_dict(tr.start),
        "report": report,
    }
    try:  # the report's plain JSON values dump fast; NaN and infinity are written as null, as the file does
        text = json.dumps(judged, sort_keys=True, separators=(",", ":"), allow_nan=False, default=_plain)
    except ValueError:
        judged["report"] = jsonable(report)
        text = json.dumps(judged, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def sealed(trajectory: Trajectory) -> Trajectory:
    """``trajectory`` with its seal in the report (for what has just been proven; an unproven one's seal is removed)."""
    report = {k: v for k, v in trajectory.report.items() if k != SEAL_KEY}
    bare = Trajectory(trajectory.robot, trajectory.joint_names, trajectory.t, trajectory.q, trajectory.start, report, trajectory.root)
    if report.get("proven") is not True:
        return bare
    return bare.with_report(**{SEAL_KEY: seal_of(bare)})


def seal_problem(trajectory: Trajectory) -> str:
    """Why ``trajectory`` is not what its proof judged ('' when its seal holds)."""
    seal = trajectory.report.get(SEAL_KEY)
    if seal is None:
        return "its report carries no seal of what its proof judged (changed by hand, or proven by an older robot_rise: prove it again)"
    if seal != seal_of(trajectory):
        return "its targets or proof entries changed after the proof (report.seal does not match what was judged)"
    return ""
