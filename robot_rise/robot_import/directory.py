"""The files of an imported robot's directory: robot.toml (every inference, to correct by hand) and servos.toml (the servo map, or a template of one).

Both are written by the one TOML writer (:func:`robot_files.toml_file.write_toml`, ``tomli-w``),
servos.toml through its format's own writer (:func:`robot_files.servo_map.write_servo_map`).
Numbers are written to 6 decimals (robot.xml keeps 6 significant digits).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path

import mujoco

from robot_files.servo_map import SERVO_MAP_COMMENTS, BusSettings, ServoMapFile, ServoRow, write_servo_map
from robot_files.toml_file import write_toml
from robot_rise.errors import ConfigError, as_config_error
from robot_rise.model import ROBOT_FORMAT
from robot_rise.robot_import.roles import InferredRoles

__all__ = ["template_servo_map", "write_servos", "write_robot_toml", "SOLE_SITE", "TORSO_SITE"]

SOLE_SITE = "robot_rise_{side}_sole"
TORSO_SITE = "robot_rise_torso"


def template_servo_map(joints: list[str], ranges: Mapping[str, tuple[float, float]], models: dict[str, str]) -> tuple[ServoRow, ...]:
    default = models.pop("*", None)
    unknown = [j for j in models if j not in joints]
    if unknown:
        raise ConfigError(f"--servo-model names joints the model lacks: {', '.join(unknown)}")
    lacking = [j for j in joints if j not in models and default is None]
    if lacking:
        raise ConfigError(f"no servo model for {', '.join(lacking)}", hint="--servo-model MODEL for all joints, JOINT=MODEL for one")
    with as_config_error():
        return tuple(ServoRow(i + 1, j, models.get(j, default), 1, 0.0, ranges[j][0], ranges[j][1]) for i, j in enumerate(joints))  # type: ignore[arg-type]


def _decimals(v: object) -> object:
    """``v`` as written: floats to 6 decimals, lists and tables item by item."""
    if isinstance(v, float):
        return round(v, 6)
    if isinstance(v, (list, tuple)):
        return [_decimals(x) for x in v]
    if isinstance(v, Mapping):
        return {k: _decimals(x) for k, x in v.items()}
    return v


def write_servos(path: Path, robot: str, rows: Sequence[ServoRow], bus: BusSettings) -> None:
    """Write the imported robot's ``servos.toml`` (numbers to 6 decimals)."""
    with as_config_error():
        bus = dataclasses.replace(bus, return_delay_time_us=_decimals(bus.return_delay_time_us), supply_voltage_v=_decimals(bus.supply_voltage_v),
                                  extra=tuple((k, _decimals(v)) for k, v in bus.extra))
        rows = tuple(dataclasses.replace(r, zero_offset=_decimals(r.zero_offset), min=_decimals(r.min), max=_decimals(r.max)) for r in rows)
        write_servo_map(path, ServoMapFile(robot, bus, rows), comments=_SERVOS_COMMENTS)


_SERVOS_COMMENTS = (SERVO_MAP_COMMENTS[0], "Written by robot-rise robot import; edit it to your hardware.", *SERVO_MAP_COMMENTS[1:])
_ROBOT_COMMENTS = (
    "Robot description written by robot-rise robot import. Every value here is an inference:",
    "correct wrong guesses in this file (roles, signs, neutral angles, sites), never in code.",
    "library: this robot's library (robot-rise library build --robot DIR).",
    "passive: hinges no servo drives; the model's equality constraints move them (closed linkages).",
    "[limbs]: for partial-body planning, every joint exactly once.",
    "[roles]: joint roles (robot_rise/roles.py): q = neutral + sign * role value. role = \"extra\": held.",
)


def write_robot_toml(path: Path, name: str, m: mujoco.MjModel, inferred: InferredRoles, passive: tuple[str, ...] = ()) -> None:
    roles = inferred.roles
    by_joint = {j.joint: j for j in roles.joints}
    limb_joints: dict[str, list[str]] = {"torso": [], "left_arm": [], "right_arm": [], "left_leg": [], "right_leg": []}
    for limb in inferred.limbs:
        key = f"{limb.side}_{limb.kind}" if limb.kind in ("arm", "leg") else "torso"
        limb_joints[key] += [m.joint(j).name for j in limb.joints]
    listed = {j for v in limb_joints.values() for j in v}
    limb_joints["torso"] += [j.joint for j in roles.joints if j.joint not in listed]
    head = [j.joint for j in roles.joints if j.role.startswith("head.")]
    foot = [j.joint for j in roles.joints if j.role.endswith(("ankle_pitch", "ankle_roll"))]
    data: dict[str, object] = {"format": ROBOT_FORMAT, "name": name, "model": "robot.xml", "servos": "servos.toml", "library": "motions"}
    if passive:
        data["passive"] = list(passive)
    data["metric_groups"] = {"head": head, "foot": foot}
    data["limbs"] = {k: v for k, v in limb_joints.items() if v}
    data["sites"] = {"soles": [SOLE_SITE.format(side=s) for s in ("left", "right")], "torso": TORSO_SITE}
    roles_table = {}
    for j in range(m.njnt):
        if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or m.joint(j).name in passive:
            continue
        r = by_joint[m.joint(j).name]
        roles_table[r.joint] = {"role": r.role, "sign": int(r.sign), "neutral": float(r.neutral_rad)}
    data["roles"] = roles_table
    with as_config_error():
        write_toml(path, _decimals(data), comments=_ROBOT_COMMENTS)  # type: ignore[arg-type]
