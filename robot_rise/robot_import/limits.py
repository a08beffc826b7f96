"""Joint ranges of an imported robot: the model's, the servo map's, the actuators', reconciled.

Where they come from, first that holds: the model's joint range (unless a placeholder), the
user's servo map, the model's actuator ``ctrlrange``. A servo map limit a rounding outside the
model's range (``ROUNDING_TOLERANCE_RAD``: 3.1415 written for a file's 3.14) is the model's,
noted once; further outside is refused. A placeholder range (what exporters write when nobody
set one: +-0.9 pi, +-pi or +-2 pi, or a URDF ``<limit>`` with an effort or velocity of 1000) is warned
about and replaced by the servo map's. A position-mode servo turns less than a revolution, so
every range is cut to ``POSITION_MODE_HALF_TURN_RAD``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from xml.etree import ElementTree

import mujoco

from robot_files.servo_map import ServoRow
from robot_rise.errors import ConfigError

__all__ = [
    "JointRanges",
    "joint_ranges",
    "urdf_limit_tags",
    "ROUNDING_TOLERANCE_RAD",
    "POSITION_MODE_HALF_TURN_RAD",
    "PLACEHOLDER_EFFORT",
]

ROUNDING_TOLERANCE_RAD = 2e-3  # the import issue: within 2 mrad outside the model's range is a rounding
POSITION_MODE_HALF_TURN_RAD = 3.14  # within +-pi, one tick clear of the wrap (4096 ticks per turn)
PLACEHOLDER_EFFORT = 1000.0  # URDF <limit effort="1000" velocity="1000">: an exporter's default, not a servo
# symmetric ranges exporters write when nobody set one (+-0.9 pi, +-pi, +-2 pi), matched to 1 mrad
_PLACEHOLDER_HALF_RANGES_RAD = (0.9 * math.pi, math.pi, 2.0 * math.pi)


@dataclass(frozen=True)
class JointRanges:
    """Each hinge's range [rad] by joint name, the servo rows with their limits reconciled, notes."""

    ranges: dict[str, tuple[float, float]]
    servo_rows: tuple[ServoRow, ...] | None
    notes: tuple[str, ...]


def urdf_limit_tags(urdf_text: str) -> dict[str, dict[str, float]]:
    """Per joint of a URDF, its ``<limit>`` attributes as numbers (effort, velocity, lower, upper)."""
    try:
        root = ElementTree.fromstring(urdf_text)
    except ElementTree.ParseError:
        return {}
    out: dict[str, dict[str, float]] = {}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if limit is None or not joint.get("name"):
            continue
        values = {}
        for k, v in limit.attrib.items():
            try:
                values[k] = float(v)
            except ValueError:
                continue
        out[str(joint.get("name"))] = values
    return out


def _placeholder(lo: float, hi: float, tag: Mapping[str, float]) -> str:
    """Why a range looks like an exporter's default ('' if it does not)."""
    if tag.get("effort", 0.0) >= PLACEHOLDER_EFFORT or tag.get("velocity", 0.0) >= PLACEHOLDER_EFFORT:
        return f"its URDF <limit> has effort {tag.get('effort', 0):g}, velocity {tag.get('velocity', 0):g} (an exporter's default)"
    if abs(lo + hi) < 1e-3 and any(abs(hi - h) < 1e-3 for h in _PLACEHOLDER_HALF_RANGES_RAD):
        return f"+-{hi:.4g} rad ({hi / math.pi:.2g} pi) is an exporter's default, not a joint's stop"
    return ""


def joint_ranges(
    m: mujoco.MjModel,
    ctrlranges: Mapping[str, tuple[float, float]],
    servo_rows: Sequence[ServoRow] | None,
    limit_tags: Mapping[str, Mapping[str, float]],
    source: str,
    servo_map: str,
    passive: tuple[str, ...] = (),
) -> JointRanges:
    """Every driven hinge's range (a passive one's is the model's, if any), and the servo rows'
    limits reconciled with it.

    Raises:
        ConfigError: a joint has no range anywhere, or a servo map limit lies outside the model's.
    """
    notes: list[str] = []
    servo = {r.joint: r for r in servo_rows or ()}
    out: dict[str, tuple[float, float]] = {}
    missing, placeholders, rounded = [], [], []
    for j in range(m.njnt):
        if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        name = m.joint(j).name
        if name in passive:  # the linkage moves it: no servo limit to reconcile
            continue
        model_range = (float(m.jnt_range[j, 0]), float(m.jnt_range[j, 1])) if m.jnt_limited[j] else None
        tag = limit_tags.get(name, {})
        written = model_range or ((tag["lower"], tag["upper"]) if "lower" in tag and "upper" in tag else None)
        if written is not None and not (math.isfinite(written[0]) and math.isfinite(written[1]) and written[0] < written[1]):
            raise ConfigError(f"{source}: joint {name}: range [{written[0]}, {written[1]}] is not a range (finite numbers, min below max)")
        why = _placeholder(*model_range, limit_tags.get(name, {})) if model_range else ""
        if why:
            placeholders.append(f"{name} ({why})")
        if model_range and not (why and name in servo):
            out[name] = model_range
        elif name in servo:
            out[name] = (servo[name].min, servo[name].max)
            if not model_range:
                notes.append(f"{name}: no range in the model; range from the servo map [{out[name][0]:.4f}, {out[name][1]:.4f}]")
        elif name in ctrlranges:
            out[name] = ctrlranges[name]
            notes.append(f"{name}: no range in the model; range from its actuator ctrlrange [{ctrlranges[name][0]:.4f}, {ctrlranges[name][1]:.4f}]")
        else:
            missing.append(name)
    if missing:
        raise ConfigError(f"{source}: no joint limit known for {', '.join(missing)}", hint="give them min/max in a servo map (--servos) or a range in the model")
    if placeholders:
        fate = "replaced by the servo map's" if servo else "kept: give the real ones in a servo map (--servos)"
        notes.append(f"placeholder ranges, {fate}: {', '.join(placeholders)}")
    for name, (lo, hi) in out.items():  # a servo in position mode turns less than one revolution
        clipped = (max(lo, -POSITION_MODE_HALF_TURN_RAD), min(hi, POSITION_MODE_HALF_TURN_RAD))
        if clipped != (lo, hi):
            out[name] = clipped
            notes.append(f"{name}: range [{lo:.4f}, {hi:.4f}] is more than a position-mode servo turns; kept [{clipped[0]:.4f}, {clipped[1]:.4f}]")
    # to 5 decimals: robot.xml keeps 6 significant digits, and a servo limit must lie inside the range as written
    out = {k: (round(lo, 5), round(hi, 5)) for k, (lo, hi) in out.items()}
    for name, row in servo.items():
        lo, hi = out[name]
        smin, smax = row.min, row.max
        if smin < lo - ROUNDING_TOLERANCE_RAD or smax > hi + ROUNDING_TOLERANCE_RAD:
            raise ConfigError(
                f"{servo_map}: servo {row.id} ({name}) limits [{smin}, {smax}] lie outside the model range [{lo:.4f}, {hi:.4f}]"
                f" by more than a rounding ({ROUNDING_TOLERANCE_RAD * 1e3:g} mrad)"
            )
        if smin < lo - 1e-6 or smax > hi + 1e-6:
            rounded.append(f"{name} [{smin:g}, {smax:g}] -> [{max(smin, lo):.5f}, {min(smax, hi):.5f}]")
        if not max(smin, lo) < min(smax, hi):
            raise ConfigError(f"{servo_map}: servo {row.id} ({name}) limits [{smin}, {smax}] are empty")
        servo[name] = dataclasses.replace(row, min=max(smin, lo), max=min(smax, hi))
    if rounded:
        notes.append(f"servo map limits within {ROUNDING_TOLERANCE_RAD * 1e3:g} mrad outside the model's range taken as the model's: {', '.join(rounded)}")
    rows = tuple(servo[r.joint] for r in servo_rows) if servo_rows is not None else None
    return JointRanges(out, rows, tuple(notes))
