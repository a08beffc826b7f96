"""Turn-over strategies on a robot: where and when the turn leaves the body, and the turn followed by a proven get-up as one motion.

A turn-over (``"lands"`` in its strategy file) ends lying, not standing, so it is never judged
as a get-up alone. ``robot-rise library build`` uses one where a robot has no proven motion for
its lying kind (:func:`robot_rise.authoring.build.build_library`):

1. :func:`landing` -- when the body lies at rest, for good, in the kind it lands in, on every
   robustness player (a momentum turn-over's goals then clamped into the envelope, and the
   nominal body timed again): a heavier body with slower servos (Wolfgang-OP: 6.1 kg, joints
   saturating at ~4.5 rad/s) lands later than the body the keyframes were written on.
2. :func:`author_turn_over` -- the turn, held until it landed, a planned path from where it lies
   to a proven get-up's start, then that get-up's rows as proven on this robot (both slowed in
   steps where the whole exceeds the envelope); judged, proven and written as one library motion.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_rise.authoring.goal_lead import clamp_goal_lead
from robot_rise.authoring.keyframes import Keyframe, build_trajectory
from robot_rise.authoring.write import PROOF_SCENE, motion_specs, prove_for_library, settled_start, write_motion
from robot_rise.errors import PostureError
from robot_rise.filter import command_limits_for, conform, join_with_blend
from robot_rise.proof import ARRIVAL_SETTLE_S, arrival_spread_starts
from robot_rise.library import Strategy
from robot_rise.model import Robot
from robot_rise.placement import place_near
from robot_rise.planning.problem import PlanningProblem
from robot_rise.planning.to_trajectory import plan_trajectory
from robot_rise.posture import Posture
from robot_rise.sampling import classify_lying
from robot_rise.sim.player import Player, Recording
from robot_rise.sim.standing import SETTLED_JOINT_SPEED_RAD_S, SETTLED_ROOT_RATE_RAD_S, SETTLED_ROOT_SPEED_M_S
from robot_rise.trajectory import Trajectory
from robot_rise.validity import ValidityChecker

__all__ = ["LANDING_WAIT_S", "LANDED_MARGIN_S", "TURN_OVER_PLAN_BUDGET_S", "TURN_OVER_STEP_S", "TURN_OVER_SLOWING", "Landing", "landing", "author_turn_over"]

log = logging.getLogger(__name__)

LANDING_WAIT_S = 3.0  # the turn-over's last goals are held this long for the body to come to rest [s]
LANDED_MARGIN_S = 0.1  # the get-up that follows starts this long after the slowest player's landing [s]
TURN_OVER_PLAN_BUDGET_S = 30.0  # planning budget from where the turn-over lands to the get-up's start [s]
TURN_OVER_STEP_S = 0.1  # the turn's last goals to the landed joints the path starts from (the servos' load error) [s]
# (path, get-up) time factors tried in turn until the whole stands within the bound on every
# robustness player: the path drags legs lying on the floor (Wolfgang-OP on high friction, 10 %
# heavier: hip roll at 0.99 of the envelope timed as planned, 0.8 at twice that), and a get-up
# proven from its own start meets arms in other states after a turn (shoulder 0.92 -> under 0.9 at x1.25)
TURN_OVER_SLOWING = ((1.0, 1.0), (2.0, 1.25), (3.0, 1.5))


@dataclass(frozen=True)
class Landing:
    """Where a turn-over leaves the robot.

    Attributes:
        landed_s: when the body lies at rest in the strategy's ``lands`` kind on every player
            (and, as clamped, on the nominal one), plus ``LANDED_MARGIN_S`` [s]; None where it
            does not (``reason`` says why).
        per_player_s: each player's landing time of the turn as streamed (conformed to the command
            limits, not clamped) [s], up to the first player where it did not land.
        reason: why it does not land (empty when it does).
        start: the settled lying posture the turn starts from (None where it does not settle so).
        turn: the turn's targets from ``start``, its last goals held ``LANDING_WAIT_S`` (a momentum
            turn-over's goals clamped into the envelope: timed on the nominal body only, a corner
            body still turning is the proof's to judge).
        keyframe_times_s: the strategy's keyframe times on ``turn`` [s] (later than written where
            conforming or the clamp slowed it).
    """

    landed_s: float | None
    per_player_s: tuple[float, ...]
    reason: str = ""
    start: Posture | None = None
    turn: Trajectory | None = None
    keyframe_times_s: tuple[float, ...] = ()


def _at_rest_in(rec: Recording, kind: str) -> np.ndarray:
    """Per recorded step: the body lies in ``kind`` and is still (root and every joint)."""
    kinds = np.array([classify_lying(q) for q in rec.root_pose[:, 3:]])
    return ((kinds == kind)
            & (np.linalg.norm(rec.root_vel[:, :3], axis=1) < SETTLED_ROOT_SPEED_M_S)
            & (np.linalg.norm(rec.root_vel[:, 3:], axis=1) < SETTLED_ROOT_RATE_RAD_S)
            & (np.abs(rec.qd).max(axis=1) < SETTLED_JOINT_SPEED_RAD_S))


def landing(robot: Robot, turn: Strategy, players: list[Player]) -> Landing:
    """Play the turn-over from its settled lying posture on each player, its last goals held for
    ``LANDING_WAIT_S``, and find when the body lies at rest, for good, in the kind it lands in.

    A momentum turn-over (``clamp_lead``) then has its goals up to that landing clamped into the
    envelope, held again, and the nominal body timed again (the clamp slows it): the landing is
    then the later of both.

    Raises:
        ValueError: ``turn`` is not a turn-over.
    """
    if turn.lands is None:
        raise ValueError(f"{turn.name} is not a turn-over (no 'lands')")
    spec = motion_specs(robot, (turn,))[0]
    try:
        start = settled_start(robot, spec)
    except PostureError as e:
        return Landing(None, (), str(e))
    if classify_lying(start.root_quat_wxyz) != turn.lying:
        return Landing(None, (), f"its lying posture settles {classify_lying(start.root_quat_wxyz)}, not {turn.lying}")
    # timed as the executor streams it: the proof conforms the whole to the command limits, and a
    # turn slowed there afterwards lands otherwise (Wolfgang-OP's roll then tip: its knee at 1.01 of
    # the envelope conformed, 0.86 as played unconformed)
    limits = command_limits_for(robot)
    authored = build_trajectory(robot, start, (*spec.keyframes, Keyframe(spec.keyframes[-1].t_s + LANDING_WAIT_S, {})))
    tr = conform(authored, limits)  # same rows, slower segments: each keyframe moves with its row
    key_t = np.interp([k.t_s for k in spec.keyframes], authored.t, tr.t)
    times, reason = _landing_times(tr, turn.lands, float(key_t[-1]), players)
    if reason:
        return Landing(None, times, reason, start, tr, tuple(key_t))
    if turn.clamp_lead:
        # the turn up to its landing clamped (clamping the whole hold too weakens a roll on its
        # later impacts until it no longer turns over: Wolfgang-OP), held again, and the nominal
        # body, which the planned path starts from, timed again: the clamp slows it. A corner body
        # still turning then is the proof's to judge (the path's goals finish its turn: OP3's roll)
        cut = tr.t <= max(times) + LANDED_MARGIN_S + 1e-9
        clamped = clamp_goal_lead(robot, dataclasses.replace(tr, t=tr.t[cut], q=tr.q[cut]), players,
                                  spread_starts=arrival_spread_starts(robot, start))
        streamed = conform(clamped, limits)  # the clamp's goals may ask for more speed again
        key_t = np.interp(key_t, clamped.t, streamed.t)
        tr = _held(streamed, LANDING_WAIT_S)
        nominal, reason = _landing_times(tr, turn.lands, float(key_t[-1]), players[:1])
        if reason:
            return Landing(None, times, f"as clamped into the envelope, {reason}", start, tr, tuple(key_t))
        return Landing(max(*times, *nominal) + LANDED_MARGIN_S, times, "", start, tr, tuple(key_t))
    return Landing(max(times) + LANDED_MARGIN_S, times, "", start, tr, tuple(key_t))


def _landing_times(tr: Trajectory, kind: str, end_s: float, players: list[Player]) -> tuple[tuple[float, ...], str]:
    """Each player's landing time of ``tr`` (at rest in ``kind`` for good, not before ``end_s``),
    or the times up to the first player where it does not land and why."""
    times: list[float] = []
    for i, player in enumerate(players):
        rec = player.play(tr, hold_s=0.0)
        landed = _at_rest_in(rec, kind)
        if not landed[-1]:
            return tuple(times), (f"player {i}: ends lying {classify_lying(rec.root_pose[-1, 3:])}, "
                                  f"its last goals held {LANDING_WAIT_S:.1f} s, not at rest {kind}")
        first_for_good = int(np.flatnonzero(~landed)[-1]) + 1 if not landed.all() else 0
        times.append(max(float(rec.t[first_for_good]), end_s))
    return tuple(times), ""


def _held(tr: Trajectory, hold_s: float) -> Trajectory:
    """``tr`` with its last targets held ``hold_s`` longer, at its row spacing."""
    dt = float(tr.t[-1] - tr.t[-2])
    extra = tr.t[-1] + dt * np.arange(1, int(round(hold_s / dt)) + 1)
    return dataclasses.replace(tr, t=np.concatenate([tr.t, extra]), q=np.concatenate([tr.q, np.repeat(tr.q[-1:], len(extra), axis=0)]))


def author_turn_over(out_dir: Path, robot: Robot, turn: Strategy, landed: Landing, get_up_row: dict, get_up_trajectory: Trajectory,
                     players: list[Player]) -> tuple[dict | None, str]:
    """A turn-over followed by a get-up the robot has, as one library motion, written if proven.

    The turn as :func:`landing` played it (a momentum turn-over's goals clamped into the
    envelope) up to ``landed.landed_s``, the nominal body checked to lie at rest there, then a
    planned collision-free path (RRT-blossom, as ``rise`` plans) from where the nominal model
    (``players[0]``) lies then to the get-up's start,
    held ``ARRIVAL_SETTLE_S``, then the get-up's rows as proven on this robot (its retiming and
    adaptation included). Judged on the robustness ``players`` and proven on the ensemble as one
    motion, with the path and the get-up slowed by each of ``TURN_OVER_SLOWING`` in turn until
    one is (:func:`robot_rise.authoring.write.prove_for_library`). Writes its two
    files into ``out_dir`` (no index: the caller merges the row). The row carries the larger of
    the two strategies' combined variants and noisy replays, and no timing window of its own.

    Returns:
        (its index row, "") or (None, why it is not written).

    Raises:
        ValueError: ``landed`` is not a landing (``landed_s`` None).
    """
    if landed.landed_s is None or landed.start is None or landed.turn is None:
        raise ValueError(f"{turn.name} did not land: {landed.reason}")
    spec, get_up, start = motion_specs(robot, (turn,))[0], str(get_up_row["name"]), landed.start
    keep = landed.turn.t <= landed.landed_s + 1e-9
    turned = dataclasses.replace(landed.turn, t=landed.turn.t[keep], q=landed.turn.q[keep])
    # where it lies once landed (nominal model), and a collision-free path from there to the
    # get-up's start: the landed limbs lie otherwise on every body (crossed feet, an arm under)
    rec = players[0].play(turned, hold_s=0.0)
    k = len(rec.t) - 1
    if not _at_rest_in(rec, turn.lands)[k]:  # a guard: landing timed this very turn on this body
        return None, f"cut at its landing, the turn does not lie at rest {turn.lands} by {landed.landed_s:.2f} s"
    lying = Posture(robot.name, rec.root_pose[k, :3], rec.root_pose[k, 3:], dict(zip(robot.joint_names, np.clip(rec.q[k], robot.joint_lower, robot.joint_upper))))
    checker = ValidityChecker(robot, PROOF_SCENE)
    goal = place_near(get_up_trajectory.start, lying, checker)
    planned = plan_trajectory(PlanningProblem(start=lying, goal=goal, checker=checker, budget_s=TURN_OVER_PLAN_BUDGET_S, seed=0),
                              report_clearance=False)
    if not planned.solved or planned.trajectory is None:
        return None, f"no path from where it lands to {get_up}'s start: {planned.result.reason or planned.result.status.value}"
    kfs = (*(dataclasses.replace(k, t_s=float(t)) for k, t in zip(spec.keyframes, landed.keyframe_times_s)), Keyframe(landed.landed_s, {}))
    name = f"{turn.name}_then_{get_up}"
    tried = []
    for path_factor, get_up_factor in TURN_OVER_SLOWING:
        path = dataclasses.replace(planned.trajectory, t=planned.trajectory.t * path_factor)
        approach = join_with_blend(turned, path, 0, blend_s=TURN_OVER_STEP_S)
        rows = dataclasses.replace(get_up_trajectory, t=get_up_trajectory.t * get_up_factor, root=None)
        tr = join_with_blend(approach, rows, 0, blend_s=ARRIVAL_SETTLE_S)
        extra = {"strategy": f"{turn.description}; then {get_up}", "lying": turn.lying, "keyframe_times_s": [k.t_s for k in kfs],
                 "turn_over": {"strategy": turn.name, "landed_s": landed.landed_s, "then": get_up,
                               "path_time_factor": path_factor, "get_up_time_factor": get_up_factor}}
        # lying, a limb rests on another (Wolfgang-OP's upper foot on its lower leg): touching is the proof's standard here, not any contact
        got = prove_for_library(robot, tr, start, players, clamp_lead=False, connect_until_s=kfs[spec.connect_keyframe].t_s,
                                report=extra, touching_ok=True)
        if not isinstance(got, str):
            break
        tried.append((f"path x{path_factor:g}, get-up x{get_up_factor:g}" if (path_factor, get_up_factor) != (1.0, 1.0) else "as planned") + f": {got}")
        log.info("%s: %s", name, tried[-1])
    else:
        return None, " | ".join(tried)
    tr, v, connect_until_s = got
    out_dir.mkdir(parents=True, exist_ok=True)
    write_motion(out_dir, name, tr, start)
    log.info("%s: %.2f s; %s", name, tr.duration_s, v.summary())
    noisy = max(turn.noise_replays, int(get_up_row.get("noise_replays", 0)))
    combined = max(turn.combined_variants, int(get_up_row.get("combined_variants", 0)))
    return {"name": name, "lying": turn.lying, "strategy": extra["strategy"], "trajectory": f"{name}.json", "start": f"{name}.start.json",
            "connect_until_s": connect_until_s, "duration_s": round(tr.duration_s, 3), "turn_over": turn.name,
            **({"combined_variants": combined} if combined else {}), **({"noise_replays": noisy} if noisy else {})}, ""
