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

from robot_rise.trajectory import Trajectory, trajectory_to_dict

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


def seal_of(trajectory: Trajectory) -> str:
    """The SHA-256 (hex) of the targets, root, joint order, start and proof entries, as written to file."""
    written = trajectory_to_dict(trajectory)
    judged = {
        "seal_format": SEAL_FORMAT,
        **{k: written.get(k) for k in ("format", "robot", "joint_names", "t", "q", "root", "start")},
        "report": {k: written["report"][k] for k in SEALED_REPORT_KEYS if k in written["report"]},
    }
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
