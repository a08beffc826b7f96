"""Writing the library: each motion settled, timed, verified on the robustness grid, and only then written with its index row.

A motion is written only after it stands on all five players of
:func:`robot_rise.authoring.robustness.robustness_players` within ``TORQUE_BOUND`` of the
envelope and without self collision; its index row is added or replaced, so the index always
names motions that pass. The file's ``report`` holds the judge's verdict, the peak torque ratio
(nominal and over the corners), ZMP margin and keyframe times; the simulated root pose is written
as ``root`` (needed by connecting-posture selection). Files are written atomically (a temporary
file renamed over the old one), so an interrupted run never leaves a half-written motion.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from robot_rise.authoring.goal_lead import clamp_goal_lead
from robot_rise.authoring.keyframes import build_trajectory
from robot_rise.authoring.lying import settle
from robot_rise.authoring.op3_motions import MOTION_SPECS
from robot_rise.authoring.retiming import RETIME_RATIO_TARGET, retime, speed_prescale, subdivide
from robot_rise.authoring.robustness import TORQUE_BOUND, robustness_players
from robot_rise.library import LIBRARY_FORMAT
from robot_rise.model import Robot, load_robot
from robot_rise.posture import write_posture
from robot_rise.sampling import classify_lying
from robot_rise.sim.standing import judge
from robot_rise.trajectory import Trajectory, write_trajectory

__all__ = ["author_library"]

log = logging.getLogger(__name__)


def _write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file renamed over it (readers never see half a file)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)


def author_library(out_dir: Path, robot: Robot | None = None, *, names: list[str] | None = None) -> list[dict]:
    """Settle, retime, play and judge motions; write the passing ones and merge them into the index.

    A motion is written (and its index row added or replaced) only if it stands, within
    ``TORQUE_BOUND`` of the envelope and without self collision, nominally and at the four
    friction/mass corners; a failing motion is logged and leaves the files and the index as they
    were, so ``index.json`` always names motions that pass. Rows of motions no longer in
    ``MOTION_SPECS`` are dropped when the whole library is rebuilt (``names`` None).

    Args:
        out_dir: the library directory (created if missing), e.g. ``configs/motions/op3``.
        robot: the robot (default: the embedded OP3-class robot, whose joints the motions name).
        names: the motions to rebuild, their rows replaced or added and the others kept; None or
            empty: every motion of ``MOTION_SPECS`` (only None drops stale rows).

    Returns:
        the index rows of the motions written by this call, in ``MOTION_SPECS`` order.
    """
    robot = robot or load_robot()
    out_dir.mkdir(parents=True, exist_ok=True)
    players = robustness_players(robot)
    player = players[0]
    index_path = out_dir / "index.json"
    old_rows: dict[str, dict] = {}
    if index_path.exists():
        try:
            old_rows = {r["name"]: r for r in json.loads(index_path.read_text()).get("motions", [])}
        except (ValueError, KeyError):
            old_rows = {}
    entries = []
    for spec in MOTION_SPECS:
        if names and spec.name not in names:
            continue
        start = settle(robot, spec.lying, spec.lying_joints, yaw_rad=spec.lying_yaw_rad)
        kind = classify_lying(start.root_quat_wxyz)
        if kind != spec.lying:
            log.error("%s: start posture settled %s, not %s: not written", spec.name, kind, spec.lying)
            continue
        if spec.retime:
            fine, where = subdivide(robot, start, speed_prescale(robot, start, spec.keyframes))
            kfs = retime(robot, start, fine, players, ratio_target=RETIME_RATIO_TARGET)
            connect_until_s = kfs[where[spec.connect_keyframe]].t_s
        else:
            kfs = spec.keyframes
            connect_until_s = kfs[spec.connect_keyframe].t_s
        tr = build_trajectory(robot, start, kfs)
        if spec.clamp_lead:
            tr = clamp_goal_lead(robot, tr, players)
        verdicts = [judge(p.play(tr)) for p in players]
        bad = [f"{i}: {v.summary()}" for i, v in enumerate(verdicts) if not v.standing or v.self_collision or v.peak_envelope_ratio > TORQUE_BOUND]
        if bad:
            log.error("%s (%.2f s) fails, not written: %s", spec.name, tr.duration_s, "; ".join(bad))
            continue
        rec = player.play(tr)
        v = judge(rec)
        # simulated root pose at every row (rows at ROW_HZ, recording at 100 Hz: interpolate)
        root = np.stack([np.interp(tr.t, np.concatenate([[0.0], rec.t]), np.concatenate([[start.root_pos[i] if i < 3 else start.root_quat_wxyz[i - 3]], rec.root_pose[:, i]])) for i in range(7)], axis=-1)
        root[:, 3:] /= np.linalg.norm(root[:, 3:], axis=1, keepdims=True)
        report = {
            "strategy": spec.strategy,
            "lying": spec.lying,
            "duration_s": tr.duration_s,
            "standing": v.standing,
            "verdict": v.summary(),
            "peak_envelope_ratio": v.peak_envelope_ratio,
            "peak_envelope_ratio_corners": max(x.peak_envelope_ratio for x in verdicts),
            "min_zmp_margin_m": v.min_zmp_margin_m,
            "self_collision": v.self_collision,
            "connect_until_s": connect_until_s,
            "keyframe_times_s": [k.t_s for k in kfs],
            "robot_digest": robot.digest(),
        }
        tr = Trajectory(tr.robot, tr.joint_names, tr.t, tr.q, tr.start, report, root)
        tmp_dir = out_dir / ".authoring"
        tmp_dir.mkdir(exist_ok=True)
        write_trajectory(tmp_dir / f"{spec.name}.json", tr)
        write_posture(tmp_dir / f"{spec.name}.start.json", start)
        (tmp_dir / f"{spec.name}.start.json").replace(out_dir / f"{spec.name}.start.json")
        (tmp_dir / f"{spec.name}.json").replace(out_dir / f"{spec.name}.json")
        tmp_dir.rmdir()
        log.info("%s: %.2f s; %s (corners: peak %.2f)", spec.name, tr.duration_s, v.summary(), report["peak_envelope_ratio_corners"])
        row = {
            "name": spec.name,
            "lying": spec.lying,
            "strategy": spec.strategy,
            "trajectory": f"{spec.name}.json",
            "start": f"{spec.name}.start.json",
            "connect_until_s": connect_until_s,
            "duration_s": round(tr.duration_s, 3),
        }
        entries.append(row)
        old_rows[spec.name] = row
        order = [s.name for s in MOTION_SPECS]
        keep = [n for n in order if n in old_rows] + [n for n in old_rows if n not in order]
        index = {"format": LIBRARY_FORMAT, "robot": robot.name, "motions": [old_rows[n] for n in keep]}
        _write_atomic(index_path, json.dumps(index, indent=1) + "\n")
    if names is None:  # a full rebuild drops rows of motions no longer authored (failed ones keep their last passing files)
        order = [s.name for s in MOTION_SPECS]
        index = {"format": LIBRARY_FORMAT, "robot": robot.name, "motions": [old_rows[n] for n in order if n in old_rows]}
        _write_atomic(index_path, json.dumps(index, indent=1) + "\n")
    return entries
