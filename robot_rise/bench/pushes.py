"""The push benchmark: push the standing robot, let the guard do its work, report per push.

:func:`push_trials` pushes a standing robot (a :class:`Pusher`: the physics twin) and lets
:func:`robot_rise.live.guard.guard_step` handle each push: limp while falling, get up once fallen
and still. :func:`summarize_pushes` gives the figures. The stock OP3's scheme runs in the same loop
for comparison: ``robot_rise.live.KeyframePlanner`` with ``GetUpConfig(limp_when_falling=False,
fallen_pitch_deg=60, execute_unproven=True)``.
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from robot_rise.errors import RobotRiseError
from robot_rise.live.estimate import PostureEstimator
from robot_rise.live.fall import FallState, new_tracker, step
from robot_rise.live.getup import GetUpConfig, GetUpReport
from robot_rise.live.guard import GuardState, guard_step
from robot_rise.live.io import RobotIO, TruthSource
from robot_rise.live.planners import GetUpPlanner

__all__ = ["Pusher", "PushConfig", "PushOutcome", "push_trials", "summarize_pushes", "RISE_WITHIN_S"]

RISE_WITHIN_S = 20.0  # [s] RoboCup: a robot not up within 20 s of falling is declared incapable


class Pusher(Protocol):
    """Pushes the robot (the physics twin) and puts it back on its feet."""

    def push(self, force_heading_n: tuple[float, float], duration_s: float) -> None:
        """Push the torso horizontally: ``force_heading_n`` [N] in the robot's heading frame
        (x forward, y to its left), for ``duration_s`` [s] from now."""
        ...

    def reset_standing(self) -> None:
        """Put the robot back on its feet, at rest (servos still to be engaged)."""
        ...


@dataclass(frozen=True)
class PushConfig:
    """The push benchmark (ours).

    Attributes:
        force_n: [N] (low, high) of the uniform push strength, for ``duration_s`` at the torso: the
            twin's OP3 withstands 15 N (0.1 s) from the front and 20 N from the side
            (fall.FallConfig), and a 30 N push topples it every way; up to 60 N tests hard falls.
        duration_s: [s] how long each push lasts.
        stand_s: [s] standing (the detector's STANDING) this long before each push.
        withstood_s: [s] still standing this long after the push: it did not topple.
        episode_s: [s] longest episode (push to the end of the guard's get-up).
    """

    force_n: tuple[float, float] = (20.0, 60.0)
    duration_s: float = 0.1
    stand_s: float = 1.0
    withstood_s: float = 3.0
    episode_s: float = 90.0


@dataclass(frozen=True)
class PushOutcome:
    """One push and what the guard made of it (times from the IO clock).

    Attributes:
        push: 0-based index.
        heading_deg: push direction in the robot's heading frame [deg] (0 forward, 90 to its left).
        force_n: push strength [N] (for ``PushConfig.duration_s``).
        toppled: the robot fell (the detector read fallen-and-still).
        max_tilt_deg: the largest tilt before it lay still (or in the episode) [deg].
        lying: the lying kind once fallen-and-still (None: did not topple).
        first_command_after_s: from fallen-and-still (the first time, after the push) to the
            first rising command of any attempt [s].
        standing: standing again at the end.
        standing_after_s: from the push to standing confirmed [s].
        attempts: get-up attempts made.
        reasons: per attempt, why it did not stand (empty strings for the one that did).
        orientation_error_deg: per attempt, the estimate's orientation error against the truth [deg].
        plan_cpu_s: per attempt, CPU time of estimate + plan + proof [s].
    """

    push: int
    heading_deg: float
    force_n: float
    toppled: bool
    max_tilt_deg: float
    lying: str | None
    first_command_after_s: float | None
    standing: bool
    standing_after_s: float | None
    attempts: int
    reasons: tuple[str, ...] = ()
    orientation_error_deg: tuple[float, ...] = ()
    plan_cpu_s: tuple[float, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return {
            "push": self.push, "heading_deg": self.heading_deg, "force_n": self.force_n, "toppled": self.toppled,
            "max_tilt_deg": self.max_tilt_deg, "lying": self.lying, "first_command_after_s": self.first_command_after_s,
            "standing": self.standing, "standing_after_s": self.standing_after_s, "attempts": self.attempts,
            "reasons": list(self.reasons), "orientation_error_deg": list(self.orientation_error_deg),
            "plan_cpu_s": list(self.plan_cpu_s),
        }


def _stand_ready(io: RobotIO, pusher: Pusher, state: GuardState, config: GetUpConfig, stand_s: float) -> GuardState:
    """Standing, servos holding, detector STANDING for ``stand_s``; reset by the pusher if not."""
    for _ in range(3):
        if state.tracker.state is not FallState.STANDING or state.limp or state.gave_up:
            pusher.reset_standing()
            why = io.hold()
            if why:
                raise RobotRiseError(f"the servos do not hold the robot put back on its feet: {why}")
            state = GuardState(new_tracker(config.fall))
        t0 = io.now_s()
        while io.now_s() - t0 < stand_s + config.fall.upright_s + 1.0:
            state = replace(state, tracker=step(state.tracker, io.read_imu()))
            if state.tracker.state is FallState.STANDING and io.now_s() - state.tracker.since_s >= stand_s:
                return state
            io.sleep(config.cycle_s)
        state = replace(state, limp=True)  # not standing: reset again
    raise RobotRiseError("the robot does not stand after being put back on its feet three times")


def push_trials(io: RobotIO, planner: GetUpPlanner, estimator: PostureEstimator, pusher: Pusher, *, n: int,
                seed: int = 0, config: GetUpConfig = GetUpConfig(), push: PushConfig = PushConfig(),
                truth: TruthSource | None = None, on_push: Callable[[PushOutcome], None] | None = None,
                cpu_clock: Callable[[], float] = time.process_time) -> list[PushOutcome]:
    """Push the standing robot ``n`` times (random direction and strength, seeded) and let the
    guard handle each: go limp while falling, get up once fallen and still.

    Before each push the robot stands (put back on its feet by the pusher when the previous
    episode did not end standing). An episode ends when the guard's get-up ends (standing or
    given up), when the robot still stands ``push.withstood_s`` after the push, or after
    ``push.episode_s``.
    """
    rng = random.Random(seed)
    out: list[PushOutcome] = []
    state = GuardState(new_tracker(config.fall), limp=True)
    for i in range(n):
        heading = rng.uniform(-180.0, 180.0)
        force = rng.uniform(*push.force_n)
        state = _stand_ready(io, pusher, state, config, push.stand_s)
        t_push = io.now_s()
        h = math.radians(heading)
        pusher.push((force * math.cos(h), force * math.sin(h)), push.duration_s)
        max_tilt = 0.0
        lying: str | None = None
        report: GetUpReport | None = None
        left_standing = False
        while io.now_s() - t_push < push.episode_s:
            if state.tracker.state is FallState.FALLEN and lying is None:
                lying = state.tracker.estimate.lying
            state, events = guard_step(io, planner, estimator, state, config=config, truth=truth, cpu_clock=cpu_clock)
            report = next((ev.report for ev in events if ev.report is not None), None)
            if report is not None:
                break
            e = state.tracker.estimate
            if lying is None and math.isfinite(e.tilt_rad):
                max_tilt = max(max_tilt, math.degrees(e.tilt_rad))
            left_standing = left_standing or state.tracker.state is not FallState.STANDING
            if not left_standing and io.now_s() - t_push >= push.withstood_s:
                break
            io.sleep(config.cycle_s)
        toppled = (report is not None and bool(report.attempts)) or lying is not None
        first = report.attempts[0] if report is not None and report.attempts else None
        if first is not None and lying is None:
            lying = first.lying
        commanded = next((a.first_command_s for a in (report.attempts if report else ()) if a.first_command_s is not None), None)
        first_command_after = (commanded - first.fallen_s) if commanded is not None and first is not None and first.fallen_s is not None else None
        standing = report.standing if report is not None else state.tracker.state is FallState.STANDING
        standing_s = report.standing_s if report is not None else None
        outcome = PushOutcome(
            push=i, heading_deg=heading, force_n=force, toppled=toppled, max_tilt_deg=max_tilt, lying=lying,
            first_command_after_s=first_command_after,
            standing=standing, standing_after_s=(standing_s - t_push) if standing_s is not None else None,
            attempts=len(report.attempts) if report is not None else 0,
            reasons=tuple(a.why for a in report.attempts) if report is not None else (),
            orientation_error_deg=tuple(a.estimate.error.orientation_deg for a in (report.attempts if report else ())
                                        if a.estimate is not None and a.estimate.error is not None),
            plan_cpu_s=tuple(a.estimate_cpu_s + a.plan_cpu_s for a in (report.attempts if report else ())
                             if a.estimate is not None),
        )
        out.append(outcome)
        if on_push is not None:
            on_push(outcome)
    return out


def _percentile(values: Sequence[float], q: float) -> float | None:
    return float(np.percentile(np.asarray(values, dtype=float), q)) if len(values) else None


def _share(hits: int, total: int) -> float | None:
    return hits / total if total else None


def summarize_pushes(outcomes: Sequence[PushOutcome], *, within_s: float = RISE_WITHIN_S,
                     max_attempts: int = 3) -> dict[str, Any]:
    """The benchmark's figures over the pushes that toppled the robot, overall, for side falls
    (lying on a side once still) and for side pushes (60..120 deg either way), and by lying kind.

    Keys per group: ``n``, ``standing`` (share standing at the end), ``within_s`` (share standing
    within ``within_s`` of the push), ``within_attempts`` (share standing within
    ``max_attempts`` attempts), ``first_command_p50_s`` / ``p95_s`` / ``max_s``, ``standing_after_p50_s``
    / ``p95_s``, ``orientation_error_p95_deg``, ``orientation_within_3deg`` (share of estimates).
    """
    def group(rows: Sequence[PushOutcome]) -> dict[str, Any]:
        lat = [r.first_command_after_s for r in rows if r.first_command_after_s is not None]
        up = [r.standing_after_s for r in rows if r.standing_after_s is not None]
        errs = [e for r in rows for e in r.orientation_error_deg]
        return {
            "n": len(rows),
            "standing": _share(sum(r.standing for r in rows), len(rows)),
            "within_s": _share(sum(r.standing and r.standing_after_s is not None and r.standing_after_s <= within_s
                                   for r in rows), len(rows)),
            "within_attempts": _share(sum(r.standing and r.attempts <= max_attempts for r in rows), len(rows)),
            "first_command_p50_s": _percentile(lat, 50), "first_command_p95_s": _percentile(lat, 95),
            "first_command_max_s": max(lat) if lat else None,
            "standing_after_p50_s": _percentile(up, 50), "standing_after_p95_s": _percentile(up, 95),
            "orientation_error_p95_deg": _percentile(errs, 95),
            "orientation_within_3deg": _share(sum(e <= 3.0 for e in errs), len(errs)),
        }

    toppled = [r for r in outcomes if r.toppled]
    side_push = [r for r in toppled if 60.0 <= abs(r.heading_deg) <= 120.0]
    return {
        "pushes": len(outcomes),
        "toppled": len(toppled),
        "within_limit_s": within_s,
        "all": group(toppled),
        "side_falls": group([r for r in toppled if r.lying in ("left", "right")]),
        "side_pushes": group(side_push),
        "by_lying": {kind: group([r for r in toppled if r.lying == kind]) for kind in ("supine", "prone", "left", "right")},
    }
