"""Authoring of the OP3 get-up motion library: keyframes in code, trajectories regenerated from them.

Run ``python -m robot_rise.library_authoring [--out configs/motions/op3] [--only NAME ...]`` to
rebuild the motions. Each motion is a list of keyframes (time [s], joint goals); the rows of the
trajectory file are the keyframes joined by a shape-preserving cubic (PCHIP) sampled at ``ROW_HZ``.
The start posture is found by dropping the robot in the motion's lying posture onto flat ground
with the servos holding it and letting it settle (it must still lie as the motion says:
``robot_rise.sampling.classify_lying``); the first row is the settled joint angles (no goal jump).

Timing is found in MuJoCo, not written by hand (the keyframe times below are only a shape):

1. :func:`speed_prescale` -- kinematic: no commanded joint speed above 0.7 of the no-load speed;
2. :func:`subdivide` -- segments longer than 0.5 s are split so that only the torque-limited part
   of a long move is slowed;
3. :func:`retime` -- played nominally and at the four friction/mass corners of issue 4: segments
   above ``RETIME_RATIO_TARGET`` (0.88) of the torque-speed envelope are stretched, segments with spare torque are shortened,
   until no segment can be shortened without breaking the torque target or the standing; then
   a coordinate descent (``_refine``) shortens one segment at a time while it still passes.

Motions that need their momentum (``retime=False``, ``clamp_lead=True``: supine_situp_rock,
prone_elbow_knees_quick) keep their searched keyframe times; :func:`clamp_goal_lead` pulls their
goals back to errors the servos can follow within the envelope on all five players.

A motion is then verified on all five players (stands, peak <= ``TORQUE_BOUND`` = 0.9 of the
envelope, no self collision) and only then written, its index row added or replaced: the index
always names motions that pass. The file's ``report`` holds the judge's verdict, the peak torque
ratio (nominal and over the corners), ZMP margin and keyframe times; the simulated root pose is
written as ``root`` (needed by connecting-posture selection).

Joint values are written for the left side; :func:`sym` mirrors them to the right side. In
robot.xml every right joint mirrors its left twin with the opposite sign (pitch axes are
mirrored, roll/yaw axes shared), so a symmetric posture has q_right = -q_left; :func:`mirror`
turns a left-side motion into its right-side twin.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
from collections.abc import Mapping, Sequence
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
    "mirror",
    "mirror_keyframes",
    "speed_prescale",
    "subdivide",
    "robustness_players",
    "TORQUE_BOUND",
    "quat_lying",
    "settle",
    "build_trajectory",
    "MOTION_SPECS",
    "author_library",
    "ROW_HZ",
    "retime",
    "clamp_goal_lead",
]

log = logging.getLogger(__name__)

ROW_HZ = 100.0  # trajectory rows per second (the servo goal update rate) [Hz]
SETTLE_S = 1.5  # time a dropped lying posture is simulated to come to rest [s]
DROP_CLEARANCE_M = 0.004  # the lying posture is dropped from this far above the ground [m]
RETIME_RATIO_TARGET = 0.88  # peak torque/envelope after retiming, nominal and the four friction/mass corners (bound 0.9: 0.02 kept as margin for the rise pipeline, which joins planned paths to these motions)
ROBUST_FRICTION = (0.5, 1.0, 1.2)  # friction scales the library must stand with (issue 4)
ROBUST_MASS = (0.9, 1.0, 1.1)  # link mass scales the library must stand with (issue 4)
TORQUE_BOUND = 0.9  # issue 4: peak torque / envelope at every instant, every corner

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


def mirror(joints: Mapping[str, float]) -> dict[str, float]:
    """The mirror image (left <-> right) of joint goals: ``l_x = v`` becomes ``r_x = -v`` and vice versa,
    ``head_pan`` changes sign (robot.xml: right joints mirror their left twins with the opposite sign)."""
    out: dict[str, float] = {}
    for k, v in joints.items():
        if k.startswith("l_"):
            out["r_" + k[2:]] = -float(v)
        elif k.startswith("r_"):
            out["l_" + k[2:]] = -float(v)
        elif k == "head_pan":
            out[k] = -float(v)
        else:
            out[k] = float(v)
    return out


def mirror_keyframes(keyframes: tuple[Keyframe, ...]) -> tuple[Keyframe, ...]:
    """Keyframes of the mirror-image motion (see :func:`mirror`)."""
    return tuple(Keyframe(k.t_s, mirror(k.joints)) for k in keyframes)


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
        lying_yaw_rad: yaw of the lying posture [rad].
        retime: find the timing in MuJoCo (:func:`retime`); False keeps the keyframe times (a
            dynamic motion whose momentum depends on them).
        clamp_lead: pass the trajectory through :func:`clamp_goal_lead` (for a motion authored
            with saturating servos: its goals are pulled back to what the servos can follow).
    """

    name: str
    lying: str
    strategy: str
    lying_joints: Mapping[str, float]
    keyframes: tuple[Keyframe, ...]
    connect_keyframe: int
    lying_yaw_rad: float = 0.0
    retime: bool = True
    clamp_lead: bool = False


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
    q[0] = q0  # the settled start, even where the ground pressed a joint a hair past its limit
    return Trajectory(robot.name, names, t, q, start)


SPEED_CAP_FRACTION = 0.7  # kinematic pre-scaling: peak joint speed <= this x the servo's no-load speed


def speed_prescale(robot: Robot, start: Posture, keyframes: tuple[Keyframe, ...], *, fraction: float = SPEED_CAP_FRACTION, passes: int = 6) -> tuple[Keyframe, ...]:
    """Stretch segments whose commanded joint speed exceeds ``fraction`` of the no-load speed.

    The torque-speed envelope is zero at the no-load speed, so no servo can follow a goal moving
    faster; doing this kinematically (no simulation) gives :func:`retime` a start near the answer.
    """
    from robot_rise.model import SUPPLY_VOLTAGE_V

    w0 = np.array([s.no_load_speed_at(SUPPLY_VOLTAGE_V) for s in robot.servo_specs()])
    goals = [k.joints for k in keyframes]
    dur = np.diff(np.array([0.0] + [k.t_s for k in keyframes]))
    for _ in range(passes):
        kfs = tuple(Keyframe(float(t), g) for t, g in zip(np.round(np.cumsum(dur), 3), goals))
        tr = build_trajectory(robot, start, kfs)
        qd = np.abs(np.diff(tr.q, axis=0) / np.diff(tr.t)[:, None]) / (fraction * w0)
        tm = 0.5 * (tr.t[1:] + tr.t[:-1])
        times = np.concatenate([[0.0], np.cumsum(dur)])
        over = np.ones(len(dur))
        for i in range(len(dur)):
            sel = (tm > times[i]) & (tm <= times[i + 1])
            if sel.any():
                over[i] = max(1.0, float(qd[sel].max()))
        if (over <= 1.001).all():
            break
        dur *= over
    return tuple(Keyframe(float(t), g) for t, g in zip(np.round(np.cumsum(dur), 3), goals))


REFINE_STEPS = (0.9, 0.95, 0.98)  # per-segment shortening factors tried by the coordinate descent of retime, coarse to fine
REFINE_MAX_EVALS = 240  # plays (on every player) the coordinate descent may spend per motion
SUBDIVIDE_S = 0.5  # after kinematic pre-scaling, segments longer than this are split for retiming [s]


def subdivide(robot: Robot, start: Posture, keyframes: tuple[Keyframe, ...], *, max_segment_s: float = SUBDIVIDE_S) -> tuple[tuple[Keyframe, ...], list[int]]:
    """Split long segments into pieces of at most ``max_segment_s`` (goals on the current curve).

    Gives :func:`retime` the freedom to slow only the torque-limited part of a long segment (a
    push-up's lift-off) and hurry the rest. Returns the keyframes and, per input keyframe, its index
    in the output.
    """
    tr = build_trajectory(robot, start, keyframes)
    names = robot.joint_names
    out: list[Keyframe] = []
    where: list[int] = []
    t_prev = 0.0
    for k in keyframes:
        n = int(math.ceil((k.t_s - t_prev) / max_segment_s - 1e-9))
        for i in range(1, n):
            t = t_prev + (k.t_s - t_prev) * i / n
            q = np.array([np.interp(t, tr.t, tr.q[:, j]) for j in range(len(names))])
            out.append(Keyframe(float(round(t, 3)), dict(zip(names, q.tolist()))))
        out.append(k)
        where.append(len(out) - 1)
        t_prev = k.t_s
    return tuple(out), where


def _evaluate(robot: Robot, start: Posture, kfs: tuple[Keyframe, ...], players: Sequence[object]) -> tuple[np.ndarray, bool, str]:
    """Play ``kfs`` on every player: per-segment peak torque/envelope ratio (max over players,
    including the 0.2 s after each segment, where a late tracking error shows) and whether every
    play stands without self collision (and why not)."""
    from robot_rise.sim.standing import judge

    tr = build_trajectory(robot, start, kfs)
    times = np.array([0.0] + [k.t_s for k in kfs])
    seg_peak = np.zeros(len(kfs))
    ok, why = True, ""
    for player in players:
        rec = player.play(tr)  # type: ignore[attr-defined]
        peak_ratio = rec.envelope_ratio.max(axis=1)
        for i in range(len(kfs)):
            sel = (rec.t > times[i]) & (rec.t <= times[i + 1] + 0.2)
            if sel.any():
                seg_peak[i] = max(seg_peak[i], float(peak_ratio[sel].max()))
        v = judge(rec)
        if not v.standing or v.self_collision:
            ok = False
            why = why or (v.reason if not v.standing else "self collision")
    return seg_peak, ok, why


def retime(
    robot: Robot,
    start: Posture,
    keyframes: tuple[Keyframe, ...],
    players: object,
    *,
    ratio_target: float = 0.85,
    shrink: float = 0.85,
    spare: float = 0.12,
    min_segment_s: float = 0.1,
    max_iter: int = 60,
    refine_steps: Sequence[float] = REFINE_STEPS,
) -> tuple[Keyframe, ...]:
    """Retime the keyframe segments to the servos' torque-speed envelope, both ways.

    A simple optimisation in MuJoCo over the segment durations:

    1. play on every player (nominal and the robustness corners); per segment, the peak torque /
       envelope ratio (including the 0.2 s after it) over all players;
    2. a segment above ``ratio_target`` is stretched in proportion to its excess (x1.05..x1.4);
    3. once the whole motion is within the target and stands on every player, each segment with
       spare torque (peak below ``ratio_target - spare``) is SHORTENED by ``shrink`` (never below
       ``min_segment_s``); a shortening that breaks the target or the standing is undone and the
       segment to blame is frozen (the one over the target; when the robot fell, the shortened
       segments are bisected until the one that makes it fall is found);
    4. :func:`_refine`: coordinate descent from there, one segment at a time, with the factors
       ``refine_steps`` (empty: skip it).

    Returns the fastest feasible timing found (the input's if none was feasible: then the caller's
    verification fails and reports it).

    Args:
        players: :class:`robot_rise.sim.Player` objects on flat ground (nominal and the
            friction/mass corners); the peak is taken over all of them.
    """
    plist = list(players) if isinstance(players, (list, tuple)) else [players]
    kfs = speed_prescale(robot, start, tuple(keyframes))
    goals = [k.joints for k in kfs]
    dur = np.diff(np.array([0.0] + [k.t_s for k in kfs]))
    frozen = np.zeros(len(kfs), dtype=bool)
    best: np.ndarray | None = None
    shrunk = np.zeros(len(kfs), dtype=bool)
    trial: np.ndarray | None = None  # restrict the next shortening to these segments (bisection)

    def to_kfs(d: np.ndarray) -> tuple[Keyframe, ...]:
        t = np.round(np.cumsum(d), 3)
        return tuple(Keyframe(float(ti), g) for ti, g in zip(t, goals))

    for it in range(max_iter):
        seg_peak, ok, why = _evaluate(robot, start, to_kfs(dur), plist)
        bad = seg_peak > ratio_target
        feasible = ok and not bad.any()
        log.info("retime %d: %.2f s, peak %.2f, %s", it, dur.sum(), seg_peak.max(), "ok" if feasible else (why or "torque"))
        if feasible:
            best = dur.copy()
            shrunk[:] = False
            cand = (~frozen) & (seg_peak < ratio_target - spare) & (dur > min_segment_s + 1e-6)
            if trial is not None and (cand & trial).any():
                cand &= trial
            trial = None
            if not cand.any():
                break
            dur[cand] = np.maximum(dur[cand] * shrink, min_segment_s)
            shrunk = cand
            continue
        if best is not None and shrunk.any():
            # the last shortening broke it: undo; freeze the segment to blame -- the one over the
            # target, or, when the robot fell, the shortened one if it was alone; else bisect
            # (try the first half of the shortened segments next)
            if ok and (shrunk & bad).any():
                frozen |= shrunk & bad
            elif shrunk.sum() == 1:
                frozen |= shrunk
            else:
                idx = np.flatnonzero(shrunk)
                trial = np.zeros(len(kfs), dtype=bool)
                trial[idx[: len(idx) // 2]] = True
                # the other half stays a candidate; the bisection continues if it fails again
            dur = best.copy()
            shrunk[:] = False
            continue
        if bad.any():
            dur[bad] *= np.clip(1.0 + 2.0 * (seg_peak[bad] - ratio_target), 1.05, 1.4)
        else:  # within torque but falls: slow everything a little
            dur *= 1.1
    if best is None:
        log.warning("retime: no feasible timing within %d iterations (last: %.2f s)", max_iter, dur.sum())
        return to_kfs(dur)
    log.info("retime: %.2f s after %d iterations", best.sum(), it + 1)
    if refine_steps:
        best = _refine(robot, start, goals, best, plist, ratio_target=ratio_target, steps=refine_steps, min_segment_s=min_segment_s)
    return to_kfs(best)



def _refine(
    robot: Robot,
    start: Posture,
    goals: Sequence[Mapping[str, float]],
    dur: np.ndarray,
    players: Sequence[object],
    *,
    ratio_target: float,
    steps: Sequence[float] = REFINE_STEPS,
    min_segment_s: float = 0.1,
    max_evals: int = REFINE_MAX_EVALS,
) -> np.ndarray:
    """Coordinate descent on feasible segment durations [s], shape (n_keyframes,).

    One segment at a time (longest first), shorten it by the step factor and keep the change only
    if the whole motion still stands on every player within ``ratio_target``; sweep until no
    segment can be shortened, then go on with the next (finer) factor. Every accepted timing is
    feasible, so unlike the joint shortening of :func:`retime` no bisection is needed; this finds
    the segments whose peak sits just under the target but that still have room.
    """
    dur = dur.copy()
    n_evals = 0
    for step in steps:
        improved = True
        while improved and n_evals < max_evals:
            improved = False
            for i in np.argsort(-dur):
                if dur[i] * step < min_segment_s or n_evals >= max_evals:
                    continue
                trial = dur.copy()
                trial[i] *= step
                kfs = tuple(Keyframe(float(t), g) for t, g in zip(np.round(np.cumsum(trial), 3), goals))
                seg_peak, ok, _ = _evaluate(robot, start, kfs, players)
                n_evals += 1
                if ok and (seg_peak <= ratio_target).all():
                    dur = trial
                    improved = True
        log.info("retime refine x%.2f: %.2f s (%d plays)", step, dur.sum(), n_evals)
    return dur


LEAD_CLAMP_RATIO = 0.85  # clamp_goal_lead: goals lead the servo by at most the error giving this ratio of the envelope
LEAD_CLAMP_TARGET = 0.87  # clamp_goal_lead: done when every player's peak torque / envelope is at most this (bound 0.9)
LEAD_CLAMP_WARM_ITER = 12  # clamp_goal_lead: iterations at the uniform ratio before it is lowered locally
LEAD_CLAMP_MAX_ITER = 40  # clamp_goal_lead: iterations (each plays every player once)
LEAD_CLAMP_WINDOW_S = 0.05  # clamp_goal_lead: a violation lowers the ratio of that joint within this window [s]
LEAD_CLAMP_STEP = 0.02  # clamp_goal_lead: how much a violation lowers the local ratio per iteration


def clamp_goal_lead(
    robot: Robot,
    trajectory: Trajectory,
    players: Sequence[object],
    *,
    ratio: float = LEAD_CLAMP_RATIO,
    target: float = LEAD_CLAMP_TARGET,
    warm_iter: int = LEAD_CLAMP_WARM_ITER,
    max_iter: int = LEAD_CLAMP_MAX_ITER,
    window_s: float = LEAD_CLAMP_WINDOW_S,
    step: float = LEAD_CLAMP_STEP,
) -> Trajectory:
    """Pull the goals of a saturating motion back to what the servos can follow within the envelope.

    A dynamic motion (one that uses momentum) is easiest to author with goals far ahead of the
    joints: the servos saturate (ratio 1). In position mode the torque is
    ``tau = tau_stall * (clip(kp e / tau_stall) - w / w0)`` with ``e`` the goal error, so the
    ratio ``r`` of the envelope is kept by ``e`` in
    ``[(-r + (1 - r) w / w0), (r + (1 - r) w / w0)] * tau_stall / kp`` (``+`` side: room
    ``tau_stall (1 - w / w0)``, braking side: ``tau_stall (1 + w / w0)``). Each iteration plays
    the motion on every player, and clips each authored goal into the intersection over the
    players of ``q(t) + [e_min, e_max]`` at the simulated joint angle ``q`` and speed ``w``; the
    motion is then played again (the joints move less fast with less torque) until it converges.
    After ``warm_iter`` iterations, wherever a player still exceeds ``target`` (impacts, fast
    speed changes within a row), the ratio of that joint within ``window_s`` is lowered by
    ``step``. The motion keeps its timing: only the torque peaks are cut.

    Args:
        trajectory: the authored motion (rows at ``ROW_HZ``), joint goals [rad].
        players: nominal and the friction/mass corners.

    Returns:
        the clamped trajectory (same rows, new goals; the first row unchanged). The caller verifies it.
    """
    specs = robot.servo_specs()
    from robot_rise.model import SUPPLY_VOLTAGE_V
    from robot_rise.servo import servo_arrays

    sv = servo_arrays(specs, SUPPLY_VOLTAGE_V)
    kp, stall, w0 = sv.kp_nm_per_rad, sv.stall_torque_nm, sv.no_load_speed_rad_s
    t = trajectory.t
    base = trajectory.q
    goals = base.copy()
    r = np.full(base.shape, ratio)
    n = base.shape[1]
    for it in range(max_iter):
        cur = Trajectory(trajectory.robot, trajectory.joint_names, t, goals, trajectory.start)
        lo = np.full(base.shape, -np.inf)
        hi = np.full(base.shape, np.inf)
        over = np.zeros(base.shape, dtype=bool)
        peaks = []
        for player in players:
            rec = player.play(cur)  # type: ignore[attr-defined]
            peaks.append(rec.peak_envelope_ratio)
            q = np.stack([np.interp(t, rec.t, rec.q[:, j]) for j in range(n)], axis=-1)
            w = np.stack([np.interp(t, rec.t, rec.qd[:, j]) for j in range(n)], axis=-1)
            lo = np.maximum(lo, q + (-r + (1 - r) * w / w0) * stall / kp)
            hi = np.minimum(hi, q + (r + (1 - r) * w / w0) * stall / kp)
            for k, j in np.argwhere(rec.envelope_ratio > target):
                over[np.abs(t - rec.t[k]) <= window_s, j] = True
        log.info("clamp_goal_lead %d: peaks %s", it, " ".join(f"{p:.3f}" for p in peaks))
        if max(peaks) <= target:
            break
        if it >= warm_iter:
            r = np.where(over, r - step, r)
        empty = lo > hi  # the players disagree: split the difference
        mid = 0.5 * (lo + hi)
        goals = np.clip(base, np.where(empty, mid, lo), np.where(empty, mid, hi))
        goals[0] = base[0]
    return Trajectory(trajectory.robot, trajectory.joint_names, t, goals, trajectory.start)

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


_ROLL_BACK = (
    Keyframe(0.3, sym(sho_pitch=0.3, sho_roll=1.3, hip_pitch=-0.2, knee=0.3)),  # ready: end of the supine (connect) phase
    # legs swung up over the hips, nearly straight (long lever, fast), the arms along the body start
    # pressing into the ground: the hips lift and the centre of mass moves over the shoulders
    Keyframe(0.8, sym(sho_pitch=0.8, hip_pitch=-1.8, knee=0.2)),
    Keyframe(1.4, sym(sho_pitch=2.0, hip_pitch=-1.7, knee=0.8)),  # over the head: the arms push on
    # knees bent for the landing on head and feet (prone pike); the arms, free while the robot goes
    # over its head, are swept out sideways (along the shoulder pitch axis, ready to be spun to the T)
    Keyframe(1.9, sym(sho_pitch=2.2, sho_roll=0.0, hip_pitch=-1.5, knee=1.5)),
)


def _prone_arms_from_overhead(t0: float) -> tuple[Keyframe, ...]:
    """Landed in the prone pike after a back roll (arms sideways): hips lowered to lie prone, arms
    spun about their own axis to the T, knees pulled under."""
    return (
        Keyframe(t0 + 0.5, sym(hip_pitch=-0.6, knee=0.8)),  # hips down: lying prone
        Keyframe(t0 + 1.0, sym(sho_pitch=-1.57, sho_roll=0.15, hip_pitch=-1.2, knee=2.0, ank_pitch=0.3)),  # the T; knees under
    )


# Lying on the left side: knees tucked, the lower (left) arm stretched over the head under it, feet
# apart -- this rests on the side (the box torso alone rolls onto its back).
_LEFT_SIDE = _LIE_FLAT | sym(hip_roll=-0.12, hip_pitch=-0.5, knee=1.0) | {"l_sho_pitch": 0.0, "l_sho_roll": -1.2, "r_hip_pitch": 0.9, "r_knee": -1.2}
_LEFT_TIP = (
    Keyframe(0.3, {}),  # end of the side-lying (connect) phase
    # lower arm turned forward under the head, upper arm reaching forward and down, knees pulled up:
    # the centre of mass moves in front of the support and the robot tips onto its front
    Keyframe(0.9, {"l_sho_pitch": -0.8, "r_sho_pitch": 1.2, "r_sho_roll": -0.6, "l_hip_pitch": -0.8, "l_knee": 1.2, "r_hip_pitch": 1.2, "r_knee": -1.4}),
    Keyframe(1.4, {"l_sho_pitch": -0.8}),
    Keyframe(2.0, sym(sho_roll=0.15, hip_roll=0.0, hip_pitch=-1.2, knee=2.0, ank_pitch=0.3)),  # prone: arms swept out, knees under
    Keyframe(2.4, sym(sho_pitch=-1.57)),  # arms turned about their axis: the prone T
)


_ELBOWS_KNEES = sym(sho_pitch=-1.57, sho_roll=0.15, el=-1.4, hip_pitch=-1.2, knee=2.0, ank_pitch=0.3)  # prone: forearms down, knees under


def _elbow_knees_tail(t0: float) -> tuple[Keyframe, ...]:
    """From prone in ``_ELBOWS_KNEES`` at ``t0``: elbows and shoulders push (short levers: the
    forearms stand on the ground) while the knees come further under, then straight back onto the
    feet (no separate all-fours pose: 0.4 s shorter, as robust), squat, stand."""
    return _elbow_knees_tail_at((t0 + 0.5, t0 + 0.9, t0 + 1.4, t0 + 1.7, t0 + 2.4))


def _elbow_knees_tail_at(times_s: tuple[float, float, float, float, float]) -> tuple[Keyframe, ...]:
    """The keyframes of :func:`_elbow_knees_tail` at the given times [s]."""
    return tuple(
        Keyframe(t, g)
        for t, g in zip(
            times_s,
            (
                sym(sho_pitch=-1.57, sho_roll=0.9, el=-0.6, hip_pitch=-1.4, knee=2.3, ank_pitch=0.4),
                sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0, hip_pitch=-1.5, knee=2.4, ank_pitch=0.5),
                _SQUAT_HANDS,
                _SQUAT,
                _STAND,
            ),
        )
    )


MOTION_SPECS: list[MotionSpec] = [
    MotionSpec(
        name="prone_elbow_knees_quick",
        lying="prone",
        strategy="prone_elbow_knees in 2.42 s: the same keyframes, pushed through with momentum (times from a search in MuJoCo), goals clamped into the envelope",
        lying_joints=_LIE_FLAT | _T_ARMS,
        # First in the index: the prone motions share this start posture, and the nearest-frame
        # search breaks that tie by index order, so the canonical prone start rises through the
        # fastest one. Times: prone_elbow_knees' retimed segments scaled by an evolution strategy that kept the
        # robot standing on all five players with saturating servos (1.2 s), then all x2.0: with
        # clamp_goal_lead the servos stay within the envelope and it still stands everywhere.
        keyframes=(Keyframe(0.292, _ELBOWS_KNEES),) + _elbow_knees_tail_at((0.516, 0.588, 1.233, 1.335, 2.416)),
        connect_keyframe=3,
        retime=False,
        clamp_lead=True,
    ),
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
    MotionSpec(
        name="prone_elbow_knees",
        lying="prone",
        strategy="prone, arms out: knees pulled under while the forearms are set down at the elbows (short levers), elbows and shoulders push up, straight back onto the feet, squat, stand",
        lying_joints=_LIE_FLAT | _T_ARMS,
        keyframes=(Keyframe(0.5, _ELBOWS_KNEES),) + _elbow_knees_tail(0.5),
        connect_keyframe=3,
    ),
    MotionSpec(
        name="supine_backroll_pushup",
        lying="supine",
        strategy="supine: legs swung over the head while the arms along the body push, backward roll, land prone; lying prone the arms go to the T and the knees under, forearms set down, elbows and shoulders push up and back onto the feet, squat, stand (prone_elbow_knees tail)",
        lying_joints=_LIE_FLAT,
        keyframes=_ROLL_BACK + _prone_arms_from_overhead(1.9) + (Keyframe(3.3, _ELBOWS_KNEES),) + _elbow_knees_tail(3.3),
        connect_keyframe=0,
    ),
    MotionSpec(
        name="supine_backroll_kneel",
        lying="supine",
        strategy="supine: backward roll over the head into a prone pike (head and feet down); arms to the T, knees pulled under with the elbows bent, pushed up and back onto the feet from the pike (never lying flat), squat, stand",
        # knees up, arms out at 40 deg: a different supine start from supine_backroll_pushup's, so
        # that connecting-posture selection covers more of the supine postures (same roll after 0.3 s)
        lying_joints=_LIE_FLAT | sym(sho_roll=0.7, hip_pitch=-0.6, knee=1.2, ank_pitch=0.3),
        keyframes=_ROLL_BACK
        + (
            Keyframe(2.5, sym(sho_pitch=-1.57, sho_roll=0.15)),  # arms spun about their own axis: the T
            # knees pulled under the hips, hands set down with bent elbows (short lever) while the head
            # still rests: the weight goes onto the shins before the arms push
            Keyframe(3.1, sym(sho_roll=0.5, el=-1.0, hip_pitch=-1.8, knee=2.5, ank_pitch=0.6)),
            Keyframe(4.0, _SQUAT_HANDS),  # pushed up and straight back onto the feet (no separate all-fours pose)
            Keyframe(4.4, _SQUAT),
            Keyframe(5.2, _STAND),
        ),
        connect_keyframe=0,
    ),
    MotionSpec(
        name="supine_situp_rock",
        lying="supine",
        strategy="supine, arms overhead: hands pressed into the ground behind the head sit the torso up while the legs swing up (jack-knife), the legs kick down and fold under while the arms push on (rocking momentum), the torso folds over the feet into a squat, stand",
        lying_joints=_LIE_FLAT | sym(sho_roll=-1.3),
        # Keyframe values and times found by a search in MuJoCo (a (1+1) evolution strategy, then
        # differential evolution, on all five players: stands on every one, then least torque
        # excess); the motion needs its momentum, so it is not retimed: its goals are pulled back
        # to what the servos can follow within the envelope by clamp_goal_lead.
        keyframes=(
            Keyframe(0.3, sym(sho_pitch=-0.4, hip_pitch=-0.2, knee=0.3)),  # end of the supine (connect) phase
            Keyframe(0.604, sym(sho_pitch=-0.7, hip_pitch=-1.8, knee=1.55)),  # hands press behind the head, legs up: the torso sits up
            Keyframe(1.374, sym(sho_pitch=-1.623, hip_pitch=-0.569, knee=2.6, ank_pitch=1.277)),  # legs kick down and fold under, arms push on
            Keyframe(1.624, sym(sho_pitch=-1.245, hip_pitch=-2.0, knee=2.6, ank_pitch=1.3)),  # torso folded forward over the feet
            Keyframe(2.031, sym(sho_pitch=-0.92, sho_roll=-0.081, el=0.0, hip_pitch=-0.763, knee=1.991, ank_pitch=1.087)),  # caught on the feet
            Keyframe(2.805, _STAND),
        ),
        connect_keyframe=0,
        retime=False,
        clamp_lead=True,
    ),
    MotionSpec(
        name="left_tip_forward",
        lying="left",
        strategy="left side, knees tucked: lower arm forward under the head, upper arm reaches forward and down, knees up: tip onto the front; arms to the T with the knees kept under, forearms set down, then elbows and shoulders push up and back onto the feet, squat, stand (prone_elbow_knees tail)",
        lying_joints=_LEFT_SIDE,
        keyframes=_LEFT_TIP + (Keyframe(2.8, _ELBOWS_KNEES),) + _elbow_knees_tail(2.8),
        connect_keyframe=0,
    ),
    MotionSpec(
        name="right_tip_forward",
        lying="right",
        strategy="mirror image of left_tip_forward: right side, knees tucked, tip onto the front, elbow push-up back onto the feet, squat, stand",
        lying_joints=mirror(_LEFT_SIDE),
        keyframes=mirror_keyframes(_LEFT_TIP + (Keyframe(2.8, _ELBOWS_KNEES),) + _elbow_knees_tail(2.8)),
        connect_keyframe=0,
    ),
]


def robustness_players(robot: Robot) -> list:
    """Players for nominal and the four friction/mass corners of issue 4 (flat ground)."""
    from robot_rise.sim.player import Player

    players = [Player(robot, "flat")]
    for f in (ROBUST_FRICTION[0], ROBUST_FRICTION[-1]):
        for mass in (ROBUST_MASS[0], ROBUST_MASS[-1]):
            players.append(Player(robot, "flat", friction_scale=f, mass_scale=mass))
    return players


def _write_atomic(path: Path, text: str) -> None:
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
    """
    from robot_rise.sim.standing import judge

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
        from robot_rise.sampling import classify_lying

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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=configs_dir() / "motions" / "op3")
    parser.add_argument("--only", nargs="*", help="motion names to rebuild (their index rows are replaced or added; others kept)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    entries = author_library(args.out, names=args.only)
    return 0 if entries else 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
