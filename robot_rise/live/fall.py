"""Fall detection from the IMU in every direction: standing, falling, fallen-and-still, lying kind.

Input: IMU samples in SI units in the torso frame (anything with ``t_s`` [s],
``angular_velocity_rad_s`` and ``specific_force_m_s2``, 3 values each, e.g. ``drivers.imu.ImuSample``
or the twin's ``TwinImuState``; a sample with ``valid`` False or non-finite values is skipped).
Output: a :class:`FallEstimate` per sample. Everything here is a pure function of its arguments;
:class:`FallTracker` is the (immutable) memory one :func:`step` hands to the next.

The gravity direction is tracked in the torso frame by a complementary filter: the gyro turns the
last estimate (a world-fixed vector seen from the torso moves as ``dv/dt = v x w``), and the
accelerometer pulls it towards the measured specific force with time constant
``gravity_time_constant_s`` whenever that force is close to 1 g (free fall and impacts are left
out). Tilt is the angle between the torso's up axis and the true up; it does not care which way
the robot tips, so side falls count as much as front and back falls (the stock OP3 looks at
pitch only, > 60 deg, and a robot on its side reads as standing).

States (:class:`FallState`):
- ``STANDING``: on its feet as far as the IMU can tell, fall detection armed: entered once
  upright (tilt below ``upright_tilt_rad``) for ``upright_s``, kept through leans short of a fall
  (a bow) until FALLING, or DOWN/FALLEN if it slides down slowly.
- ``FALLING``: from STANDING, the tilt is past ``fall_tilt_rad`` and growing faster than
  ``fall_tilt_rate_rad_s``, or the torso turns about a horizontal axis faster than
  ``fall_gyro_rad_s``: go limp or to a safe falling pose now.
- ``FALLEN``: fallen and still: tilt past ``fallen_tilt_rad``, the gyro and the accelerometer's
  variation small for ``still_s`` (debounced); with the lying kind (supine, prone, left, right)
  from the gravity direction in the torso frame.
- ``DOWN``: not upright and not still: the robot is rolling after a fall, or getting up. This is
  the "rising mode": falling is only detected from STANDING, so the large tilts and turn rates of
  a get-up never read as a fall; the robot is STANDING again only once upright for
  ``upright_s`` (a get-up that fails ends FALLEN again, with its new lying kind).
- ``UNKNOWN``: before the first valid sample.

Which torso axis points forward, left and up is the robot's (:class:`TorsoAxes`; the OP3 model's
torso frame is x forward, y left, z up: ``configs/robots/op3/robot.xml``).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Literal, Protocol

import numpy as np

__all__ = [
    "LyingKind",
    "LYING_KINDS",
    "STANDARD_GRAVITY_M_S2",
    "TorsoAxes",
    "FallConfig",
    "FallState",
    "FallEstimate",
    "FallTracker",
    "ImuSampleLike",
    "up_from_specific_force",
    "propagate_up",
    "fuse_up",
    "tilt_rad",
    "tilt_rate_rad_s",
    "lying_kind",
    "new_tracker",
    "step",
    "detect",
]

LyingKind = Literal["supine", "prone", "left", "right"]
LYING_KINDS: tuple[LyingKind, ...] = ("supine", "prone", "left", "right")
STANDARD_GRAVITY_M_S2 = 9.80665  # [m/s^2] one g: what the accelerometer reads at rest

Vec3 = tuple[float, float, float]


class ImuSampleLike(Protocol):
    """What the detector reads of an IMU sample (SI units, torso frame)."""

    @property
    def t_s(self) -> float: ...

    @property
    def angular_velocity_rad_s(self) -> Sequence[float]: ...

    @property
    def specific_force_m_s2(self) -> Sequence[float]: ...


@dataclass(frozen=True)
class TorsoAxes:
    """Which torso-frame axes point forward, to the robot's left and up (unit vectors).

    The OP3 default: x forward, y left, z up (the torso frame of configs/robots/op3/robot.xml).
    """

    forward: Vec3 = (1.0, 0.0, 0.0)
    left: Vec3 = (0.0, 1.0, 0.0)
    up: Vec3 = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        axes = {}
        for name in ("forward", "left", "up"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (3,) or not np.isclose(np.linalg.norm(v), 1.0, atol=1e-6):
                raise ValueError(f"TorsoAxes.{name} must be a unit 3-vector, got {getattr(self, name)!r}")
            axes[name] = v
            object.__setattr__(self, name, (float(v[0]), float(v[1]), float(v[2])))
        if not np.allclose(np.cross(axes["forward"], axes["left"]), axes["up"], atol=1e-6):
            raise ValueError("TorsoAxes must be right-handed and orthogonal: forward x left = up")


@dataclass(frozen=True)
class FallConfig:
    """Every threshold of the detector, in one place (ours; numbers measured on the OP3 twin).

    Attributes:
        gravity_time_constant_s: [s] how fast the accelerometer corrects the gyro's gravity
            estimate. 0.3 s: a gyro bias of 0.05 rad/s then tilts the estimate by only
            ~1 deg, yet it converges within a second after a tumble.
        accel_gate_m_s2: [m/s^2] the accelerometer corrects the estimate only while |f| is
            within this of 1 g: a falling OP3 reads 0.4-8 m/s^2 (near free fall) and its
            impacts 20-150 m/s^2 (the OpenCR saturates at 2 g), neither shows gravity.
        accel_lowpass_s: [s] time constant of the low-passed specific force the stillness test
            compares each reading with.
        upright_tilt_rad: 20 deg: the standing judge counts 15 deg as standing
            (robot_rise.constants.STAND_MAX_TILT_RAD); 5 deg more for sway and sensor error.
        upright_s: [s] upright this long before STANDING (a get-up passing through upright
            for an instant is not standing yet).
        fall_tilt_rad: 30 deg: twice the standing judge's tilt, beyond any lean of standing or
            walking; a toppling OP3 passes it about 0.2 s before it hits the ground (the twin:
            30 deg at 0.6 s, impact at 0.8 s after a 30 N push), time to go limp.
        fall_tilt_rate_rad_s: [rad/s] "growing": a toppling OP3 passes 30 deg at 2-3 rad/s;
            a deliberate lean is far slower than 1 rad/s.
        fall_gyro_rad_s: [rad/s] a turn this fast about a horizontal axis (a turn about the
            vertical tips nothing) from standing is a fall whatever the tilt:
            the twin's OP3 withstood 0.1 s pushes of 15 N (front) and 20 N (side) turning at up
            to 1.5 rad/s; twice that is a violent event (trip, hard push: toppling pushes reach
            2-3 rad/s before 30 deg).
        fallen_tilt_rad: 50 deg: below the 60 deg of the stock OP3's pitch test and of
            robot_rise.sampling's "lying", so a robot resting on knees and elbows or on a slope
            counts as fallen; well past fall_tilt_rad.
        still_gyro_rad_s: [rad/s] still: angular speed below this (sensor noise ~0.01 rad/s,
            servo jitter of a robot lying with torque on a few 0.01 rad/s).
        still_accel_m_s2: [m/s^2] still: |f - low-passed f| and ||f| - 1 g| below this.
        still_s: [s] debounce: still this long before FALLEN (a bounce or a pause of a get-up
            is shorter; leaves 1.5 s of the 2 s budget to the first rising command).
        resume_factor: hysteresis: FALLEN ends once the motion exceeds this multiple of the
            still thresholds (or the tilt drops below fallen_tilt_rad), so sensor noise near a
            threshold does not flap the state.
        max_gap_s: [s] across a longer gap between usable samples (reads lost) the gyro is not
            integrated: the gravity estimate restarts from the accelerometer (when it shows 1 g).
            10 cycles of the 100 Hz loop.
    """

    gravity_time_constant_s: float = 0.3
    accel_gate_m_s2: float = 0.25 * STANDARD_GRAVITY_M_S2
    accel_lowpass_s: float = 0.2
    upright_tilt_rad: float = math.radians(20.0)
    upright_s: float = 0.5
    fall_tilt_rad: float = math.radians(30.0)
    fall_tilt_rate_rad_s: float = 1.0
    fall_gyro_rad_s: float = 3.0
    fallen_tilt_rad: float = math.radians(50.0)
    still_gyro_rad_s: float = 0.2
    still_accel_m_s2: float = 0.8
    still_s: float = 0.5
    resume_factor: float = 2.0
    max_gap_s: float = 0.1

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"FallConfig.{name} must be finite and > 0, got {value}")
        if not self.upright_tilt_rad < self.fall_tilt_rad < self.fallen_tilt_rad < math.pi:
            raise ValueError("FallConfig needs upright_tilt_rad < fall_tilt_rad < fallen_tilt_rad < pi, got "
                             f"{self.upright_tilt_rad:.3f}, {self.fall_tilt_rad:.3f}, {self.fallen_tilt_rad:.3f}")


class FallState(enum.Enum):
    """What the detector says about the robot (see the module docstring)."""

    UNKNOWN = "unknown"
    STANDING = "standing"
    FALLING = "falling"
    FALLEN = "fallen"
    DOWN = "down"


@dataclass(frozen=True)
class FallEstimate:
    """The detector's verdict at one sample.

    Attributes:
        t_s: the sample's time [s].
        state: :class:`FallState`.
        lying: the lying kind when the tilt is past ``fallen_tilt_rad`` (else None).
        tilt_rad: angle between the torso's up axis and the true up [rad].
        tilt_rate_rad_s: how fast the tilt grows [rad/s] (negative: righting).
        angular_speed_rad_s: |angular velocity| [rad/s].
        up_torso: estimated up direction (against gravity) in the torso frame, unit 3-vector.
        still_s: how long the robot has been still [s] (0 if moving).
        changed: the state changed at this sample.
    """

    t_s: float
    state: FallState
    lying: LyingKind | None = None
    tilt_rad: float = math.nan
    tilt_rate_rad_s: float = 0.0
    angular_speed_rad_s: float = 0.0
    up_torso: Vec3 = (math.nan, math.nan, math.nan)
    still_s: float = 0.0
    changed: bool = False


@dataclass(frozen=True)
class FallTracker:
    """The detector's memory between samples; :func:`step` returns the next one.

    Attributes:
        config: thresholds.
        axes: the torso's forward, left and up axes.
        estimate: the latest verdict (state UNKNOWN before the first valid sample).
        up: estimated up direction in the torso frame (None before the first valid sample).
        force_lowpass: low-passed specific force [m/s^2] (None before the first valid sample).
        still_since_s: when the robot became still [s] (None while moving).
        upright_since_s: when the torso became upright [s] (None while tilted).
        since_s: when the present state began [s].
    """

    config: FallConfig = field(default_factory=FallConfig)
    axes: TorsoAxes = field(default_factory=TorsoAxes)
    estimate: FallEstimate = field(default_factory=lambda: FallEstimate(math.nan, FallState.UNKNOWN))
    up: Vec3 | None = None
    force_lowpass: Vec3 | None = None
    still_since_s: float | None = None
    upright_since_s: float | None = None
    since_s: float = math.nan

    @property
    def state(self) -> FallState:
        return self.estimate.state


# ---- pure geometry ---------------------------------------------------------------------------


def _vec(v: Sequence[float]) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(3)


def _tuple(v: np.ndarray) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


def up_from_specific_force(specific_force_m_s2: Sequence[float]) -> Vec3:
    """The up direction the accelerometer shows at rest: ``f / |f|`` (torso frame, unit).

    Raises:
        ValueError: ``f`` is zero (free fall shows no direction).
    """
    f = _vec(specific_force_m_s2)
    n = float(np.linalg.norm(f))
    if not n > 0.0:
        raise ValueError("a zero specific force (free fall) shows no gravity direction")
    return _tuple(f / n)


def propagate_up(up: Sequence[float], angular_velocity_rad_s: Sequence[float], dt_s: float) -> Vec3:
    """Turn the torso-frame up direction by the torso's rotation over ``dt_s`` [s].

    A world-fixed vector seen from a body turning at ``w`` (body frame) turns by ``-w dt``
    (exact for constant ``w``: Rodrigues' rotation).
    """
    v, w = _vec(up), _vec(angular_velocity_rad_s)
    speed = float(np.linalg.norm(w))
    angle = -speed * dt_s
    if speed * abs(dt_s) < 1e-12:
        return _tuple(v)
    k = w / speed
    out = v * math.cos(angle) + np.cross(k, v) * math.sin(angle) + k * float(k @ v) * (1.0 - math.cos(angle))
    return _tuple(out / np.linalg.norm(out))


def fuse_up(up_predicted: Sequence[float], specific_force_m_s2: Sequence[float], dt_s: float,
            config: FallConfig) -> Vec3:
    """Complementary filter step: pull the gyro's prediction towards the accelerometer's up.

    The pull is ``dt / (tau + dt)`` of the way (all the way for an infinite ``dt_s``), only while
    |f| is within ``config.accel_gate_m_s2`` of 1 g; otherwise the prediction stands.
    """
    f = _vec(specific_force_m_s2)
    n = float(np.linalg.norm(f))
    if not abs(n - STANDARD_GRAVITY_M_S2) < config.accel_gate_m_s2:
        return _tuple(_vec(up_predicted))
    gain = 1.0 if math.isinf(dt_s) else dt_s / (config.gravity_time_constant_s + dt_s)
    out = _vec(up_predicted) + gain * (f / n - _vec(up_predicted))
    return _tuple(out / np.linalg.norm(out))


def tilt_rad(up: Sequence[float], axes: TorsoAxes) -> float:
    """Angle between the torso's up axis and the true up [rad], 0..pi."""
    return math.acos(max(-1.0, min(1.0, float(_vec(up) @ _vec(axes.up)))))


def tilt_rate_rad_s(up: Sequence[float], angular_velocity_rad_s: Sequence[float], axes: TorsoAxes) -> float:
    """d(tilt)/dt [rad/s] from the gyro: positive while the torso tips further from upright."""
    v = _vec(up)
    s = math.sin(tilt_rad(v, axes))
    if s < 1e-6:
        return 0.0
    dv = np.cross(v, _vec(angular_velocity_rad_s))
    return -float(dv @ _vec(axes.up)) / s


def lying_kind(up: Sequence[float], axes: TorsoAxes) -> LyingKind:
    """How the robot lies, from the true up direction in the torso frame.

    The dominant horizontal torso axis decides (as robot_rise.sampling.classify_lying does from
    the root orientation): front up is supine, front down prone, left side down "left", right
    side down "right".
    """
    v = _vec(up)
    front, left = float(v @ _vec(axes.forward)), float(v @ _vec(axes.left))
    if abs(front) >= abs(left):
        return "supine" if front > 0 else "prone"
    return "left" if left < 0 else "right"


# ---- the detector ----------------------------------------------------------------------------


def new_tracker(config: FallConfig | None = None, axes: TorsoAxes | None = None) -> FallTracker:
    """A detector that has seen nothing yet (state UNKNOWN)."""
    return FallTracker(config or FallConfig(), axes or TorsoAxes())


def _usable(sample: ImuSampleLike) -> bool:
    if not getattr(sample, "valid", True):
        return False
    values = (sample.t_s, *sample.angular_velocity_rad_s, *sample.specific_force_m_s2)
    return len(values) == 7 and all(math.isfinite(float(v)) for v in values)


def step(tracker: FallTracker, sample: ImuSampleLike) -> FallTracker:
    """The detector after one more sample (an unusable sample returns ``tracker`` unchanged)."""
    if not _usable(sample):
        return tracker
    cfg, axes = tracker.config, tracker.axes
    t = float(sample.t_s)
    w = _vec(sample.angular_velocity_rad_s)
    f = _vec(sample.specific_force_m_s2)
    if tracker.up is None or tracker.force_lowpass is None:
        try:
            up = up_from_specific_force(f)
        except ValueError:
            return tracker  # free fall at the very first sample: wait for gravity
        f_lp = f
    else:
        dt = max(0.0, t - tracker.estimate.t_s)
        if dt > cfg.max_gap_s:  # reads were lost: do not integrate the gyro across the gap
            up = fuse_up(tracker.up, f, math.inf, cfg)
        else:
            up = fuse_up(propagate_up(tracker.up, w, dt), f, dt, cfg)
        a = dt / (cfg.accel_lowpass_s + dt) if dt > 0 else 0.0
        f_lp = _vec(tracker.force_lowpass) + a * (f - _vec(tracker.force_lowpass))
    tilt = tilt_rad(up, axes)
    rate = tilt_rate_rad_s(up, w, axes)
    speed = float(np.linalg.norm(w))
    up_v = _vec(up)
    tipping_speed = float(np.linalg.norm(w - float(w @ up_v) * up_v))  # about horizontal axes
    still_now = (speed < cfg.still_gyro_rad_s and float(np.linalg.norm(f - f_lp)) < cfg.still_accel_m_s2
                 and abs(float(np.linalg.norm(f)) - STANDARD_GRAVITY_M_S2) < cfg.still_accel_m_s2)
    still_since = (tracker.still_since_s if tracker.still_since_s is not None else t) if still_now else None
    upright_now = tilt < cfg.upright_tilt_rad
    upright_since = (tracker.upright_since_s if tracker.upright_since_s is not None else t) if upright_now else None
    still_for = t - still_since if still_since is not None else 0.0
    # upright time counts from the start of the present state: a fall that begins while upright
    # (a hard push) is not "caught" by the upright time before it
    upright_for = t - max(upright_since, tracker.since_s) if upright_since is not None else 0.0
    lying_now = tilt > cfg.fallen_tilt_rad
    fallen_now = lying_now and still_for >= cfg.still_s

    old = tracker.state
    new = old
    if old is FallState.UNKNOWN:
        new = FallState.STANDING if upright_now else FallState.DOWN
    elif old is FallState.STANDING:
        if (tilt > cfg.fall_tilt_rad and rate > cfg.fall_tilt_rate_rad_s) or tipping_speed > cfg.fall_gyro_rad_s:
            new = FallState.FALLING
        elif fallen_now:
            new = FallState.FALLEN  # slid down slowly
        elif lying_now:
            new = FallState.DOWN
    elif old in (FallState.FALLING, FallState.DOWN):
        if fallen_now:
            new = FallState.FALLEN
        elif upright_for >= cfg.upright_s:
            new = FallState.STANDING
    elif old is FallState.FALLEN:
        k = cfg.resume_factor
        moving = (speed > k * cfg.still_gyro_rad_s or float(np.linalg.norm(f - f_lp)) > k * cfg.still_accel_m_s2
                  or abs(float(np.linalg.norm(f)) - STANDARD_GRAVITY_M_S2) > k * cfg.still_accel_m_s2)
        if moving or not lying_now:
            new = FallState.STANDING if upright_for >= cfg.upright_s else FallState.DOWN
    estimate = FallEstimate(t, new, lying_kind(up, axes) if lying_now else None, tilt, rate, speed,
                            up, still_for, new is not old)
    return replace(tracker, estimate=estimate, up=up, force_lowpass=_tuple(f_lp), still_since_s=still_since,
                   upright_since_s=upright_since, since_s=t if new is not old else tracker.since_s)


def detect(samples: Iterable[ImuSampleLike], config: FallConfig | None = None,
           axes: TorsoAxes | None = None) -> list[FallEstimate]:
    """Run the detector over ``samples`` (in time order): one estimate per usable sample."""
    tracker = new_tracker(config, axes)
    out = []
    for s in samples:
        nxt = step(tracker, s)
        if nxt is not tracker:
            out.append(nxt.estimate)
        tracker = nxt
    return out
