"""Authoring of the OP3 get-up motion library: keyframes in code, trajectories regenerated from them.

Run ``python -m robot_rise.library_authoring [--out configs/motions/op3]`` to rewrite every motion
file, its start posture and the index. Each motion is a list of keyframes (time [s], joint goals);
the rows of the trajectory file are the keyframes joined by minimum-jerk blends sampled at
``ROW_HZ``. The start posture is found by dropping the robot in the motion's lying posture onto flat
ground with the servos holding it and letting it settle; the first row is the settled joint angles
(no goal jump at t = 0). Each motion is then played through the servo model (robot_rise/sim.py)
and its judge verdict, peak torque ratio and ZMP margin go into the file's ``report``; the
simulated root pose is written as ``root`` (needed by connecting-posture selection).

Joint values are written for the left side; :func:`sym` mirrors them to the right side. In
robot.xml every right joint mirrors its left twin with the opposite sign (pitch axes are
mirrored, roll/yaw axes shared), so a symmetric posture has q_right = -q_left.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from scipy.interpolate import PchipInterpolator

from robot_rise.model import Robot, compose, load_robot, model_index
from robot_rise.library import LIBRARY_FORMAT
from robot_rise.paths import configs_dir
from robot_rise.posture import Posture, posture_from_qpos, write_posture
from robot_rise.trajectory import Trajectory, write_trajectory

__all__ = [
    "MotionSpec",
    "Keyframe",
    "sym",
    "quat_lying",
    "settle",
    "build_trajectory",
    "MOTION_SPECS",
    "author_library",
    "ROW_HZ",
    "retime",
]

log = logging.getLogger(__name__)

ROW_HZ = 100.0  # trajectory rows per second (the servo goal update rate) [Hz]
SETTLE_S = 1.5  # time a dropped lying posture is simulated to come to rest [s]
DROP_CLEARANCE_M = 0.004  # the lying posture is dropped from this far above the ground [m]
RETIME_RATIO_TARGET = 0.85  # peak torque/envelope after retiming, nominal and heavy corner (bound: 0.9)
ROBUST_FRICTION = (0.5, 1.0, 1.2)  # friction scales the library must stand with (issue 4)
ROBUST_MASS = (0.9, 1.0, 1.1)  # link mass scales the library must stand with (issue 4)

_SIDES = ("sho_pitch", "sho_roll", "el", "hip_yaw", "hip_roll", "hip_pitch", "knee", "ank_pitch", "ank_roll")


def sym(**left: float) -> dict[str, float]:
    """Joint goals for both sides from left-side values: ``sym(knee=1.0)`` -> l_knee 1, r_knee -1.

    Keys may also be full joint names (``l_knee``, ``r_el``, ``head_tilt``) for one side only.
    """
    out: dict[str, float] = {}
    for k, v in left.items():
        if k in _SIDES:
            out[f"l_{k}"] = float(v)
            out[f"r_{k}"] = -float(v)
        else:
            out[k] = float(v)
    return out


def quat_lying(kind: str, yaw_rad: float = 0.0) -> np.ndarray:
    """Root quaternion (w, x, y, z) of a lying robot: ``supine``, ``prone``, ``left`` or ``right`` side.

    Supine: the torso's front (+x) faces up, head towards -x. Prone: front down, head towards +x.
    Left: the left side (+y) down. Right: the right side down. Then a yaw about world z.
    """
    h = math.pi / 4
    base = {
        "supine": np.array([math.cos(-h), 0.0, math.sin(-h), 0.0]),  # -90 deg about y
        "prone": np.array([math.cos(h), 0.0, math.sin(h), 0.0]),  # +90 deg about y
        "left": np.array([math.cos(-h), math.sin(-h), 0.0, 0.0]),  # -90 deg about x: +y -> -z
        "right": np.array([math.cos(h), math.sin(h), 0.0, 0.0]),  # +90 deg about x: -y -> -z
    }
    if kind not in base:
        raise ValueError(f"unknown lying kind {kind!r}; known: {', '.join(base)}")
    yaw = np.array([math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2)])
    from robot_rise.posture import quat_multiply

    return quat_multiply(yaw, base[kind])


@dataclass(frozen=True)
class Keyframe:
    """Joint goals reached at time ``t_s`` [s]; joints not named keep the previous keyframe's goal."""

    t_s: float
    joints: Mapping[str, float]


@dataclass(frozen=True)
class MotionSpec:
    """One library motion as authored.

    Attributes:
        name: file stem and CLI name.
        lying: ``supine``, ``prone``, ``left`` or ``right``.
        strategy: one line for people.
        lying_joints: joint angles of the lying posture before settling [rad].
        keyframes: goals after t = 0, increasing in time.
        connect_keyframe: index into ``keyframes`` of the keyframe that ends the lying-to-sitting/
            squatting phase (its time, after retiming, is written as ``connect_until_s``).
    """

    name: str
    lying: str
    strategy: str
    lying_joints: Mapping[str, float]
    keyframes: tuple[Keyframe, ...]
    connect_keyframe: int
    lying_yaw_rad: float = 0.0


def settle(robot: Robot, lying: str, joints: Mapping[str, float], *, yaw_rad: float = 0.0, settle_s: float = SETTLE_S) -> Posture:
    """Drop the robot in a lying posture onto flat ground with the servos holding it; return the rest posture."""
    from robot_rise.validity import ValidityChecker

    q = np.array([joints.get(j, 0.0) for j in robot.joint_names])
    q = np.clip(q, robot.joint_lower, robot.joint_upper)
    quat = quat_lying(lying, yaw_rad)
    pose = Posture(robot.name, np.array([0.0, 0.0, 1.0]), quat, dict(zip(robot.joint_names, q)))
    checker = ValidityChecker(robot, "flat")
    qpos = checker.qpos_of(pose)
    low = checker.lowest_point_z(qpos)
    pose = pose.with_root(root_pos=np.array([0.0, 0.0, 1.0 - low + DROP_CLEARANCE_M]))
    m = compose(robot, "flat")
    d = mujoco.MjData(m)
    idx = model_index(m, robot)
    d.qpos[:] = pose.qpos(robot, idx, m.qpos0)
    d.ctrl[idx.actuators] = q
    for _ in range(int(round(settle_s / m.opt.timestep))):
        mujoco.mj_step(m, d)
    d.qpos[idx.qpos_root[:2]] = 0.0  # back over the origin (x, y only)
    return posture_from_qpos(robot, idx, d.qpos)


def _min_jerk(s: np.ndarray) -> np.ndarray:
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def build_trajectory(robot: Robot, start: Posture, keyframes: tuple[Keyframe, ...], *, row_hz: float = ROW_HZ) -> Trajectory:
    """Join the start joints and the keyframes with minimum-jerk blends, sampled at ``row_hz``.

    Returns:
        a Trajectory with rows every 1 / row_hz seconds (plus the final keyframe time).
    """
    names = robot.joint_names
    q0 = start.joint_vector(names)
    times = [0.0]
    goals = [q0]
    for kf in keyframes:
        if kf.t_s <= times[-1]:
            raise ValueError(f"keyframe times must increase: {kf.t_s} after {times[-1]}")
        unknown = set(kf.joints) - set(names)
        if unknown:
            raise ValueError(f"unknown joints {sorted(unknown)}")
        g = goals[-1].copy()
        for j, v in kf.joints.items():
            g[names.index(j)] = v
        goals.append(np.clip(g, robot.joint_lower, robot.joint_upper))
        times.append(kf.t_s)
    T = times[-1]
    t = np.arange(0.0, T, 1.0 / row_hz)
    t = np.append(t[t < T - 1e-9], T)
    # Shape-preserving cubic through the keyframes: no overshoot past a keyframe (so no joint
    # limit is crossed), velocity continuous, zero at the start and end.
    g = np.array(goals)
    q = PchipInterpolator(np.array(times), g, axis=0)(t)
    q = np.clip(q, robot.joint_lower, robot.joint_upper)
    return Trajectory(robot.name, names, t, q, start)


def retime(
    robot: Robot,
    start: Posture,
    keyframes: tuple[Keyframe, ...],
    players: object,
    *,
    ratio_target: float = 0.85,
    stretch: float = 1.15,
    max_iter: int = 25,
) -> tuple[Keyframe, ...]:
    """Stretch the keyframe segments in which the servos leave ``ratio_target`` of their envelope.

    A simple optimisation in MuJoCo: play, find each segment's peak torque / envelope ratio
    (including the 0.2 s after it, where a late tracking error shows), multiply the duration of
    every offending segment by ``stretch``, repeat. Segments within the target keep their
    duration, so the motion stays as fast as the servos allow.

    Args:
        players: :class:`robot_rise.sim.Player` objects on flat ground (e.g. nominal and the
            heaviest / highest-friction variant); the peak is taken over all of them.

    Returns:
        keyframes with new times (same goals).
    """
    kfs = tuple(keyframes)
    for it in range(max_iter):
        tr = build_trajectory(robot, start, kfs)
        times = np.array([0.0] + [k.t_s for k in kfs])
        seg_peak = np.zeros(len(kfs))
        for player in players if isinstance(players, (list, tuple)) else [players]:
            rec = player.play(tr, hold_s=0.5)  # type: ignore[attr-defined]
            peak_ratio = rec.envelope_ratio.max(axis=1)
            for i in range(len(kfs)):
                sel = (rec.t > times[i]) & (rec.t <= times[i + 1] + 0.2)
                if sel.any():
                    seg_peak[i] = max(seg_peak[i], float(peak_ratio[sel].max()))
        bad = seg_peak > ratio_target
        if not bad.any():
            log.info("retime: converged after %d iterations, duration %.2f s", it, times[-1])
            return kfs
        durations = np.diff(times)
        durations[bad] *= stretch
        new_t = np.cumsum(durations)
        kfs = tuple(Keyframe(float(round(t, 3)), k.joints) for t, k in zip(new_t, kfs))
    log.warning("retime: still above %.2f after %d iterations", ratio_target, max_iter)
    return kfs


# --- the motions ------------------------------------------------------------------------------

_STAND = sym(sho_pitch=0.0, sho_roll=1.25, el=0.0, hip_yaw=0.0, hip_roll=0.0, hip_pitch=-0.35, knee=0.7, ank_pitch=0.35, ank_roll=0.0) | {
    "head_pan": 0.0,
    "head_tilt": 0.0,
}
_LIE_FLAT = sym(sho_pitch=0.0, sho_roll=1.3, el=0.0, hip_pitch=0.0, knee=0.05, ank_pitch=0.0) | {"head_pan": 0.0, "head_tilt": 0.0}

_T_ARMS = sym(sho_pitch=-1.57, sho_roll=0.15)  # arms out sideways, turned so sho_roll pushes them down
_ALL_FOURS = sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0, hip_pitch=-1.7, knee=2.5, ank_pitch=0.6)
_SQUAT_HANDS = sym(sho_pitch=-0.8, sho_roll=1.3, el=0.0, hip_pitch=-1.7, knee=2.6, ank_pitch=1.3)
_SQUAT = sym(sho_pitch=0.0, sho_roll=1.3, el=0.0, hip_pitch=-1.7, knee=2.4, ank_pitch=1.2)


def _prone_tail(t0: float) -> tuple[Keyframe, ...]:
    """Push-up -> all fours -> squat -> stand, starting at ``t0`` from prone with T arms."""
    return (
        Keyframe(t0 + 0.6, sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0)),
        Keyframe(t0 + 1.2, _ALL_FOURS),
        Keyframe(t0 + 1.7, _SQUAT_HANDS),
        Keyframe(t0 + 2.0, _SQUAT),
        Keyframe(t0 + 2.7, _STAND),
    )


MOTION_SPECS: list[MotionSpec] = [
    MotionSpec(
        name="prone_pushup_squat",
        lying="prone",
        strategy="prone, arms out: lateral push-up, legs folded under to all fours, push back onto the feet, squat, stand",
        lying_joints=_LIE_FLAT | _T_ARMS,
        keyframes=_prone_tail(0.0),
        connect_keyframe=2,
    ),
    MotionSpec(
        name="prone_knees_first",
        lying="prone",
        strategy="prone, arms out: knees pulled under first, then the push-up onto all fours, push back onto the feet, squat, stand",
        lying_joints=_LIE_FLAT | _T_ARMS,
        keyframes=(
            Keyframe(0.5, _T_ARMS | sym(hip_pitch=-1.2, knee=2.0, ank_pitch=0.3)),
            Keyframe(1.1, sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0, hip_pitch=-1.5, knee=2.4, ank_pitch=0.5)),
            Keyframe(1.6, _ALL_FOURS),
            Keyframe(2.1, _SQUAT_HANDS),
            Keyframe(2.4, _SQUAT),
            Keyframe(3.1, _STAND),
        ),
        connect_keyframe=3,
    ),
    MotionSpec(
        name="prone_elbow_pushup",
        lying="prone",
        strategy="prone, arms out: forearms pushed down at the elbows first (short lever), then the shoulders, all fours, squat, stand",
        lying_joints=_LIE_FLAT | _T_ARMS,
        keyframes=(
            Keyframe(0.4, sym(sho_pitch=-1.57, sho_roll=0.15, el=-1.4)),
            Keyframe(0.9, sym(sho_pitch=-1.57, sho_roll=0.9, el=-0.6)),
            Keyframe(1.3, sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0)),
            Keyframe(1.9, _ALL_FOURS),
            Keyframe(2.4, _SQUAT_HANDS),
            Keyframe(2.7, _SQUAT),
            Keyframe(3.4, _STAND),
        ),
        connect_keyframe=4,
    ),
]


def author_library(out_dir: Path, robot: Robot | None = None, *, names: list[str] | None = None) -> list[dict]:
    """Settle, build, play and judge every motion; write the files and the index into ``out_dir``."""
    from robot_rise.judge import judge
    from robot_rise.sim import Player

    robot = robot or load_robot()
    out_dir.mkdir(parents=True, exist_ok=True)
    player = Player(robot, "flat")
    # the worst corner of the robustness grid for torque: heaviest links, highest friction
    heavy = Player(robot, "flat", friction_scale=ROBUST_FRICTION[-1], mass_scale=ROBUST_MASS[-1])
    entries = []
    for spec in MOTION_SPECS:
        if names and spec.name not in names:
            continue
        start = settle(robot, spec.lying, spec.lying_joints, yaw_rad=spec.lying_yaw_rad)
        kfs = retime(robot, start, spec.keyframes, [player, heavy], ratio_target=RETIME_RATIO_TARGET)
        connect_until_s = kfs[spec.connect_keyframe].t_s
        tr = build_trajectory(robot, start, kfs)
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
            "min_zmp_margin_m": v.min_zmp_margin_m,
            "self_collision": v.self_collision,
            "connect_until_s": connect_until_s,
            "keyframe_times_s": [k.t_s for k in kfs],
            "robot_digest": robot.digest(),
        }
        tr = Trajectory(tr.robot, tr.joint_names, tr.t, tr.q, tr.start, report, root)
        write_trajectory(out_dir / f"{spec.name}.json", tr)
        write_posture(out_dir / f"{spec.name}.start.json", start)
        log.info("%s: %s", spec.name, v.summary())
        entries.append(
            {
                "name": spec.name,
                "lying": spec.lying,
                "strategy": spec.strategy,
                "trajectory": f"{spec.name}.json",
                "start": f"{spec.name}.start.json",
                "connect_until_s": connect_until_s,
                "duration_s": round(tr.duration_s, 3),
            }
        )
    if names is None:
        index = {"format": LIBRARY_FORMAT, "robot": robot.name, "motions": entries}
        (out_dir / "index.json").write_text(json.dumps(index, indent=1) + "\n")
    return entries


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=configs_dir() / "motions" / "op3")
    parser.add_argument("--only", nargs="*", help="motion names to rebuild (index not rewritten)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    entries = author_library(args.out, names=args.only)
    return 0 if entries else 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
