"""Retargeting (paper 000 section 5.3): robot variants with other body proportions.

``scale_robot`` writes a new robot directory whose arm, leg and torso segments are longer or
shorter by given factors, with masses scaled with length and inertias with mass x length^2
(a uniform rod). The variant keeps its source robot's joint names, servo map and motion
library, so ``rise`` runs on it with no code change: the planner and the dynamics filter adapt
the library's motions to the new body.
"""

from __future__ import annotations

import os
import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from robot_files.toml_file import read_toml, write_toml
from robot_rise.errors import ConfigError, as_config_error
from robot_rise.model import Robot, load_robot

__all__ = ["BodyScale", "scale_robot"]

MIN_SCALE, MAX_SCALE = 0.5, 2.0  # beyond these the servo map and library stop making sense


@dataclass(frozen=True)
class BodyScale:
    """Length factors per body part (1.0 = unchanged)."""

    arms: float = 1.0
    legs: float = 1.0
    torso: float = 1.0

    def __post_init__(self) -> None:
        for name in ("arms", "legs", "torso"):
            v = getattr(self, name)
            if not MIN_SCALE <= v <= MAX_SCALE:
                raise ConfigError(f"{name} scale {v} outside [{MIN_SCALE}, {MAX_SCALE}]")


def _fmt(values: np.ndarray) -> str:
    return " ".join(f"{v:.6g}" for v in values)


def _scale_attr(el: ET.Element, attr: str, factor: np.ndarray | float) -> None:
    if attr in el.attrib:
        v = np.array([float(x) for x in el.attrib[attr].split()])
        el.attrib[attr] = _fmt(v * factor)


def _scale_body_contents(body: ET.Element, s: float, axis_mask: np.ndarray | None = None) -> None:
    """Scale a body's own geoms, sites and inertial (not its children bodies' contents)."""
    f = s if axis_mask is None else np.where(axis_mask, s, 1.0)
    for child in body:
        if child.tag == "geom":
            if "fromto" in child.attrib:
                _scale_attr(child, "fromto", np.tile(f, 2) if axis_mask is not None else s)
            _scale_attr(child, "pos", f)
            if axis_mask is not None and child.attrib.get("type") == "box":
                _scale_attr(child, "size", f)
        elif child.tag == "site":
            _scale_attr(child, "pos", f)
        elif child.tag == "inertial":
            _scale_attr(child, "pos", f)
            _scale_attr(child, "mass", s)
            _scale_attr(child, "diaginertia", s**3)


def scale_robot(
    source: str | os.PathLike[str] | Robot,
    destination: str | os.PathLike[str],
    scale: BodyScale,
    *,
    name: str | None = None,
) -> Robot:
    """Write a scaled copy of a robot directory and return it loaded.

    Args:
        source: robot directory (or loaded robot) to scale.
        destination: new directory (must not exist or be empty).
        scale: length factors for arms, legs and torso (limbs named *arm* / *leg* in robot.toml;
            the torso is the root body).
        name: new robot name (default: source name + "_scaled").

    Raises:
        ConfigError: bad factors, an existing non-empty destination, or a source that cannot be read.
    """
    robot = source if isinstance(source, Robot) else load_robot(source)
    dst = Path(destination)
    if dst.exists() and any(dst.iterdir()):
        raise ConfigError(f"{dst} exists and is not empty", hint="choose a new directory")
    dst.mkdir(parents=True, exist_ok=True)
    tree = ET.parse(robot.xml_path)
    root = tree.getroot()
    joint_to_part: dict[str, str] = {}
    for limb, joints in robot.limbs.items():
        part = "arms" if "arm" in limb else "legs" if "leg" in limb else ""
        for j in joints:
            joint_to_part[j] = part
    bodies = {b.attrib.get("name"): b for b in root.iter("body")}
    parent_of = {c: p for p in root.iter("body") for c in p if c.tag == "body"}
    torso = bodies[robot.root_body]

    def part_of(body: ET.Element) -> str:
        j = body.find("joint")
        return joint_to_part.get(j.attrib.get("name", ""), "") if j is not None else ""

    z_only = np.array([False, False, True])
    for body in root.iter("body"):
        if body is torso:
            _scale_body_contents(body, scale.torso, z_only)
            for child in body:
                if child.tag == "body":
                    _scale_attr(child, "pos", np.where(z_only, scale.torso, 1.0))
            continue
        part = part_of(body)
        if not part:
            continue
        s = getattr(scale, part)
        _scale_body_contents(body, s)
        parent = parent_of.get(body)
        if parent is not None and part_of(parent) == part:
            _scale_attr(body, "pos", s)
    root.attrib["model"] = name or f"{robot.name}_scaled"
    xml_out = dst / robot.xml_path.name
    tree.write(xml_out, encoding="unicode")
    _fix_stand_height(xml_out, robot)
    shutil.copy(robot.directory / "servos.toml", dst / "servos.toml")
    with as_config_error():  # robot.toml through the one TOML reader and writer: its values, renamed
        meta = read_toml(robot.directory / "robot.toml", "file")
        meta["name"] = name or f"{robot.name}_scaled"
        meta["library"] = robot.library
        write_toml(dst / "robot.toml", meta, comments=(
            f"Scaled from {robot.name}: arms x{scale.arms}, legs x{scale.legs}, torso x{scale.torso} (robot-rise robot scale).",
            "library: the source robot's motion library.",
        ))
    return load_robot(dst)


def _fix_stand_height(xml_path: Path, source: Robot) -> None:
    """Put the soles of the ``stand`` keyframe back on z = 0."""
    m = mujoco.MjModel.from_xml_path(str(xml_path))
    d = mujoco.MjData(m)
    k = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "stand")
    d.qpos[:] = m.key_qpos[k]
    mujoco.mj_kinematics(m, d)
    sole_z = min(d.site(s).xpos[2] for s in source.sole_sites)
    qpos = m.key_qpos[k].copy()
    qpos[2] -= sole_z
    tree = ET.parse(xml_path)
    for key in tree.getroot().iter("key"):
        if key.attrib.get("name") == "stand":
            key.attrib["qpos"] = _fmt(qpos)
    tree.write(xml_path, encoding="unicode")
