"""The safety layer: pure functions every command goes through, never bypassed.

- Targets are clamped to the joint limits, then to a per-cycle step (velocity limit).
- A trajectory whose first target is far from the present posture is refused unless a slow
  approach from the present posture is requested (:func:`check_start`, :func:`approach_path`).
- Each cycle's feedback is judged by :func:`evaluate_feedback`: tracking error, hardware error
  bits, temperature, input voltage, consecutive communication failures.
- Tracking is watched either against the last command (an absolute ``max_tracking_error_rad``)
  or, when the caller knows where the joints should be (a proof's prediction), against
  :class:`ExpectedPositions` by :func:`evaluate_expected`: a per-joint tolerance held for a
  short debounce.
- Stop policies: hold the present position, or go limp slowly (Goal PWM ramps to zero, then
  torque off). Never a jump: a stop target is always the present position.

All angles in [rad], arrays in servo-map order, shape (n,) unless stated.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.control_table import HardwareErrorBits
from drivers.errors import SafetyError

__all__ = [
    "MAX_VELOCITY_RAD_S",
    "MAX_TRACKING_ERROR_RAD",
    "SafetyLimits",
    "voltage_limits_for_supply",
    "EXPECTED_DEBOUNCE_S",
    "ExpectedPositions",
    "evaluate_expected",
    "band_deviation",
    "TILT_DEBOUNCE_S",
    "ExpectedTilt",
    "evaluate_tilt",
    "StopPolicy",
    "FaultKind",
    "Fault",
    "StartCheck",
    "LIMIT_TOLERANCE_RAD",
    "LimitCheck",
    "check_limits",
    "clamp_to_limits",
    "clamp_step",
    "safe_target",
    "check_start",
    "approach_path",
    "evaluate_feedback",
    "limp_pwm_ramp",
    "require_inside_limits",
]

FloatArray = NDArray[np.float64]

# The command speed limit: every streamed target moves at most this x the cycle period from the
# previous one. The core's robot_rise.filter.command_limits.DEFAULT_MAX_SPEED_RAD_S repeats it
# (the filter proves trajectories under it; sim_tests/test_command_limits.py holds them equal).
# 4.8 rad/s is the XM430-W350's no-load speed at 12 V (46 rpm, datasheet): a command faster than
# the servo can turn only builds up tracking error, so this lets every feasible motion through and
# still stops a jump (0.048 rad per 100 Hz cycle).
MAX_VELOCITY_RAD_S = 4.8  # [rad/s]
MAX_TRACKING_ERROR_RAD = 0.35  # [rad] |present - last command| that aborts when no prediction is watched
EXPECTED_DEBOUNCE_S = 0.03  # [s] a deviation from the expected positions must last this long (3 cycles at 100 Hz)
# [s] the torso must stay off its expected tilt this long to be falling: longer than the joints'
# debounce, since the IMU's fused orientation lags and rings after an impact (a hand landing)
TILT_DEBOUNCE_S = 0.1


class StopPolicy(enum.Enum):
    """What the servos do after an abort, Ctrl-C or the end of a trajectory."""

    HOLD = "hold"  # goal = present position, torque stays on
    LIMP = "limp"  # goal = present, Goal PWM ramps to 0 over the limp time, then torque off


class FaultKind(enum.Enum):
    TRACKING = "tracking error"
    HARDWARE = "hardware error"
    TEMPERATURE = "temperature"
    VOLTAGE = "input voltage"
    COMMUNICATION = "communication"
    INTERRUPTED = "interrupted"
    DEADLINE = "deadline"
    HOST = "host error"
    FALLING = "falling"


@dataclass(frozen=True)
class Fault:
    """One reason to stop.

    Attributes:
        kind: :class:`FaultKind`.
        index: joint index in map order (-1 for the whole bus).
        value: measured value (rad, degC, V, count ...).
        limit: the threshold it crossed.
        message: one human line.
    """

    kind: FaultKind
    index: int
    value: float
    limit: float
    message: str


@dataclass(frozen=True)
class SafetyLimits:
    """Thresholds of the safety layer.

    Attributes:
        lower_rad: lower joint limits [rad], shape (n,).
        upper_rad: upper joint limits [rad], shape (n,).
        max_velocity_rad_s: command step limit per cycle = this x cycle period [rad/s].
        max_tracking_error_rad: abort when |present - last command| exceeds it [rad].
        start_tolerance_rad: largest first-target distance from the present posture accepted
            without an approach [rad].
        approach_velocity_rad_s: speed of an approach move [rad/s] (sets its minimum duration).
        max_temperature_c: abort above this [degC].
        min_voltage_v: abort below this input voltage [V].
        max_voltage_v: abort above this input voltage [V].
        max_comm_failures: abort after this many consecutive cycles without a servo's data.
    """

    lower_rad: FloatArray
    upper_rad: FloatArray
    max_velocity_rad_s: float = MAX_VELOCITY_RAD_S
    max_tracking_error_rad: float = MAX_TRACKING_ERROR_RAD
    start_tolerance_rad: float = 0.1
    approach_velocity_rad_s: float = 0.3
    max_temperature_c: float = 70.0
    min_voltage_v: float = 10.0
    max_voltage_v: float = 14.8
    max_comm_failures: int = 5

    def __post_init__(self) -> None:
        lo = np.array(self.lower_rad, dtype=float)
        hi = np.array(self.upper_rad, dtype=float)
        if lo.shape != hi.shape or lo.ndim != 1:
            raise SafetyError(f"limit arrays must have the same shape (n,), got {lo.shape} and {hi.shape}")
        if np.any(lo >= hi):
            raise SafetyError("every lower limit must be below its upper limit")
        for name in ("max_velocity_rad_s", "max_tracking_error_rad", "approach_velocity_rad_s"):
            if not getattr(self, name) > 0:
                raise SafetyError(f"{name} must be positive")
        if self.max_comm_failures < 1:
            raise SafetyError("max_comm_failures must be >= 1")
        lo.setflags(write=False)
        hi.setflags(write=False)
        object.__setattr__(self, "lower_rad", lo)
        object.__setattr__(self, "upper_rad", hi)

    def max_step_rad(self, dt_s: float) -> float:
        """Largest command change in one cycle of ``dt_s`` [s]."""
        return self.max_velocity_rad_s * dt_s


_LIMITS_SUPPLY_V = 12.0  # the supply SafetyLimits' voltage defaults are set for (a 3S LiPo)


def voltage_limits_for_supply(supply_v: float) -> dict[str, float]:
    """``min_voltage_v`` / ``max_voltage_v`` of :class:`SafetyLimits` for a bus whose servos run
    on ``supply_v`` (the servo map's ``[bus] supply_voltage_v``): the 12 V defaults scaled, so a
    4S LiPo's 14.8 V aborts below 12.3 V and above 18.3 V instead of refusing a charged battery."""
    k = supply_v / _LIMITS_SUPPLY_V
    return {"min_voltage_v": SafetyLimits.min_voltage_v * k, "max_voltage_v": SafetyLimits.max_voltage_v * k}


@dataclass(frozen=True)
class ExpectedPositions:
    """Where the joints should be while a trajectory runs (e.g. a proof's replay), in map order.

    Watched instead of the absolute tracking limit: a joint farther than its tolerance from the
    band between its expected position and its goals for ``debounce_s`` is a TRACKING fault
    (:func:`evaluate_expected`). The band, not the expected position alone: a servo that follows
    its goals more closely than the proof's loaded lag predicts (an unloaded servo, the robot on a
    stand; a bus whose servos are stiffer than the model) is not a fault; one that falls behind
    the prediction, or is pushed off past its goals, is.

    Attributes:
        t_s: trajectory time [s], shape (K,), strictly increasing (0 = the trajectory's first row).
        q_rad: expected positions [rad], shape (K, n).
        tolerance_rad: largest accepted |present - expected| per joint [rad], shape (n,).
        debounce_s: how long a joint may stay beyond its tolerance before it is a fault [s].
    """

    t_s: FloatArray
    q_rad: FloatArray
    tolerance_rad: FloatArray
    debounce_s: float = EXPECTED_DEBOUNCE_S

    def __post_init__(self) -> None:
        t = np.array(self.t_s, dtype=float)
        q = np.array(self.q_rad, dtype=float)
        tol = np.array(self.tolerance_rad, dtype=float)
        if t.ndim != 1 or t.size < 1 or q.ndim != 2 or q.shape[0] != t.size or tol.shape != (q.shape[1],):
            raise SafetyError(f"expected positions: shapes t{t.shape} q{q.shape} tolerance{tol.shape} disagree")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q)) and np.all(np.isfinite(tol))):
            raise SafetyError("expected positions contain NaN or infinite values")
        if np.any(np.diff(t) <= 0):
            raise SafetyError("expected positions: times must increase strictly")
        if np.any(tol <= 0) or not (self.debounce_s >= 0 and math.isfinite(self.debounce_s)):
            raise SafetyError("expected positions: tolerances must be positive and the debounce >= 0")
        for a in (t, q, tol):
            a.setflags(write=False)
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "q_rad", q)
        object.__setattr__(self, "tolerance_rad", tol)

    def debounce_cycles(self, dt_s: float) -> int:
        """Consecutive cycles of ``dt_s`` [s] beyond the tolerance that make a fault (at least 1)."""
        return max(1, int(math.ceil(self.debounce_s / dt_s - 1e-9)))


def band_deviation(q_present_rad: FloatArray, q_expected_rad: FloatArray, *q_goals_rad: FloatArray) -> FloatArray:
    """How far each present position lies outside the band from its expected position to its goals [rad]. Pure.

    The band spans the expected position and every goal given (the last goal sent and the one
    just sent: the servo moves from where the prediction has it towards them); inside it is 0.
    Without goals it is |present - expected|.
    """
    present, expected = np.asarray(q_present_rad, dtype=float), np.asarray(q_expected_rad, dtype=float)
    lo, hi = expected.copy(), expected.copy()
    for goal in q_goals_rad:
        lo, hi = np.minimum(lo, goal), np.maximum(hi, goal)
    return np.maximum(np.maximum(lo - present, present - hi), 0.0)


def evaluate_expected(q_present_rad: FloatArray, q_expected_rad: FloatArray, tolerance_rad: FloatArray,
                      valid: NDArray[np.bool_], beyond_cycles: NDArray[np.int64],
                      debounce_cycles: int, q_goals_rad: tuple[FloatArray, ...] = ()) -> tuple[NDArray[np.int64], list[Fault]]:
    """Judge one cycle's present positions against the band from the expected ones to the goals. Pure.

    Args:
        q_present_rad: present positions [rad] (NaN where not valid), shape (n,).
        q_expected_rad: expected positions [rad], shape (n,).
        q_goals_rad: the goals the servos were sent (last cycle's and this one's), each shape (n,):
            the band's other edge (:func:`band_deviation`); none: the expected positions alone.
        tolerance_rad: per joint [rad], shape (n,).
        valid: which entries were read this cycle, shape (n,).
        beyond_cycles: consecutive cycles each joint has been beyond its tolerance so far, shape (n,).
        debounce_cycles: that many in a row make a TRACKING fault.

    Returns:
        (the updated count per joint: +1 beyond, 0 within, unchanged where not read; the faults).
    """
    err = band_deviation(q_present_rad, q_expected_rad, *q_goals_rad)
    v = np.asarray(valid, dtype=bool)
    beyond = v & (err > tolerance_rad)
    count = np.where(beyond, beyond_cycles + 1, np.where(v, 0, beyond_cycles))
    faults = [Fault(FaultKind.TRACKING, int(i), float(err[i]), float(tolerance_rad[i]),
                    f"joint {i}: {err[i]:.3f} rad from its expected position for {int(count[i])} cycles "
                    f"(tolerance {tolerance_rad[i]:.3f} rad)")
              for i in np.flatnonzero(count >= debounce_cycles)]
    return count, faults


@dataclass(frozen=True)
class ExpectedTilt:
    """How far the torso should lean from the vertical while a trajectory runs (a proof's replay).

    The IMU read in each cycle gives the torso's tilt; farther than ``tolerance_rad`` from the
    expected one for ``debounce_s`` is a FALLING fault (:func:`evaluate_tilt`): the body is not
    moving as proven, and streaming on would only fight the fall.

    Attributes:
        t_s: trajectory time [s], shape (K,), strictly increasing (0 = the trajectory's first row).
        tilt_rad: expected angle between the torso's z axis and the world vertical [rad], shape (K,).
        tolerance_rad: largest accepted |present - expected| [rad].
        debounce_s: how long the tilt may stay beyond the tolerance before it is a fault [s].
    """

    t_s: FloatArray
    tilt_rad: FloatArray
    tolerance_rad: float
    debounce_s: float = TILT_DEBOUNCE_S

    def __post_init__(self) -> None:
        t = np.array(self.t_s, dtype=float)
        tilt = np.array(self.tilt_rad, dtype=float)
        if t.ndim != 1 or t.size < 1 or tilt.shape != t.shape:
            raise SafetyError(f"expected tilt: shapes t{t.shape} tilt{tilt.shape} disagree")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(tilt))) or np.any(np.diff(t) <= 0):
            raise SafetyError("expected tilt: times must increase strictly and every value be finite")
        if not (self.tolerance_rad > 0 and math.isfinite(self.tolerance_rad)) or not (self.debounce_s >= 0 and math.isfinite(self.debounce_s)):
            raise SafetyError("expected tilt: the tolerance must be positive and the debounce >= 0")
        for a in (t, tilt):
            a.setflags(write=False)
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "tilt_rad", tilt)

    def at(self, tau_s: float) -> float:
        """The expected tilt at trajectory time ``tau_s`` [s] (held at the ends) [rad]."""
        return float(np.interp(tau_s, self.t_s, self.tilt_rad))

    def debounce_cycles(self, dt_s: float) -> int:
        """Consecutive cycles of ``dt_s`` [s] beyond the tolerance that make a fault (at least 1)."""
        return max(1, int(math.ceil(self.debounce_s / dt_s - 1e-9)))


def evaluate_tilt(tilt_rad: float, expected_rad: float, tolerance_rad: float, beyond_cycles: int,
                  debounce_cycles: int) -> tuple[int, list[Fault]]:
    """Judge one cycle's torso tilt against the expected one. Pure.

    Args:
        tilt_rad: present tilt [rad] (NaN: not read this cycle: the count is kept).
        expected_rad: expected tilt [rad].
        tolerance_rad: the accepted distance [rad].
        beyond_cycles: consecutive cycles beyond the tolerance so far.
        debounce_cycles: that many in a row make a FALLING fault.

    Returns:
        (the updated count, the faults).
    """
    if not math.isfinite(tilt_rad):
        return beyond_cycles, []
    err = abs(tilt_rad - expected_rad)
    count = beyond_cycles + 1 if err > tolerance_rad else 0
    if count < debounce_cycles:
        return count, []
    return count, [Fault(FaultKind.FALLING, -1, err, tolerance_rad,
                         f"torso tilted {math.degrees(tilt_rad):.0f} deg where the proof expects "
                         f"{math.degrees(expected_rad):.0f} +- {math.degrees(tolerance_rad):.0f} deg, "
                         f"for {count} cycles: the body is not moving as proven")]


def clamp_to_limits(q_rad: FloatArray, lower_rad: FloatArray, upper_rad: FloatArray) -> FloatArray:
    """Clip ``q_rad`` (shape (..., n)) into [lower, upper]; NaN or inf is refused.

    Raises:
        SafetyError: a target is NaN or infinite.
    """
    q = np.asarray(q_rad, dtype=float)
    if not np.all(np.isfinite(q)):
        raise SafetyError("target contains NaN or infinite values")
    return np.minimum(np.maximum(q, lower_rad), upper_rad)


def clamp_step(q_target_rad: FloatArray, q_previous_rad: FloatArray, max_step_rad: float) -> FloatArray:
    """Limit each joint's change from ``q_previous_rad`` to ``max_step_rad`` [rad]."""
    step = np.clip(np.asarray(q_target_rad, dtype=float) - q_previous_rad, -max_step_rad, max_step_rad)
    return q_previous_rad + step


def safe_target(q_desired_rad: FloatArray, q_previous_rad: FloatArray, limits: SafetyLimits,
                dt_s: float) -> tuple[FloatArray, bool]:
    """The command actually sent: limits clamp, then step clamp.

    ``q_previous_rad`` must itself be within limits (it is the previous command, or the present
    posture clamped), so the result is within limits too.

    Returns:
        (command [rad] shape (n,), True if any clamp changed the desired target).
    """
    q_lim = clamp_to_limits(q_desired_rad, limits.lower_rad, limits.upper_rad)
    prev = clamp_to_limits(q_previous_rad, limits.lower_rad, limits.upper_rad)
    q_cmd = clamp_step(q_lim, prev, limits.max_step_rad(dt_s))
    clamped = bool(np.any(np.abs(q_cmd - np.asarray(q_desired_rad)) > 1e-12))
    return q_cmd, clamped


LIMIT_TOLERANCE_RAD = 0.02  # [rad] excursion beyond a joint limit still accepted (and clamped)


def require_inside_limits(q_rad: FloatArray, lower_rad: FloatArray, upper_rad: FloatArray,
                          labels: Sequence[str], refusal: str, *,
                          tolerance_rad: float = LIMIT_TOLERANCE_RAD) -> None:
    """Refuse (``SafetyError``: ``refusal``, then every such joint) when a present position
    ``q_rad`` (shape (n,)) lies beyond its limit by more than ``tolerance_rad``.

    What the driver commands is clamped into the limits, so from a joint posed (or pushed) far
    outside them the first command would be a jump to the limit at full speed.
    """
    q = np.asarray(q_rad, dtype=float)
    excess = np.maximum(q - upper_rad, lower_rad - q)
    outside = np.flatnonzero(excess > tolerance_rad)
    if outside.size:
        joints = "; ".join(f"{labels[k]} at {q[k]:.2f} rad is {excess[k]:.3f} rad outside its limits "
                           f"{lower_rad[k]:.2f}..{upper_rad[k]:.2f} rad" for k in outside)
        raise SafetyError(f"{refusal}: {joints}",
                          hint="with torque off (robot-rise servos torque off), move it inside its limits by hand, "
                               "or correct its limits in servos.toml")


@dataclass(frozen=True)
class LimitCheck:
    """How far a trajectory leaves the joint limits.

    Attributes:
        ok: no sample beyond a limit by more than the tolerance.
        max_excess_rad: largest excursion beyond a limit [rad] (0 if inside).
        joint_index: joint of that excursion (map order).
        sample_index: row of that excursion.
        value_rad: the sample's value [rad].
        limit_rad: the limit it crosses [rad].
    """

    ok: bool
    max_excess_rad: float
    joint_index: int
    sample_index: int
    value_rad: float
    limit_rad: float


def check_limits(q_rad: FloatArray, limits: SafetyLimits, *,
                 tolerance_rad: float = LIMIT_TOLERANCE_RAD) -> LimitCheck:
    """Preflight check of a whole trajectory ``q_rad`` (shape (T, n), map order) against the limits.

    The executor clamps every target anyway; a trajectory far outside the limits is a wrong
    file (other robot, other servo map, degrees for radians) and is better refused before
    anything moves.
    """
    q = np.asarray(q_rad, dtype=float)
    above = q - limits.upper_rad
    below = limits.lower_rad - q
    excess = np.maximum(above, below)
    if excess.size == 0:
        return LimitCheck(True, 0.0, -1, -1, 0.0, 0.0)
    row, col = np.unravel_index(int(np.argmax(excess)), excess.shape)
    worst = float(excess[row, col])
    limit = float(limits.upper_rad[col] if above[row, col] >= below[row, col] else limits.lower_rad[col])
    return LimitCheck(worst <= tolerance_rad, max(worst, 0.0), int(col), int(row), float(q[row, col]), limit)


@dataclass(frozen=True)
class StartCheck:
    """Distance between the present posture and the first target.

    Attributes:
        ok: within tolerance.
        max_error_rad: largest absolute joint difference [rad].
        worst_index: joint index of that difference.
        min_approach_s: shortest approach at the approach velocity [s].
    """

    ok: bool
    max_error_rad: float
    worst_index: int
    min_approach_s: float


def check_start(q_first_rad: FloatArray, q_present_rad: FloatArray, limits: SafetyLimits) -> StartCheck:
    """Compare the trajectory's first target with the present posture."""
    diff = np.abs(np.asarray(q_first_rad, dtype=float) - np.asarray(q_present_rad, dtype=float))
    if not np.all(np.isfinite(diff)):
        return StartCheck(False, math.inf, int(np.argmax(~np.isfinite(diff))), math.inf)
    worst = int(np.argmax(diff))
    err = float(diff[worst])
    return StartCheck(err <= limits.start_tolerance_rad, err, worst, err / limits.approach_velocity_rad_s)


def approach_path(q_present_rad: FloatArray, q_first_rad: FloatArray, duration_s: float,
                  limits: SafetyLimits) -> tuple[FloatArray, FloatArray]:
    """A minimum-jerk move from the present posture to the first target.

    The duration is raised to what the approach velocity allows (peak speed of a minimum-jerk
    move is 1.875 x distance / duration).

    Returns:
        (t [s] shape (K,), q [rad] shape (K, n)) sampled at 100 Hz, starting at t = 0.
    """
    q0 = clamp_to_limits(q_present_rad, limits.lower_rad, limits.upper_rad)
    q1 = clamp_to_limits(q_first_rad, limits.lower_rad, limits.upper_rad)
    dist = float(np.max(np.abs(q1 - q0))) if q0.size else 0.0
    duration = max(duration_s, 1.875 * dist / limits.approach_velocity_rad_s, 0.02)
    n = max(2, int(math.ceil(duration * 100)) + 1)
    t = np.linspace(0.0, duration, n)
    s = t / duration
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    return t, q0 + blend[:, None] * (q1 - q0)


def evaluate_feedback(limits: SafetyLimits, *, q_command_rad: FloatArray | None, q_present_rad: FloatArray,
                      valid: NDArray[np.bool_], hardware_error: NDArray[np.int64],
                      temperature_c: FloatArray, voltage_v: FloatArray,
                      consecutive_failures: NDArray[np.int64]) -> list[Fault]:
    """Judge one cycle's feedback. Pure: returns every fault found (empty list = carry on).

    Args:
        q_command_rad: the command the servos have been tracking [rad], shape (n,); None when
            tracking is watched against expected positions instead (:func:`evaluate_expected`).
        q_present_rad: present positions [rad] (NaN where not valid), shape (n,).
        valid: which entries were read this cycle, shape (n,).
        hardware_error: Hardware Error Status bits (or just the alert bit 0x80), shape (n,).
        temperature_c: [degC], shape (n,).
        voltage_v: [V], shape (n,).
        consecutive_failures: cycles in a row without data, per servo, shape (n,).
    """
    v = np.asarray(valid, dtype=bool)
    err = (np.zeros(len(v)) if q_command_rad is None
           else np.abs(np.asarray(q_present_rad) - np.asarray(q_command_rad)))
    temp = np.asarray(temperature_c)
    volt = np.asarray(voltage_v)
    # the usual cycle: every servo read and within every threshold. Equivalent to the checks
    # below finding nothing (a NaN fails these comparisons and takes the full path).
    if (v.all() and not np.any(hardware_error) and np.max(consecutive_failures) < limits.max_comm_failures
            and np.max(err) <= limits.max_tracking_error_rad and np.max(temp) <= limits.max_temperature_c
            and limits.min_voltage_v <= np.min(volt) and np.max(volt) <= limits.max_voltage_v):
        return []
    faults: list[Fault] = []
    for i in np.flatnonzero(consecutive_failures >= limits.max_comm_failures):
        faults.append(Fault(FaultKind.COMMUNICATION, int(i), float(consecutive_failures[i]),
                            limits.max_comm_failures,
                            f"joint {i}: no data for {int(consecutive_failures[i])} consecutive cycles"))
    for i in np.flatnonzero(v & (np.asarray(hardware_error) != 0)):
        bits = int(hardware_error[i])
        text = "alert bit set" if bits == 0x80 else HardwareErrorBits.describe(bits & 0x7F)
        faults.append(Fault(FaultKind.HARDWARE, int(i), bits, 0, f"joint {i}: hardware error ({text})"))
    for i in np.flatnonzero(v & (err > limits.max_tracking_error_rad)):
        faults.append(Fault(FaultKind.TRACKING, int(i), float(err[i]), limits.max_tracking_error_rad,
                            f"joint {i}: tracking error {err[i]:.3f} rad > {limits.max_tracking_error_rad} rad"))
    for i in np.flatnonzero(v & (temp > limits.max_temperature_c)):
        faults.append(Fault(FaultKind.TEMPERATURE, int(i), float(temp[i]), limits.max_temperature_c,
                            f"joint {i}: temperature {temp[i]:.0f} C > {limits.max_temperature_c} C"))
    bad_v = v & ((volt < limits.min_voltage_v) | (volt > limits.max_voltage_v))
    for i in np.flatnonzero(bad_v):
        faults.append(Fault(FaultKind.VOLTAGE, int(i), float(volt[i]),
                            limits.min_voltage_v if volt[i] < limits.min_voltage_v else limits.max_voltage_v,
                            f"joint {i}: input voltage {volt[i]:.1f} V outside "
                            f"{limits.min_voltage_v}..{limits.max_voltage_v} V"))
    return faults


def limp_pwm_ramp(pwm_limit: int | NDArray[np.int64], duration_s: float, dt_s: float) -> NDArray[np.int64]:
    """Goal PWM values for a slow limp: linear from ``pwm_limit`` to 0 over ``duration_s`` [s].

    Args:
        pwm_limit: one servo's PWM Limit, or each servo's, shape (n,).

    Returns:
        Integer PWM per cycle, shape (K,) (or (K, n)), last row 0.
    """
    n = max(1, int(math.ceil(duration_s / dt_s)))
    fraction = np.linspace(1.0, 0.0, n + 1)[1:]
    return np.rint(np.multiply.outer(fraction, pwm_limit)).astype(np.int64)
