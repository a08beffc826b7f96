"""Time parameterisation of a posture sequence within servo velocity and acceleration limits.

Paper 000 section 4.3 plays the smoothed curve at constant speed; that is the floor. We give
each joint a velocity limit (a fraction of its servo's no-load speed, robot_rise/servo.py) and
an acceleration limit (what the servo gives the joint's own inertia at that speed within the
torque-speed envelope: near time-optimal for unloaded limbs, the filter slowing loaded ones), and the planned root a linear and angular speed and acceleration limit,
and find the fastest progress along the path that keeps all of them (path-velocity
decomposition, Bobrow / Shin & McKay; the classic forward-backward pass over the waypoints):

1. the path is densified so that no joint moves more than ``max_step_rad`` per segment, and
   parameterised by its length s (each segment's largest step in units of the densification
   step, dimensionless; repeated waypoints dropped): a smoothed curve's samples are unevenly
   spaced, and with the waypoint index as s every change of spacing was a velocity jump the
   corner cap below slowed the body for (OP3, seed 1, three prone approaches: 1.38 / 1.33 /
   2.44 s timed by the index, 0.76 / 0.89 / 1.36 s by the length);
2. per segment i, of length L_i and direction u_i = dq_i / L_i, the path speed s' is capped by
   every axis: s' <= v_j / |u_ij|, and the path acceleration by s'' <= a_j / |u_ij|;
3. at each knot the change of direction caps the speed too (|u_i - u_i-1|_j s'^2 <= a_j L, L the
   mean of the two segments' lengths);
   a forward pass (accelerate from rest) and a backward pass (decelerate to rest) give the knot
   speeds; constant s'' within a segment gives its duration: a trapezoidal profile in the
   large, since cruise segments run at the cap;
4. rows at a fixed period follow each segment's exact trapezoid in s; then the limits are verified on the resampled
   rows by finite differences (what an executor interpolating the rows will command). Where
   the direction changes between segments make them exceed a limit, the whole time axis is
   stretched by the needed factor (velocity scales with 1/c, acceleration with 1/c^2) and
   checked again.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from robot_rise.constants import (
    CAUTIOUS_JOINT_ACCEL_RAD_S2,
    CAUTIOUS_ROOT_ACCEL_M_S2,
    CAUTIOUS_ROOT_ANGULAR_ACCEL_RAD_S2,
    CAUTIOUS_ROOT_ANGULAR_SPEED_RAD_S,
    CAUTIOUS_ROOT_SPEED_M_S,
    JOINT_SPEED_FRACTION_OF_NO_LOAD,
    ROOT_ACCEL_LIMIT_M_S2,
    ROOT_ANGULAR_ACCEL_LIMIT_RAD_S2,
    ROOT_ANGULAR_SPEED_LIMIT_RAD_S,
    ROOT_SPEED_LIMIT_M_S,
)
from robot_rise.model import Robot
from robot_rise.planning.problem import PostureSequence
from robot_rise.planning.space import quat_angle, slerp

__all__ = ["TimingLimits", "TimedPath", "time_parameterize", "measured_rates", "integrated_squared_jerk"]

log = logging.getLogger(__name__)

DEFAULT_SAMPLE_PERIOD_S = 0.02  # rows of the output every 20 ms (50 Hz)
# Ours: the trapezoid's acceleration steps become 0.1 s ramps (jerk <= ~2 a_max / 0.1 s); the
# paper's constant speed (000 section 4.3) and a plain trapezoid both have unbounded jerk.
JERK_WINDOW_S = 0.1


@dataclass(frozen=True)
class TimingLimits:
    """Velocity and acceleration limits.

    Attributes:
        joint_velocity_rad_s: per joint [rad/s], shape (n,).
        joint_accel_rad_s2: per joint [rad/s^2], shape (n,).
        root_velocity_m_s, root_accel_m_s2: root position limits [m/s], [m/s^2].
        root_angular_velocity_rad_s, root_angular_accel_rad_s2: root orientation limits.
    """

    joint_velocity_rad_s: np.ndarray
    joint_accel_rad_s2: np.ndarray
    root_velocity_m_s: float = ROOT_SPEED_LIMIT_M_S
    root_accel_m_s2: float = ROOT_ACCEL_LIMIT_M_S2
    root_angular_velocity_rad_s: float = ROOT_ANGULAR_SPEED_LIMIT_RAD_S
    root_angular_accel_rad_s2: float = ROOT_ANGULAR_ACCEL_LIMIT_RAD_S2

    @classmethod
    def from_robot(
        cls,
        robot: Robot,
        *,
        speed_fraction: float = JOINT_SPEED_FRACTION_OF_NO_LOAD,
        joint_accel_rad_s2: float | None = None,
    ) -> TimingLimits:
        """Per joint: ``speed_fraction`` x its servo's no-load speed, and the acceleration its servo
        gives the joint's own inertia at that speed within the envelope
        (``Robot.joint_accel_limits_rad_s2``), or ``joint_accel_rad_s2`` for every joint."""
        v = np.array([s.no_load_speed_at(robot.supply_voltage_v) for s in robot.servo_datasheets()]) * speed_fraction
        if joint_accel_rad_s2 is None:
            return cls(v, robot.joint_accel_limits_rad_s2(speed_fraction))
        return cls(v, np.full(robot.n_joints, float(joint_accel_rad_s2)))

    @classmethod
    def cautious(cls, robot: Robot) -> TimingLimits:
        """The slower timing a rise falls back on when the fast approach went off plan."""
        fast = cls.from_robot(robot, joint_accel_rad_s2=CAUTIOUS_JOINT_ACCEL_RAD_S2)
        return cls(fast.joint_velocity_rad_s, fast.joint_accel_rad_s2, CAUTIOUS_ROOT_SPEED_M_S, CAUTIOUS_ROOT_ACCEL_M_S2,
                   CAUTIOUS_ROOT_ANGULAR_SPEED_RAD_S, CAUTIOUS_ROOT_ANGULAR_ACCEL_RAD_S2)


@dataclass(frozen=True)
class TimedPath:
    """A posture sequence with times, resampled at a fixed period.

    Attributes:
        t: times [s], shape (T,), from 0, strictly increasing.
        root: root pose per row, shape (T, 7): x, y, z [m], qw, qx, qy, qz.
        joints: joint angles [rad], shape (T, n).
        joint_names: column order of ``joints``.
        max_velocity_ratio, max_accel_ratio: largest |rate| / limit over all rows and axes.
    """

    t: np.ndarray
    root: np.ndarray
    joints: np.ndarray
    joint_names: tuple[str, ...]
    max_velocity_ratio: float
    max_accel_ratio: float

    @property
    def duration_s(self) -> float:
        return float(self.t[-1])


def _densify(seq: PostureSequence, max_step_rad: float, max_step_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pos, quat, q = [seq.root_pos[0]], [seq.root_quat_wxyz[0]], [seq.joints[0]]
    for i in range(len(seq) - 1):
        dj = float(np.max(np.abs(seq.joints[i + 1] - seq.joints[i]))) if seq.joints.shape[1] else 0.0
        dp = float(np.linalg.norm(seq.root_pos[i + 1] - seq.root_pos[i]))
        da = 2.0 * float(quat_angle(seq.root_quat_wxyz[i], seq.root_quat_wxyz[i + 1]))
        m = max(1, int(np.ceil(max(dj / max_step_rad, da / max_step_rad, dp / max_step_m))))
        s = np.arange(1, m + 1) / m
        pos.extend(seq.root_pos[i] + s[:, None] * (seq.root_pos[i + 1] - seq.root_pos[i]))
        quat.extend(slerp(seq.root_quat_wxyz[i], seq.root_quat_wxyz[i + 1], s))
        q.extend(seq.joints[i] + s[:, None] * (seq.joints[i + 1] - seq.joints[i]))
    return np.array(pos), np.array(quat), np.array(q)


def measured_rates(t: np.ndarray, root: np.ndarray, joints: np.ndarray, limits: TimingLimits) -> tuple[float, float]:
    """Largest velocity and acceleration ratios (|rate| / limit) of rows by finite differences.

    Velocities are per interval (what linear interpolation between rows commands); accelerations
    are velocity changes over the mean of the two intervals.
    """
    if len(t) < 2:
        return 0.0, 0.0
    dt = np.diff(t)
    vj = np.diff(joints, axis=0) / dt[:, None]
    vp = np.linalg.norm(np.diff(root[:, :3], axis=0), axis=1) / dt
    va = 2.0 * quat_angle(root[:-1, 3:], root[1:, 3:]) / dt
    vr = max(
        float(np.max(np.abs(vj) / limits.joint_velocity_rad_s, initial=0.0)),
        float(np.max(vp, initial=0.0)) / limits.root_velocity_m_s,
        float(np.max(va, initial=0.0)) / limits.root_angular_velocity_rad_s,
    )
    # include the rest at both ends: velocity 0 before the first and after the last row
    zj = np.zeros((1, joints.shape[1]))
    vj_full = np.concatenate([zj, vj, zj])
    dtm = np.concatenate([[dt[0]], 0.5 * (dt[:-1] + dt[1:]), [dt[-1]]])
    aj = np.diff(vj_full, axis=0) / dtm[:, None]
    rootv = np.diff(root[:, :3], axis=0) / dt[:, None]
    rootv_full = np.concatenate([np.zeros((1, 3)), rootv, np.zeros((1, 3))])
    ap = np.linalg.norm(np.diff(rootv_full, axis=0), axis=1) / dtm
    va_full = np.concatenate([[0.0], va, [0.0]])
    aa = np.abs(np.diff(va_full)) / dtm  # magnitude change only: a lower bound on angular accel
    ar = max(
        float(np.max(np.abs(aj) / limits.joint_accel_rad_s2, initial=0.0)),
        float(np.max(ap, initial=0.0)) / limits.root_accel_m_s2,
        float(np.max(aa, initial=0.0)) / limits.root_angular_accel_rad_s2,
    )
    return vr, ar


def time_parameterize(
    seq: PostureSequence,
    robot: Robot,
    *,
    limits: TimingLimits | None = None,
    sample_period_s: float = DEFAULT_SAMPLE_PERIOD_S,
    max_step_rad: float = 0.01,
    max_step_m: float = 0.002,
    jerk_window_s: float = JERK_WINDOW_S,
) -> TimedPath:
    """Fastest timing of a posture sequence within the limits (see module docstring).

    Args:
        seq: the path (e.g. smoothed), K >= 1 waypoints, joints in ``robot.joint_names`` order.
        robot: for the servo limits when ``limits`` is None.
        limits: velocity and acceleration limits (default: from the robot's servos).
        sample_period_s: period of the output rows [s].
        max_step_rad, max_step_m: densification before timing [rad], [m].
        jerk_window_s: the trapezoid's speed is averaged over this window, bounding jerk (0: a
            plain trapezoid).

    Returns:
        TimedPath whose rows start and end at rest on the first and last posture and whose
        finite-difference rates are within the limits (ratios <= 1 + 1e-6; the time axis is
        stretched up to 20 times for it, and a warning logged if that does not do).
    """
    lim = limits if limits is not None else TimingLimits.from_robot(robot)
    pos, quat, q = _densify(seq, max_step_rad, max_step_m)
    # a repeated waypoint is a segment of no length: no direction, and a knot the passes would stop at
    moved = np.concatenate([[True], (np.max(np.abs(np.diff(q, axis=0)), axis=1, initial=0.0) > 0)
                            | (np.linalg.norm(np.diff(pos, axis=0), axis=1) > 0) | (quat_angle(quat[:-1], quat[1:]) > 0)])
    pos, quat, q = pos[moved], quat[moved], q[moved]
    k = len(q)
    if k == 1:
        root = np.concatenate([pos, quat], axis=1)
        return TimedPath(np.zeros(1), root, q, tuple(seq.joint_names), 0.0, 0.0)
    dq = np.abs(np.diff(q, axis=0))  # (K-1, n)
    dp = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    da = 2.0 * quat_angle(quat[:-1], quat[1:])
    tiny = 1e-12
    # each segment's length: its largest step in units of the densification step (<= 1)
    length = np.maximum.reduce([np.max(dq, axis=1, initial=0.0) / max_step_rad, da / max_step_rad, dp / max_step_m, np.full(k - 1, tiny)])
    with np.errstate(divide="ignore"):
        vmax = length * np.minimum.reduce([
            np.min(lim.joint_velocity_rad_s / np.maximum(dq, tiny), axis=1),
            lim.root_velocity_m_s / np.maximum(dp, tiny),
            lim.root_angular_velocity_rad_s / np.maximum(da, tiny),
        ])
        amax = length * np.minimum.reduce([
            np.min(lim.joint_accel_rad_s2 / np.maximum(dq, tiny), axis=1),
            lim.root_accel_m_s2 / np.maximum(dp, tiny),
            lim.root_angular_accel_rad_s2 / np.maximum(da, tiny),
        ])
    # knot speeds (length per second): forward then backward pass
    v = np.zeros(k)
    # a corner at knot i changes the axis velocities by |u_i - u_i-1| s' within ~L/s' seconds, so
    # |u_i - u_i-1|_j s'^2 <= a_j L (the discrete centripetal term the plain pass ignores)
    u = np.diff(q, axis=0) / length[:, None]
    up = np.diff(pos, axis=0) / length[:, None]
    du = np.abs(np.diff(u, axis=0))
    dup = np.linalg.norm(np.diff(up, axis=0), axis=1)
    mean_len = 0.5 * (length[:-1] + length[1:])
    with np.errstate(divide="ignore"):
        corner = np.sqrt(mean_len * np.minimum(
            np.min(lim.joint_accel_rad_s2 / np.maximum(du, tiny), axis=1) if q.shape[1] else np.inf,
            lim.root_accel_m_s2 / np.maximum(dup, tiny),
        ))
    cap = np.concatenate([[0.0], np.minimum.reduce([vmax[:-1], vmax[1:], corner]), [0.0]])
    for i in range(k - 1):
        v[i + 1] = min(cap[i + 1], np.sqrt(v[i] ** 2 + 2.0 * amax[i] * length[i]))
    for i in range(k - 2, -1, -1):
        v[i] = min(v[i], np.sqrt(v[i + 1] ** 2 + 2.0 * amax[i] * length[i]))
    seg_t = np.array([_segment_time(v[i], v[i + 1], vmax[i], amax[i], length[i]) for i in range(k - 1)])
    knots_t = np.concatenate([[0.0], np.cumsum(seg_t)])
    knots_s = np.concatenate([[0.0], np.cumsum(length)])
    smooth_t, smooth_s = _jerk_limited(knots_t, knots_s, v, vmax, amax, jerk_window_s)
    scale = 1.0
    for _ in range(20):
        t_out = _row_times(float(smooth_t[-1]) * scale, sample_period_s)
        s_out = np.clip(np.interp(t_out / scale, smooth_t, smooth_s), 0.0, knots_s[-1])
        s_out[-1] = knots_s[-1]  # the last row on the last posture exactly
        root, joints = _at_progress(s_out, knots_s, pos, quat, q)
        vr, ar = measured_rates(t_out, root, joints, lim)
        need = max(vr, np.sqrt(ar))
        if need <= 1.0 + 1e-6:
            break
        scale *= need * 1.01
    else:
        log.warning("timing did not keep the limits after 20 stretches (velocity %.3f, accel %.3f of limits)", vr, ar)
    log.debug("timed %d knots: %.3f s (stretch %.3f), velocity %.2f, accel %.2f of limits", k, t_out[-1], scale, vr, ar)
    return TimedPath(t_out, root, joints, tuple(seq.joint_names), vr, ar)


def integrated_squared_jerk(t: np.ndarray, q: np.ndarray) -> float:
    """Sum over joints of the integral of the squared third derivative [rad^2 / s^5].

    Args:
        t: sample times [s], shape (T,), uniform period.
        q: joint angles [rad], shape (T, n).
    """
    if len(t) < 4:
        return 0.0
    dt = float(np.median(np.diff(t)))
    jerk = np.diff(q, n=3, axis=0) / dt**3
    return float(np.sum(jerk * jerk) * dt)


def _jerk_limited(knots_t: np.ndarray, knots_s: np.ndarray, v: np.ndarray, vmax: np.ndarray, amax: np.ndarray,
                  window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Progress s(t) of the trapezoidal profile with its speed averaged over ``window_s``.

    A moving average of the path speed keeps every speed and acceleration bound of the trapezoid
    (an average never exceeds the largest value it averages) and turns its acceleration steps into
    ramps, so jerk is bounded by ~2 a_max / window_s instead of infinite. It lengthens the motion
    by one window.

    Returns:
        (t, s): times [s] and progress [path length, in densification steps], fine-grained (1 ms),
        s from 0 to the path's end.
    """
    total = float(knots_t[-1])
    n = max(2, int(np.ceil(total / _FINE_DT_S)) + 1)
    fine_t = np.linspace(0.0, total, n)
    s = _progress(fine_t, knots_t, knots_s, v, vmax, amax)
    dt = fine_t[1] - fine_t[0]
    w = int(round(window_s / dt)) if window_s > 0 else 0
    if w < 2:
        return fine_t, s
    speed = np.diff(s) / dt
    speed = np.convolve(speed, np.full(w, 1.0 / w))
    out = np.concatenate([[0.0], np.cumsum(speed) * dt])
    out *= s[-1] / out[-1]  # same end, exactly
    return np.arange(out.size) * dt, out


_FINE_DT_S = 0.001  # resolution of the jerk-limited progress curve [s]


def _segment_time(v0: float, v1: float, vmax: float, amax: float, length: float) -> float:
    """Duration of a segment of ``length`` from speed v0 to v1 with |s''| <= amax, s' <= vmax (trapezoid)."""
    # peak speed reachable in the segment
    vp = min(vmax, np.sqrt(amax * length + 0.5 * (v0**2 + v1**2)))
    d_acc = (vp**2 - v0**2) / (2 * amax)
    d_dec = (vp**2 - v1**2) / (2 * amax)
    cruise = max(0.0, length - d_acc - d_dec)
    return float((vp - v0) / amax + (vp - v1) / amax + (cruise / vp if vp > 0 else 0.0))


def _row_times(total: float, period: float) -> np.ndarray:
    n = max(1, int(np.ceil(total / period - 1e-9)))
    return np.linspace(0.0, total, n + 1)


def _progress(t: np.ndarray, knots_t: np.ndarray, knots_s: np.ndarray, v: np.ndarray, vmax: np.ndarray, amax: np.ndarray) -> np.ndarray:
    """Path progress s (path length, in densification steps) at times t: the exact trapezoid of each segment."""
    i = np.clip(np.searchsorted(knots_t, t, side="right") - 1, 0, len(knots_t) - 2)
    tau = np.clip(t - knots_t[i], 0.0, None)
    v0, v1, a, vm = v[i], v[i + 1], amax[i], vmax[i]
    length = knots_s[i + 1] - knots_s[i]
    vp = np.minimum(vm, np.sqrt(a * length + 0.5 * (v0**2 + v1**2)))
    t_acc = (vp - v0) / a
    t_dec = (vp - v1) / a
    seg = knots_t[i + 1] - knots_t[i]
    t_cru = np.maximum(0.0, seg - t_acc - t_dec)
    d_acc = v0 * np.minimum(tau, t_acc) + 0.5 * a * np.minimum(tau, t_acc) ** 2
    d_cru = vp * np.clip(tau - t_acc, 0.0, t_cru)
    td = np.clip(tau - t_acc - t_cru, 0.0, t_dec)
    d_dec = vp * td - 0.5 * a * td**2
    return np.minimum(knots_s[i] + np.clip(d_acc + d_cru + d_dec, 0.0, length), knots_s[-1])


def _at_progress(s: np.ndarray, knots_s: np.ndarray, pos: np.ndarray, quat: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root (T, 7) and joints (T, n) at path length s (densification steps; linear within a segment)."""
    idx = np.clip(np.searchsorted(knots_s, s, side="right") - 1, 0, len(q) - 2)
    f = np.clip((s - knots_s[idx]) / (knots_s[idx + 1] - knots_s[idx]), 0.0, 1.0)[:, None]
    joints = q[idx] + f * (q[idx + 1] - q[idx])
    p = pos[idx] + f * (pos[idx + 1] - pos[idx])
    qa, qb = quat[idx], quat[idx + 1]
    sign = np.where(np.sum(qa * qb, axis=1) < 0, -1.0, 1.0)[:, None]
    qq = (1 - f) * qa + f * sign * qb  # knots are <= max_step_rad apart: nlerp is exact enough
    qq /= np.linalg.norm(qq, axis=1, keepdims=True)
    return np.concatenate([p, qq], axis=1), joints
