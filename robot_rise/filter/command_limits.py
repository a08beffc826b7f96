"""The command limits the executor enforces, as a value of the core, and targets made to respect them.

The driver's safety layer (``drivers/safety.py``) passes every streamed target through two
clamps: into the joint limits of ``servos.toml``, then to a step per control cycle of
``max_velocity_rad_s / rate``. The executor (``drivers/executor.py``) samples the trajectory by
linear interpolation at cycle k's time ``k / rate`` (after the ``--speed`` time scale). A target
either clamp changes is not the target the filter proved: the robot then moves later and
otherwise than its proof says (``make demo`` clamped 81 of 612 cycles before this module).

:class:`CommandLimits` holds those numbers (rate, speed limit per joint, joint limits) so the
filter can take them as an input and record them in the proof (report key ``command_limits``);
:func:`conform` returns targets the executor streams unclamped; :func:`match_command_limits` is
the rule the executor's wiring applies before streaming ("proven under these limits?").

Why every segment, not every sample: linear interpolation is piecewise linear, so the change
between any two samples ``dt`` apart is at most the fastest segment speed crossed times ``dt``.
Segments no faster than the limit therefore never clamp at any rate and any sampling phase
(a stall re-anchors the executor's schedule), and slower ``--speed`` only lowers every speed.
The core cannot import ``drivers``: the defaults below repeat the driver's constants, and
``sim_tests/test_command_limits.py`` holds the two equal.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from robot_rise.errors import FormatError, RobotRiseError
from robot_rise.model import Robot
from robot_rise.trajectory import Trajectory

__all__ = [
    "CommandLimits",
    "LimitsMatch",
    "COMMAND_LIMITS_KEY",
    "DEFAULT_RATE_HZ",
    "DEFAULT_MAX_SPEED_RAD_S",
    "SPEED_MARGIN",
    "LIMIT_MARGIN_RAD",
    "command_limits_for",
    "command_limits_of",
    "conform",
    "match_command_limits",
]

COMMAND_LIMITS_KEY = "command_limits"  # the trajectory report's entry holding CommandLimits.to_dict()
DEFAULT_RATE_HZ = 100.0  # [Hz] = drivers.executor.DEFAULT_RATE_HZ (the executor's control rate)
DEFAULT_MAX_SPEED_RAD_S = 4.8  # [rad/s] = drivers.safety.MAX_VELOCITY_RAD_S (XM430-W350 no-load speed at 12 V)
# ours: conform() keeps every segment this fraction under the speed limit, so the trajectory
# file's rounding (6 decimals of s and rad) can never lift a segment onto the limit: a 10 ms
# cycle's step keeps 0.3 mrad of headroom at 3 rad/s against 2e-6 rad of rounding
SPEED_MARGIN = 0.01
# ours: conform() keeps targets this far inside the joint limits, more than the file's rounding
# of angles (5e-7 rad), so the executor's limit clamp never changes a rounded target
LIMIT_MARGIN_RAD = 1e-6
# [s] shorter stretches are float noise and the file's rounding (times and angles to 1e-6: a conformed
# trajectory written and read back conforms; SPEED_MARGIN's 1 % covers a segment that much too fast)
_STRETCH_MIN_S = 5e-6
_LIMIT_MATCH_RAD = 1e-6  # [rad] joint limits closer than this are the same limits (float round trips)


@dataclass(frozen=True)
class CommandLimits:
    """What the executor lets through: its control rate, speed limit and joint limits.

    Attributes:
        joint_names: joint order of the arrays, shape (n,).
        lower_rad: lower joint limits [rad], shape (n,) (``servos.toml`` ``min``).
        upper_rad: upper joint limits [rad], shape (n,) (``servos.toml`` ``max``).
        max_speed_rad_s: command speed limit per joint [rad/s], shape (n,); a scalar is
            broadcast. The step per cycle is this divided by ``rate_hz``.
        rate_hz: control rate the executor streams at [Hz].

    Raises:
        RobotRiseError: shapes disagree, a lower limit is not below its upper one, or a speed
            or the rate is not positive and finite.
    """

    joint_names: tuple[str, ...]
    lower_rad: np.ndarray
    upper_rad: np.ndarray
    max_speed_rad_s: np.ndarray | float = DEFAULT_MAX_SPEED_RAD_S
    rate_hz: float = DEFAULT_RATE_HZ

    def __post_init__(self) -> None:
        names = tuple(self.joint_names)
        n = len(names)
        lo = np.array(self.lower_rad, dtype=float)
        hi = np.array(self.upper_rad, dtype=float)
        speed = (np.full(n, float(self.max_speed_rad_s)) if np.ndim(self.max_speed_rad_s) == 0  # type: ignore[arg-type]
                 else np.array(self.max_speed_rad_s, dtype=float))
        if len(set(names)) != n or n == 0:
            raise RobotRiseError("command limits: joint names must be non-empty and distinct")
        for what, a in (("lower_rad", lo), ("upper_rad", hi), ("max_speed_rad_s", speed)):
            if a.shape != (n,) or not np.all(np.isfinite(a)):
                raise RobotRiseError(f"command limits: {what} must be {n} finite numbers, got shape {a.shape}")
        if np.any(lo >= hi):
            k = int(np.argmax(lo >= hi))
            raise RobotRiseError(f"command limits: {names[k]}: lower limit {lo[k]} is not below upper limit {hi[k]}")
        if np.any(speed <= 0):
            raise RobotRiseError(f"command limits: {names[int(np.argmin(speed))]}: speed limit must be positive")
        if not (self.rate_hz > 0 and math.isfinite(self.rate_hz)):
            raise RobotRiseError(f"command limits: rate {self.rate_hz} Hz must be positive")
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "rate_hz", float(self.rate_hz))
        for field, a in (("lower_rad", lo), ("upper_rad", hi), ("max_speed_rad_s", speed)):
            a.setflags(write=False)
            object.__setattr__(self, field, a)

    @property
    def max_step_rad(self) -> np.ndarray:
        """Largest command change per control cycle [rad], shape (n,)."""
        return np.asarray(self.max_speed_rad_s) / self.rate_hz

    def columns(self, joint_names: Sequence[str]) -> np.ndarray:
        """Indices into these limits' arrays for each of ``joint_names``, shape (len(joint_names),).

        Raises:
            RobotRiseError: a joint has no limits here.
        """
        index = {j: k for k, j in enumerate(self.joint_names)}
        missing = [j for j in joint_names if j not in index]
        if missing:
            raise RobotRiseError(f"command limits have no joint {', '.join(missing)}; "
                                 f"joints: {', '.join(self.joint_names)}")
        return np.array([index[j] for j in joint_names], dtype=int)

    def to_dict(self) -> dict[str, Any]:
        """The report entry: rate, speed limit (one number when every joint shares it), and
        the joint limits by joint name."""
        speed = np.asarray(self.max_speed_rad_s)
        return {
            "rate_hz": self.rate_hz,
            "max_speed_rad_s": float(speed[0]) if np.all(speed == speed[0])
            else {j: float(v) for j, v in zip(self.joint_names, speed)},
            "lower_rad": {j: float(v) for j, v in zip(self.joint_names, self.lower_rad)},
            "upper_rad": {j: float(v) for j, v in zip(self.joint_names, self.upper_rad)},
        }

    @classmethod
    def from_dict(cls, obj: Any, *, where: str = "command_limits") -> CommandLimits:
        """Read :meth:`to_dict`'s entry back.

        Raises:
            FormatError: naming the missing or mistyped field.
        """
        if not isinstance(obj, Mapping):
            raise FormatError(f"{where}: expected an object with rate_hz, max_speed_rad_s, lower_rad, upper_rad")
        for key in ("rate_hz", "max_speed_rad_s", "lower_rad", "upper_rad"):
            if key not in obj:
                raise FormatError(f"{where}: missing field {key!r}")
        lower, upper = (_by_joint(obj[k], f"{where}.{k}") for k in ("lower_rad", "upper_rad"))
        if list(lower) != list(upper):
            raise FormatError(f"{where}: lower_rad and upper_rad must name the same joints in the same order")
        names = tuple(lower)
        raw_speed = obj["max_speed_rad_s"]
        if isinstance(raw_speed, Mapping):
            by_joint = _by_joint(raw_speed, f"{where}.max_speed_rad_s")
            if set(by_joint) != set(names):
                raise FormatError(f"{where}: max_speed_rad_s must name the joints of lower_rad")
            speed: np.ndarray | float = np.array([by_joint[j] for j in names])
        else:
            speed = _number(raw_speed, f"{where}.max_speed_rad_s")
        try:
            return cls(names, np.array(list(lower.values())), np.array(list(upper.values())), speed,
                       _number(obj["rate_hz"], f"{where}.rate_hz"))
        except FormatError:
            raise
        except RobotRiseError as e:
            raise FormatError(f"{where}: {str(e).removeprefix('command limits: ')}") from None


def _number(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise FormatError(f"{where} must be a number, got {v!r}")
    return float(v)


def _by_joint(v: Any, where: str) -> dict[str, float]:
    if not isinstance(v, Mapping) or not v:
        raise FormatError(f"{where} must be an object of numbers by joint name")
    return {str(k): _number(x, f"{where}.{k}") for k, x in v.items()}


def command_limits_for(robot: Robot, *, rate_hz: float = DEFAULT_RATE_HZ,
                       max_speed_rad_s: float | np.ndarray = DEFAULT_MAX_SPEED_RAD_S) -> CommandLimits:
    """The limits the executor enforces on ``robot`` by default: its ``servos.toml`` joint
    limits (the servo map's ``lower_rad``/``upper_rad``), the driver's speed limit and rate."""
    return CommandLimits(robot.joint_names, np.array([s.lower for s in robot.servos]),
                         np.array([s.upper for s in robot.servos]), max_speed_rad_s, rate_hz)


def command_limits_of(report: Mapping[str, Any]) -> CommandLimits | None:
    """The command limits a trajectory was proven under (its report's ``command_limits``).

    Returns:
        None for a report without the entry (a file from before the limits were recorded).

    Raises:
        FormatError: the entry is malformed.
    """
    if COMMAND_LIMITS_KEY not in report:
        return None
    return CommandLimits.from_dict(report[COMMAND_LIMITS_KEY], where=f"report.{COMMAND_LIMITS_KEY}")


def conform(trajectory: Trajectory, limits: CommandLimits) -> Trajectory:
    """Targets the executor streams without clamping, by the shape of ``trajectory``.

    Every target is kept inside the joint limits (by :data:`LIMIT_MARGIN_RAD`; a target beyond
    one is clipped there, as the executor would); every segment faster than
    ``(1 - SPEED_MARGIN) x max_speed_rad_s`` on some joint is slowed to that speed: its duration
    grows, the rows (the path) stay. A time-scaled segment changes the timing, never the shape.

    Args:
        trajectory: the targets; each joint must have limits in ``limits``.
        limits: the executor's limits.

    Returns:
        ``trajectory`` itself when it already conforms; otherwise a copy with clipped rows and
        stretched times (same start, report and root rows).

    Raises:
        RobotRiseError: a trajectory joint has no limits.
    """
    cols = limits.columns(trajectory.joint_names)
    lo = limits.lower_rad[cols]
    hi = limits.upper_rad[cols]
    margin = np.minimum(LIMIT_MARGIN_RAD, 0.25 * (hi - lo))
    q = np.clip(trajectory.q, lo + margin, hi - margin)
    t = trajectory.t
    speed = np.asarray(limits.max_speed_rad_s)[cols] * (1.0 - SPEED_MARGIN)
    needed_s = np.max(np.abs(np.diff(q, axis=0)) / speed, axis=1, initial=0.0)
    extra_s = needed_s - np.diff(t)  # each too-fast segment's stretch [s]
    extra_s = np.where(extra_s > _STRETCH_MIN_S, extra_s, 0.0)
    if np.any(extra_s > 0):  # times before the first stretch stay exact
        t = t + np.concatenate([[0.0], np.cumsum(extra_s)])
    elif np.array_equal(q, trajectory.q):
        return trajectory
    return Trajectory(trajectory.robot, trajectory.joint_names, t, q, trajectory.start, dict(trajectory.report),
                      trajectory.root)


@dataclass(frozen=True)
class LimitsMatch:
    """Whether an execution keeps the limits a trajectory was proven under
    (:func:`match_command_limits`).

    Attributes:
        ok: it does (nothing streamed will be clamped by limits the proof did not see).
        reason: why not, one line (empty when ok).
        hint: what to do about it, one line.
    """

    ok: bool
    reason: str = ""
    hint: str = ""


def match_command_limits(proven: CommandLimits, executing: CommandLimits, *, speed: float = 1.0) -> LimitsMatch:
    """May a trajectory proven under ``proven`` be streamed under ``executing`` at ``speed``?

    The rate and the speed limit must be the proof's (another rate or step limit streams other
    commands than the proven ones), the joint limits too (per joint, within 1e-6 rad), and
    ``speed`` (the executor's time scale) at most 1: slower only lowers every segment's speed,
    faster would move the joints faster than proven and into the step limit.
    """
    if speed > 1.0 + 1e-12:
        return LimitsMatch(False, f"--speed {speed:g} would stream the trajectory faster than it was proven",
                           "use --speed 1 or below (slower never reaches the step limit)")
    if not math.isclose(proven.rate_hz, executing.rate_hz, rel_tol=1e-9):
        return LimitsMatch(False, f"the trajectory was proven for a {proven.rate_hz:g} Hz control rate, "
                                  f"not the {executing.rate_hz:g} Hz requested",
                           f"use --rate {proven.rate_hz:g}, or prove it again for {executing.rate_hz:g} Hz")
    try:
        cols = executing.columns(proven.joint_names)
    except RobotRiseError:
        missing = sorted(set(proven.joint_names) - set(executing.joint_names))
        return LimitsMatch(False, f"the trajectory was proven with limits for joints the servo map lacks: "
                                  f"{', '.join(missing)}", "is it for this robot? (servos.toml)")
    ours = np.asarray(executing.max_speed_rad_s)[cols]
    theirs = np.asarray(proven.max_speed_rad_s)
    if np.any(np.abs(ours - theirs) > 1e-9 * theirs):
        k = int(np.argmax(np.abs(ours - theirs)))
        return LimitsMatch(False, f"the trajectory was proven under a {theirs[k]:g} rad/s command speed limit, "
                                  f"the executor enforces {ours[k]:g} rad/s at {proven.joint_names[k]}",
                           "prove it again under the executor's limits (robot-rise rise), or execute with the "
                           "limits it was proven under")
    for side, mine, proof in (("lower", executing.lower_rad[cols], proven.lower_rad),
                              ("upper", executing.upper_rad[cols], proven.upper_rad)):
        if np.any(np.abs(mine - proof) > _LIMIT_MATCH_RAD):
            k = int(np.argmax(np.abs(mine - proof)))
            return LimitsMatch(False, f"the trajectory was proven with {side} limit {proof[k]:.4f} rad at "
                                      f"{proven.joint_names[k]}, servos.toml says {mine[k]:.4f} rad",
                               "the servo map changed since the proof: prove it again for this robot")
    return LimitsMatch(True)
