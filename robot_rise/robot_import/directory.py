"""The files of an imported robot's directory: robot.toml (every inference, to correct by hand) and servos.toml (the servo map, or a template of one)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import mujoco

from robot_rise.errors import ConfigError
from robot_rise.model import ROBOT_FORMAT, SERVOS_FORMAT
from robot_rise.robot_import.roles import InferredRoles

__all__ = ["template_servo_map", "write_servos", "write_robot_toml", "SOLE_SITE", "TORSO_SITE"]

SOLE_SITE = "robot_rise_{side}_sole"
TORSO_SITE = "robot_rise_torso"


def template_servo_map(joints: list[str], ranges: Mapping[str, tuple[float, float]], models: dict[str, str]) -> list[dict]:
    default = models.pop("*", None)
    unknown = [j for j in models if j not in joints]
    if unknown:
        raise ConfigError(f"--servo-model names joints the model lacks: {', '.join(unknown)}")
    lacking = [j for j in joints if j not in models and default is None]
    if lacking:
        raise ConfigError(f"no servo model for {', '.join(lacking)}", hint="--servo-model MODEL for all joints, JOINT=MODEL for one")
    return [
        {"id": i + 1, "joint": j, "model": models.get(j, default), "direction": 1, "zero_offset": 0.0, "min": ranges[j][0], "max": ranges[j][1]}
        for i, j in enumerate(joints)
    ]


def _toml_value(v: object) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(round(v, 6))
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return str(v)


def write_servos(path: Path, robot: str, rows: list[dict], bus: Mapping[str, object]) -> None:
    lines = [
        "# Servo map: which servo drives which joint (IDs, models, directions, zero offsets, limits in radians).",
        "# Written by robot-rise robot import; edit it to your hardware.",
        "# [bus] supply_voltage_v: the servos' supply (12.0 for a 3S LiPo at 4 V a cell, 14.8 for a 4S at its",
        "# nominal): every simulation models the servos' torque and speed at it.",
        f'format = "{SERVOS_FORMAT}"',
        f"robot = {_toml_value(robot)}",
        "",
        "[bus]",
    ] + [f"{k} = {_toml_value(v)}" for k, v in bus.items()]
    for r in rows:
        lines += ["", "[[servo]]"] + [f"{k} = {_toml_value(r[k])}" for k in ("id", "joint", "model", "direction", "zero_offset", "min", "max") if k in r]
    path.write_text("\n".join(lines) + "\n")


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
    lines = [
        "# Robot description written by robot-rise robot import. Every value here is an inference:",
        "# correct wrong guesses in this file (roles, signs, neutral angles, sites), never in code.",
        f'format = "{ROBOT_FORMAT}"',
        f"name = {_toml_value(name)}",
        'model = "robot.xml"',
        'servos = "servos.toml"',
        'library = "motions"  # this robot\'s library: robot-rise library build --robot DIR',
    ]
    if passive:
        lines += ["# Hinges no servo drives: the model's equality constraints move them (closed linkages).", f"passive = {_toml_value(list(passive))}"]
    lines += [
        "",
        "[metric_groups]",
        f"head = {_toml_value(head)}",
        f"foot = {_toml_value(foot)}",
        "",
        "# Limbs for partial-body planning: every joint exactly once.",
        "[limbs]",
    ]
    lines += [f"{k} = {_toml_value(v)}" for k, v in limb_joints.items() if v]
    lines += [
        "",
        "[sites]",
        f"soles = {_toml_value([SOLE_SITE.format(side=s) for s in ('left', 'right')])}",
        f"torso = {_toml_value(TORSO_SITE)}",
        "",
        "# Joint roles (robot_rise/roles.py): q = neutral + sign * role value. role = \"extra\": held.",
        "[roles]",
    ]
    for j in range(m.njnt):
        if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or m.joint(j).name in passive:
            continue
        r = by_joint[m.joint(j).name]
        lines.append(f"{_toml_value(r.joint)} = {{ role = {_toml_value(r.role)}, sign = {r.sign}, neutral = {_toml_value(float(r.neutral_rad))} }}")
    path.write_text("\n".join(lines) + "\n")
