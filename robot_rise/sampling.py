"""Physically settled random lying postures.

A sample: random joint angles within limits, a root orientation of the asked kind (supine,
prone, lying on the left or right side) with random yaw and a small random tilt, placed just
above the ground, then dropped and simulated with the servos holding the sampled angles until
the robot is at rest. What comes to rest is the posture (so it is physically real, including
the sag of the limbs under load). Note that a servo holding a loaded joint deflects by
load / stiffness (up to its saturation error, ~0.22 rad for an XM430 at the default gain), so
commanding a posture's own angles lets loaded joints sag by that much again. Samples are discarded, with a counted reason, when the sampled
angles self-collide, the robot does not come to rest, it rolls into another kind of lying, or
the rest posture is invalid.

Deterministic: attempt i of a run with seed s draws from ``default_rng([s, kind, i])``.
"""

from __future__ import annotations

import logging
import math
import os
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import mujoco
import numpy as np

from robot_rise.errors import RobotRiseError
from robot_rise.model import Robot, compose, model_index
from robot_rise.posture import Posture, posture_from_qpos, quat_multiply
from robot_rise.validity import ValidityChecker

__all__ = [
    "LyingKind",
    "LYING_KINDS",
    "SampleResult",
    "sample_lying",
    "sample_lying_postures",
    "classify_lying",
    "settle",
    "SettleResult",
]

log = logging.getLogger(__name__)

LyingKind = Literal["supine", "prone", "left", "right"]
LYING_KINDS: tuple[LyingKind, ...] = ("supine", "prone", "left", "right")

DROP_CLEARANCE_M = 0.01  # the lowest point starts this far above the ground
MAX_TILT_RAD = math.radians(20.0)  # random tilt around the kind's nominal orientation
SETTLE_MAX_S = 5.0  # give up if not at rest by then
SETTLE_MIN_S = 0.5  # never call it settled before this (the drop)
SETTLE_HOLD_S = 0.3  # velocities must stay small this long
SETTLE_SPEED_RAD_S = 0.02  # "at rest": every generalised velocity below this
STABLE_ROUNDS = 3  # re-settles holding its own angles before a posture counts as tipping
STABLE_ROOT_MOVE_M = 0.005  # root movement below which a re-settle "stays put"
# The robot is no longer lying once its head axis is within 60 degrees of vertical.
LYING_AXIS_COS = 0.5


def _axis_angle_quat(axis: np.ndarray, angle: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])


# Nominal root orientation per kind (w, x, y, z). Robot frame: x forward, y left, z up (head).
_KIND_QUAT: dict[str, np.ndarray] = {
    "supine": _axis_angle_quat(np.array([0.0, 1.0, 0.0]), -math.pi / 2),  # front (x) up
    "prone": _axis_angle_quat(np.array([0.0, 1.0, 0.0]), math.pi / 2),  # front (x) down
    "left": _axis_angle_quat(np.array([1.0, 0.0, 0.0]), -math.pi / 2),  # left side (y) down
    "right": _axis_angle_quat(np.array([1.0, 0.0, 0.0]), math.pi / 2),  # right side (y) down
}


def classify_lying(root_quat_wxyz: np.ndarray) -> str:
    """Which way a robot lies, from its root orientation: supine, prone, left, right or upright."""
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(root_quat_wxyz, dtype=float))
    mat = mat.reshape(3, 3)
    front_z, left_z, up_z = mat[2, 0], mat[2, 1], mat[2, 2]
    if up_z > LYING_AXIS_COS:
        return "upright"
    # The dominant horizontal body axis decides: within 45 degrees of a nominal kind.
    if abs(front_z) >= abs(left_z):
        return "supine" if front_z > 0 else "prone"
    return "left" if left_z < 0 else "right"


@dataclass(frozen=True)
class SettleResult:
    """Outcome of dropping a posture: the rest qpos, whether it came to rest, time taken [s]."""

    qpos: np.ndarray
    settled: bool
    time_s: float
    max_speed: float


def settle(m: mujoco.MjModel, qpos: np.ndarray, targets: np.ndarray, actuators: np.ndarray) -> SettleResult:
    """Simulate from ``qpos`` at rest with the servos holding ``targets`` [rad] until at rest."""
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    d.ctrl[actuators] = targets
    mujoco.mj_forward(m, d)
    dt = m.opt.timestep
    still = 0.0
    speed = np.inf
    steps = int(SETTLE_MAX_S / dt)
    for k in range(steps):
        mujoco.mj_step(m, d)
        if k % 10:
            continue
        speed = float(np.max(np.abs(d.qvel)))
        if not np.isfinite(speed):
            return SettleResult(d.qpos.copy(), False, d.time, speed)
        still = still + 10 * dt if speed < SETTLE_SPEED_RAD_S else 0.0
        if d.time >= SETTLE_MIN_S and still >= SETTLE_HOLD_S:
            return SettleResult(d.qpos.copy(), True, d.time, speed)
    return SettleResult(d.qpos.copy(), False, d.time, speed)


def _settle_holding_own_angles(m: mujoco.MjModel, rest: SettleResult, idx) -> SettleResult | None:
    """Re-settle with the servos commanding the rest angles themselves, until it stays put.

    A posture file holds the angles at rest; replaying it commands those angles, and loaded
    joints sag again. A posture propped on its limbs may then tip into another one. We accept
    a posture only once commanding its own angles moves the root less than STABLE_ROOT_MOVE_M
    (the written posture is the last rest), and give up after STABLE_ROUNDS.
    """
    for _ in range(STABLE_ROUNDS):
        nxt = settle(m, rest.qpos, rest.qpos[idx.qpos_joints], idx.actuators)
        if not nxt.settled:
            return None
        moved = float(np.linalg.norm(nxt.qpos[idx.qpos_root[:3]] - rest.qpos[idx.qpos_root[:3]]))
        rest = nxt
        if moved < STABLE_ROOT_MOVE_M:
            return rest
    return None


@dataclass(frozen=True)
class SampleResult:
    """Postures that came to rest, their kinds, and why other attempts were discarded."""

    postures: tuple[Posture, ...]
    kinds: tuple[str, ...]
    attempts: int
    discarded: dict[str, int] = field(default_factory=dict)


def sample_lying(
    robot: Robot,
    kind: LyingKind | Literal["any"],
    n: int,
    seed: int,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    max_attempts: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> SampleResult:
    """Sample ``n`` settled lying postures of a kind.

    Args:
        robot: the robot.
        kind: supine, prone, left, right, or any (the i-th posture is supine, prone, left, right for i % 4 = 0..3).
        n: how many postures to return.
        seed: random seed.
        scene: scene to settle in (default flat ground).
        max_attempts: give up after this many attempts (default 1000 * n: a robot with many
            collision shapes, e.g. Wolfgang-OP, has 96 % of its uniformly sampled angles
            self-colliding; those are rejected before any physics, so they cost little).
        progress: called as progress(done, n) after each accepted posture.

    Raises:
        RobotRiseError: fewer than n postures after max_attempts (names the discard reasons).
    """
    if kind != "any" and kind not in LYING_KINDS:
        raise RobotRiseError(f"unknown lying kind {kind!r}; choose from {', '.join(LYING_KINDS)}, any")
    if n < 0:
        raise RobotRiseError("n must be >= 0")
    m = compose(robot, scene, with_actuators=True)
    idx = model_index(m, robot)
    checker = ValidityChecker(robot, scene)
    free_checker = ValidityChecker(robot, None)  # robot alone: self-collision of the sampled angles
    limit = max_attempts if max_attempts is not None else 1000 * max(n, 1)
    postures: list[Posture] = []
    kinds: list[str] = []
    discarded: Counter[str] = Counter()
    attempt = 0
    while len(postures) < n and attempt < limit:
        want = LYING_KINDS[len(postures) % 4] if kind == "any" else kind
        rng = np.random.default_rng([seed, LYING_KINDS.index(want), attempt])
        attempt += 1
        joints = rng.uniform(robot.joint_lower, robot.joint_upper)
        yaw = _axis_angle_quat(np.array([0.0, 0.0, 1.0]), rng.uniform(-math.pi, math.pi))
        tilt_axis = np.array([*rng.normal(size=2), 0.0])
        tilt = _axis_angle_quat(tilt_axis, rng.uniform(0.0, MAX_TILT_RAD))
        quat = quat_multiply(yaw, quat_multiply(tilt, _KIND_QUAT[want]))
        q = m.qpos0.copy()
        q[idx.qpos_root[3:]] = quat
        q[idx.qpos_joints] = joints
        q[idx.qpos_root[:3]] = [0.0, 0.0, 1.0]
        fq = free_checker.model.qpos0.copy()
        fq[free_checker.index.qpos_root] = q[idx.qpos_root]
        fq[free_checker.index.qpos_joints] = joints
        if not free_checker.is_valid_qpos(fq):
            discarded["sampled angles self-collide"] += 1
            continue
        q[idx.qpos_root[2]] += DROP_CLEARANCE_M - checker.lowest_point_z(q)
        rest = settle(m, q, joints, idx.actuators)
        if not rest.settled:
            discarded["did not come to rest"] += 1
            continue
        rest = _settle_holding_own_angles(m, rest, idx)
        if rest is None:
            discarded["tips over when holding its own angles"] += 1
            continue
        rq = rest.qpos.copy()
        got = classify_lying(rq[idx.qpos_root[3:]])
        if got != want:
            discarded[f"rolled to {got}"] += 1
            continue
        rq[idx.qpos_joints] = np.clip(rq[idx.qpos_joints], robot.joint_lower, robot.joint_upper)
        report = checker.check_qpos(rq)
        if not report.valid:
            discarded["rest posture invalid: " + report.reasons()[0].split(":")[0]] += 1
            continue
        rq[idx.qpos_root[3:]] /= np.linalg.norm(rq[idx.qpos_root[3:]])
        postures.append(posture_from_qpos(robot, idx, rq))
        kinds.append(got)
        if progress is not None:
            progress(len(postures), n)
    if len(postures) < n:
        why = ", ".join(f"{k}: {v}" for k, v in discarded.most_common()) or "none"
        raise RobotRiseError(
            f"only {len(postures)} of {n} {kind} postures after {attempt} attempts (discarded: {why})",
            hint="raise --max-attempts or try another seed",
        )
    log.info("sampled %d %s postures in %d attempts; discarded %s", n, kind, attempt, dict(discarded))
    return SampleResult(tuple(postures), tuple(kinds), attempt, dict(discarded))


def sample_lying_postures(
    robot: Robot,
    kind: LyingKind | Literal["any"],
    n: int,
    *,
    seed: int,
    scene: str | os.PathLike[str] | None = "flat",
) -> list[Posture]:
    """``n`` settled lying postures of a kind (the public face of :func:`sample_lying`, which also
    says why attempts were discarded).

    Raises:
        RobotRiseError: fewer than n postures came to rest (names the discard reasons).
    """
    return list(sample_lying(robot, kind, n, seed, scene=scene).postures)

