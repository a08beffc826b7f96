"""Retiming: the keyframe times of a motion found in MuJoCo against the servos' torque-speed envelope.

The keyframe times an author writes are only a shape. The timing is found in three steps:

1. :func:`speed_prescale` -- kinematic: no commanded joint speed above 0.7 of the no-load speed;
2. :func:`subdivide` -- segments longer than 0.5 s are split so that only the torque-limited part
   of a long move is slowed;
3. :func:`retime` -- played nominally and at the four friction/mass corners of issue 4: segments
   above ``RETIME_RATIO_TARGET`` (0.88) of the torque-speed envelope are stretched, segments with
   spare torque are shortened, until no segment can be shortened without breaking the torque
   target or the standing; then a coordinate descent (``_refine``) shortens one segment at a time
   while it still passes.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from robot_rise.authoring.keyframes import Keyframe, build_trajectory
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.sim.player import Player
from robot_rise.sim.standing import judge

__all__ = [
    "REFINE_MAX_EVALS",
    "REFINE_STEPS",
    "RETIME_RATIO_TARGET",
    "RETIME_RISE_PROGRESS",
    "RETIME_SAME_FALL_LIMIT",
    "SPEED_CAP_FRACTION",
    "SUBDIVIDE_S",
    "Retimed",
    "retime",
    "speed_prescale",
    "subdivide",
]

log = logging.getLogger(__name__)

RETIME_RATIO_TARGET = 0.88  # peak torque/envelope after retiming, nominal and the four friction/mass corners (bound 0.9: 0.02 kept as margin for the rise pipeline, which joins planned paths to these motions)
SPEED_CAP_FRACTION = 0.7  # kinematic pre-scaling: peak joint speed <= this x the servo's no-load speed
# A motion within the torque target that falls is slowed x1.1 at a time; one that falls the same way
# (the same judge's reason) and rises no higher (the torso's highest point, within
# RETIME_RISE_PROGRESS of the stand height) after this many slowings in a row is not one that
# slowing rescues, so the retiming gives up (a prone get-up that never rose on Bez1's body was
# slowed fifty times, 7 s to 650 s of motion, 11 minutes of building, before it was stopped).
RETIME_SAME_FALL_LIMIT = 8
RETIME_RISE_PROGRESS = 0.02


def speed_prescale(robot: Robot, start: Posture, keyframes: tuple[Keyframe, ...], *, fraction: float = SPEED_CAP_FRACTION, passes: int = 6) -> tuple[Keyframe, ...]:
    """Stretch segments whose commanded joint speed exceeds ``fraction`` of the no-load speed.

    The torque-speed envelope is zero at the no-load speed, so no servo can follow a goal moving
    faster; doing this kinematically (no simulation) gives :func:`retime` a start near the answer.
    """
    w0 = np.array([s.no_load_speed_at(robot.supply_voltage_v) for s in robot.servo_datasheets()])
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


def _evaluate(robot: Robot, start: Posture, kfs: tuple[Keyframe, ...], players: Sequence[Player], *,
              stop_above: float | None = None) -> tuple[np.ndarray, bool, str, float]:
    """Play ``kfs`` on every player: per-segment peak torque/envelope ratio (max over players,
    including the 0.2 s after each segment, where a late tracking error shows), whether every
    play stands without self collision, why not, and how high the first play that failed got
    (the torso's highest point over its stand height; 1 when none failed). ``stop_above``: stop
    at the first player that fails or peaks above it (a pass/fail question: the peaks returned
    then are partial)."""
    tr = build_trajectory(robot, start, kfs)
    times = np.array([0.0] + [k.t_s for k in kfs])
    seg_peak = np.zeros(len(kfs))
    ok, why, rose = True, "", 1.0
    for player in players:
        rec = player.play(tr)
        peak_ratio = rec.envelope_ratio.max(axis=1)
        for i in range(len(kfs)):
            sel = (rec.t > times[i]) & (rec.t <= times[i + 1] + 0.2)
            if sel.any():
                seg_peak[i] = max(seg_peak[i], float(peak_ratio[sel].max()))
        v = judge(rec)
        if (not v.standing or v.self_collision) and ok:
            ok, why = False, v.reason if not v.standing else "self collision"
            rose = float(np.max(rec.torso_height_m, initial=0.0)) / rec.stand_height_m
        if stop_above is not None and (not ok or (seg_peak > stop_above).any()):
            break
    return seg_peak, ok, why, rose


@dataclass(frozen=True)
class Retimed:
    """What :func:`retime` found: the fastest timing (after the coordinate descent) and the
    timing before it (one a proof may still accept when the fastest sits on a knife edge)."""

    fastest: tuple[Keyframe, ...]
    unrefined: tuple[Keyframe, ...]


def retime(
    robot: Robot,
    start: Posture,
    keyframes: tuple[Keyframe, ...],
    players: Player | Sequence[Player],
    *,
    ratio_target: float = 0.85,
    shrink: float = 0.85,
    spare: float = 0.12,
    min_segment_s: float = 0.1,
    max_iter: int = 60,
    refine_steps: Sequence[float] = REFINE_STEPS,
) -> Retimed:
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

    Returns the fastest feasible timing found and the one before step 4 (both the last timing
    tried if none was feasible: then the caller's verification fails and reports it; the search
    gives up early on a motion that falls the same way, rising no higher, ``RETIME_SAME_FALL_LIMIT``
    slowings in a row). A caller that needs both (the library author tries the unrefined timing when the
    fastest is not proven) retimes once.

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
    same_fall = (0, "", 0.0)  # slowings in a row after which the motion fell the same way, that way, how high it got

    def to_kfs(d: np.ndarray) -> tuple[Keyframe, ...]:
        t = np.round(np.cumsum(d), 3)
        return tuple(Keyframe(float(ti), g) for ti, g in zip(t, goals))

    for it in range(max_iter):
        seg_peak, ok, why, rose = _evaluate(robot, start, to_kfs(dur), plist)
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
            same_fall = (0, "", 0.0)
        else:  # within torque but falls: slow everything a little, unless slowing has not changed the fall
            n, way, height = same_fall
            same_fall = (n + 1, way, height) if why == way and rose < height + RETIME_RISE_PROGRESS else (1, why, rose)
            # (a self collision is exempt: slowing takes the overshoot out of a limb that grazes another)
            if same_fall[0] > RETIME_SAME_FALL_LIMIT and why != "self collision":
                log.warning("retime: falls the same way (%s, rising to %.0f %% of the stand height) after %d slowings in a row: giving up at %.2f s",
                            why, 100 * same_fall[2], RETIME_SAME_FALL_LIMIT, dur.sum())
                break
            dur *= 1.1
    if best is None:
        log.warning("retime: no feasible timing within %d iterations (last: %.2f s)", max_iter, dur.sum())
        return Retimed(to_kfs(dur), to_kfs(dur))
    log.info("retime: %.2f s after %d iterations", best.sum(), it + 1)
    unrefined = to_kfs(best)
    if refine_steps:
        best = _refine(robot, start, goals, best, plist, ratio_target=ratio_target, steps=refine_steps, min_segment_s=min_segment_s)
    return Retimed(to_kfs(best), unrefined)


def _refine(
    robot: Robot,
    start: Posture,
    goals: Sequence[Mapping[str, float]],
    dur: np.ndarray,
    players: Sequence[Player],
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
                # pass or fail is all that is asked: the first failing player answers it
                seg_peak, ok, _, _ = _evaluate(robot, start, kfs, players, stop_above=ratio_target)
                n_evals += 1
                if ok and (seg_peak <= ratio_target).all():
                    dur = trial
                    improved = True
        log.info("retime refine x%.2f: %.2f s (%d plays)", step, dur.sum(), n_evals)
    return dur
