"""Get-up strategies as robot-independent data: keyframes in joint roles, read from versioned files and mapped onto a robot.

A strategy file (format ``robot-rise/strategy@1``, JSON) holds one get-up motion as people wrote
it: the lying kind it starts from, the lying posture and keyframes as role values
(:mod:`robot_rise.roles`: "left.knee" = 1.0 flexes the left knee one radian on every robot), which
keyframe ends the lying-to-sitting phase, and whether the timing is to be found in simulation.
The shipped strategies live in ``configs/strategies``; ``robot-rise library build`` adapts them to
a robot (:func:`joint_keyframes`), then times, proves and writes them.

A role the robot lacks is skipped (Bez1 has no shoulder roll); joints with no role (``extra``)
hold their standing angle.

A *turn-over* strategy (``"lands": "prone"``) is not a get-up: its keyframes turn the body over
and leave it lying in another kind (a roll off the back, a tip off a side). ``robot-rise library
build`` uses one only where a robot has no proven motion for its lying kind, followed by a get-up
the robot has for the kind it lands in (``robot_rise.authoring.turn_over``): what one body
does from its back, another may only do from its front.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Generic, TypeVar

from robot_rise.errors import ConfigError, FormatError
from robot_rise.library.motions import LYING_KINDS, MAX_COMBINED_VARIANTS, MAX_NOISE_REPLAYS
from robot_rise.model import Robot
from robot_rise.paths import configs_dir
from robot_rise.roles import EXTRA, ROLES

__all__ = [
    "STRATEGY_FORMAT",
    "KeyframedMotion",
    "Strategy",
    "RoleKeyframe",
    "read_strategy",
    "load_strategies",
    "default_strategies_dir",
    "joint_keyframes",
]

STRATEGY_FORMAT = "robot-rise/strategy@1"


@dataclass(frozen=True)
class RoleKeyframe:
    """Role values reached at ``t_s`` [s]; roles not named keep the previous keyframe's value."""

    t_s: float
    roles: Mapping[str, float]


K = TypeVar("K")  # a keyframe: RoleKeyframe (role values) or a robot's joint goals


@dataclass(frozen=True, kw_only=True)
class KeyframedMotion(Generic[K]):
    """A get-up motion as keyframes, whatever its values are written in: what a :class:`Strategy`
    (role values) and the same motion mapped onto a robot's joints
    (:class:`robot_rise.authoring.keyframes.MotionSpec`) both are. Keyword-only fields.

    Attributes:
        name: file stem and CLI name.
        lying: ``supine``, ``prone``, ``left`` or ``right``.
        keyframes: goals after t = 0, increasing in time.
        connect_keyframe: index into ``keyframes`` of the keyframe that ends the lying-to-sitting/
            squatting phase (its time, after retiming, is written as ``connect_until_s``).
        lying_yaw_rad: yaw of the lying posture [rad].
        retime: find the timing in MuJoCo (:func:`robot_rise.authoring.retiming.retime`); False keeps the keyframe times (a
            dynamic motion whose momentum depends on them).
        clamp_lead: pass the trajectory through
            :func:`robot_rise.authoring.goal_lead.clamp_goal_lead` (for a motion authored
            with saturating servos: its goals are pulled back to what the servos can follow).
        max_stretch: how far the motion may be slowed and still stand, as a multiple of its
            duration (None: no bound of its own). A momentum motion stands only near its own
            timing (supine_situp_rock_robust: x0.95-x1.05 of its keyframe times); ``rise`` then
            stops slowing it there and tries the next candidate instead of ever slower replays.
        combined_variants: combined random variants (every difference of the ensemble's ranges
            drawn at once, ``robot_rise.sim.variants.combined_variants``) every ``rise`` proof that
            joins the motion replays besides the ensemble. For a momentum motion whose standing the one-difference-
            at-a-time ensemble misses: joined from random starts, supine_situp_rock_robust passed
            all 19 variants yet stood in only 30-38 of 50 random ones (issue 14).
        noise_replays: noisy replays (``robot_rise.proof.noise``) every ``rise`` proof that joins
            the motion runs, when more than the filter's own (0: the filter's). For a motion whose
            landing is a knife edge: one taken in 40 % of noisy replays escapes 6 of them 4.7 % of
            the time, 12 of them 0.2 % (supine_roll_elbow_knees joined from a side, issue 14).
    """

    name: str
    lying: str
    keyframes: tuple[K, ...]
    connect_keyframe: int
    lying_yaw_rad: float = 0.0
    retime: bool = True
    clamp_lead: bool = False
    max_stretch: float | None = None
    combined_variants: int = 0
    noise_replays: int = 0


@dataclass(frozen=True, kw_only=True)
class Strategy(KeyframedMotion[RoleKeyframe]):
    """One get-up strategy, or a turn-over (see the module docstring). Times are a shape; most are found in simulation.

    Attributes (besides those of :class:`KeyframedMotion`):
        description: one line for people.
        lying_roles: role values of the lying posture before settling [rad].
        lands: a turn-over's lying kind after its keyframes (None: a get-up).
    """

    description: str
    lying_roles: Mapping[str, float]
    lands: str | None = None  # a turn-over: the lying kind its keyframes leave the body in (not a get-up)


def default_strategies_dir() -> Path:
    return configs_dir() / "strategies"


def _roles(obj: object, where: str) -> dict[str, float]:
    if not isinstance(obj, dict):
        raise FormatError(f"{where}: expected an object of role: value")
    bad = [r for r in obj if r not in ROLES]
    if bad:
        raise FormatError(f"{where}: unknown roles {', '.join(bad)}")
    try:
        return {str(k): float(v) for k, v in obj.items()}
    except (TypeError, ValueError) as e:
        raise FormatError(f"{where}: role values must be numbers ({e})") from e


def read_strategy(path: str | os.PathLike[str]) -> Strategy:
    """Read and validate one strategy file.

    Raises:
        FormatError: unreadable, wrong format string, or a malformed field (named).
    """
    p = Path(path)
    try:
        obj = json.loads(p.read_text())
    except (OSError, ValueError) as e:
        raise FormatError(f"{p}: cannot read strategy: {e}") from e
    if not isinstance(obj, dict) or obj.get("format") != STRATEGY_FORMAT:
        raise FormatError(f"{p}: format is {obj.get('format') if isinstance(obj, dict) else None!r}, expected {STRATEGY_FORMAT!r}")
    try:
        lying = str(obj["lying"])
        if lying not in LYING_KINDS:
            raise FormatError(f"{p}: lying {lying!r} is not one of {', '.join(LYING_KINDS)}")
        kfs = []
        last = 0.0
        for i, k in enumerate(obj["keyframes"]):
            t = float(k["t_s"])
            if t <= last:
                raise FormatError(f"{p}: keyframe {i}: times must increase ({t} after {last})")
            last = t
            kfs.append(RoleKeyframe(t, _roles(k["roles"], f"{p}: keyframe {i}")))
        connect = int(obj["connect_keyframe"])
        if not 0 <= connect < len(kfs):
            raise FormatError(f"{p}: connect_keyframe {connect} is not a keyframe index (0..{len(kfs) - 1})")
        max_stretch = obj.get("max_stretch")
        if max_stretch is not None:
            max_stretch = float(max_stretch)
            if not max_stretch >= 1.0:
                raise FormatError(f"{p}: max_stretch {max_stretch} must be >= 1 (a multiple of the motion's duration)")
        combined = obj.get("combined_variants", 0)
        if not (isinstance(combined, int) and not isinstance(combined, bool) and 0 <= combined <= MAX_COMBINED_VARIANTS):
            raise FormatError(f"{p}: combined_variants {combined!r} must be a whole number in 0..{MAX_COMBINED_VARIANTS}")
        noisy = obj.get("noise_replays", 0)
        if not (isinstance(noisy, int) and not isinstance(noisy, bool) and 0 <= noisy <= MAX_NOISE_REPLAYS):
            raise FormatError(f"{p}: noise_replays {noisy!r} must be a whole number in 0..{MAX_NOISE_REPLAYS}")
        lands = obj.get("lands")
        if lands is not None and (lands not in LYING_KINDS or lands == lying):
            raise FormatError(f"{p}: lands {lands!r} must be a lying kind other than {lying!r} ({', '.join(LYING_KINDS)})")
        return Strategy(
            name=str(obj.get("name", p.stem)),
            lying=lying,
            description=str(obj.get("description", "")),
            lying_roles=_roles(obj["lying_roles"], f"{p}: lying_roles"),
            keyframes=tuple(kfs),
            connect_keyframe=connect,
            lying_yaw_rad=float(obj.get("lying_yaw_rad", 0.0)),
            retime=bool(obj.get("retime", True)),
            clamp_lead=bool(obj.get("clamp_lead", False)),
            max_stretch=max_stretch,
            combined_variants=combined,
            noise_replays=noisy,
            lands=lands,
        )
    except (KeyError, TypeError, ValueError) as e:
        raise FormatError(f"{p}: malformed strategy: missing or bad {e}") from e


def load_strategies(directory: str | os.PathLike[str] | None = None) -> tuple[Strategy, ...]:
    """Every strategy of a directory (default: the shipped ones), in the order of its ``index.json``
    list if there is one, else by file name."""
    root = Path(directory) if directory is not None else default_strategies_dir()
    if not root.is_dir():
        raise ConfigError(f"strategy directory {root} does not exist")
    order_file = root / "index.json"
    if order_file.is_file():
        try:
            names = [str(n) for n in json.loads(order_file.read_text())["strategies"]]
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise FormatError(f"{order_file}: expected {{\"strategies\": [names]}}: {e}") from e
        paths = [root / f"{n}.json" for n in names]
    else:
        paths = sorted(p for p in root.glob("*.json"))
    return tuple(read_strategy(p) for p in paths)


def joint_keyframes(strategy: Strategy, robot: Robot) -> tuple[dict[str, float], tuple[tuple[float, dict[str, float]], ...]]:
    """The strategy on a robot: lying joint angles and keyframes as (time, joint goals) [rad].

    Joints with no role hold their standing angle in the lying posture; roles the robot lacks are
    dropped.

    Raises:
        ConfigError: the robot has no joint roles (``[roles]`` in robot.toml).
    """
    if robot.roles is None:
        raise ConfigError(f"robot {robot.name} has no joint roles", hint="add [roles] to robot.toml (robot-rise robot import writes them)")
    stand = dict(zip(robot.joint_names, robot.stand_qpos[7:]))
    held = {j.joint: float(stand[j.joint]) for j in robot.roles.joints if j.role == EXTRA}
    lying = held | robot.roles.joint_goals(strategy.lying_roles)
    keyframes = tuple((k.t_s, robot.roles.joint_goals(k.roles)) for k in strategy.keyframes)
    return lying, keyframes
