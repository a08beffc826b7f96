"""Synthetic robot files, one per feature of published descriptions the import must handle.

Each case writes a small humanoid (2 legs of 5 joints, 2 arms of 3, a head: about 1.3 kg, XL430
servos) the way some team or exporter would publish it, with one feature in it: a ROS package
with ``package://`` meshes in mixed case, a package found only through ``--package-path``, xacro
with ``$(find)``, CAD physics MuJoCo refuses, fixed links between base and limbs, an MJCF written
for a scene (``<include>``, defaults, a floor its contact pair names), a root frame that is not
x forward, placeholder and rounded limits, a closed four-bar knee. The tests import each one
(``sim_tests/test_import_cases.py``) and ``robot-rise bench import`` reports them beside the
real files of ``../shared/robots``.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["ImportCase", "CASES", "write_case", "write_box_stl"]

SERVO = "XL430-W250"


@dataclass(frozen=True)
class ImportCase:
    """A written case: the model file, what to import it with, and what the import must say."""

    name: str
    model: Path
    servos: Path | None = None
    package_paths: tuple[Path, ...] = ()
    env: dict[str, str] = field(default_factory=dict)
    expect_notes: tuple[str, ...] = ()  # substrings some note must contain
    feature: str = ""


def write_box_stl(path: Path, half: tuple[float, float, float], center: tuple[float, float, float] = (0, 0, 0), flat: bool = False) -> None:
    """A binary STL box (12 triangles); ``flat``: two triangles of its bottom face only (no volume)."""
    hx, hy, hz = half
    cx, cy, cz = center
    v = [(cx + sx * hx, cy + sy * hy, cz + sz * hz) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    faces = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4), (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]
    if flat:
        faces = [(0, 4, 6), (0, 6, 2)]  # the bottom face (z = -hz): four distinct corners
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        f.write(b"robot_rise synthetic".ljust(80, b"\0"))
        f.write(struct.pack("<I", len(faces)))
        for tri in faces:
            f.write(struct.pack("<3f", 0.0, 0.0, 0.0))
            for i in tri:
                f.write(struct.pack("<3f", *v[i]))
            f.write(b"\0\0")


def _inertial(mass: float, box: tuple[float, float, float], xyz: str = "0 0 0", override: str = "") -> str:
    a, b, c = box
    ixx, iyy, izz = (mass / 12 * (b * b + c * c), mass / 12 * (a * a + c * c), mass / 12 * (a * a + b * b))
    inertia = override or f'ixx="{ixx:.3e}" iyy="{iyy:.3e}" izz="{izz:.3e}" ixy="0" ixz="0" iyz="0"'
    return f'<inertial><origin xyz="{xyz}"/><mass value="{mass}"/><inertia {inertia}/></inertial>'


def _link(name: str, mass: float, box: tuple[float, float, float], xyz: str, collision: str = "", inertia: str = "", yaw: float = 0.0) -> str:
    geom = collision or f'<box size="{box[0]} {box[1]} {box[2]}"/>'
    return (
        f'<link name="{name}">{_inertial(mass, box, xyz, inertia)}'
        f'<collision><origin xyz="{xyz}" rpy="0 0 {yaw:.6f}"/><geometry>{geom}</geometry></collision></link>'
    )


def _joint(name: str, parent: str, child: str, xyz: str, axis: str, lo: float, hi: float, effort: float = 1.5, rpy: str = "0 0 0") -> str:
    return (
        f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/><limit lower="{lo}" upper="{hi}" effort="{effort}" velocity="5"/></joint>'
    )


def _fixed(parent: str, child: str, xyz: str = "0 0 0") -> str:
    return f'<joint name="{parent}_to_{child}" type="fixed"><parent link="{parent}"/><child link="{child}"/><origin xyz="{xyz}"/></joint>'


def humanoid_urdf(
    *,
    foot_mesh: str = "",
    head_mesh: str = "",
    base: str = "torso",
    frames: bool = False,
    turn_yaw_rad: float = 0.0,
    bad_inertia: bool = False,
    massless_wrist: bool = False,
    placeholder_head: bool = False,
) -> str:
    """A small humanoid as URDF (x forward, y left, z up unless ``turn_yaw_rad`` turns every frame).

    Args:
        foot_mesh: the feet's collision geometry as this mesh URI (else boxes).
        head_mesh: the head's collision as this mesh URI (else a box).
        base: the root link; "base_link" puts a 0.1 g dummy link fixed above the torso.
        frames: fixed camera, IMU, wrist and sole frames (massless links).
        turn_yaw_rad: the root frame turned about z (a CAD export's axes): limbs placed in it.
        bad_inertia: the torso's inertia breaks the triangle inequality (a CAD rounding).
        massless_wrist: a wrist joint whose link has no mass (a dummy servo horn frame).
        placeholder_head: the head joint's limits are an exporter's default (effort 1000, +-pi).
    """
    c, s = math.cos(turn_yaw_rad), math.sin(turn_yaw_rad)

    def at(x: float, y: float, z: float) -> str:  # a point of the stand frame in the turned root frame
        return f"{c * x + s * y:.6f} {-s * x + c * y:.6f} {z:.6f}"

    def ax(x: float, y: float, z: float) -> str:
        return at(x, y, z)

    parts = ['<?xml version="1.0"?>', '<robot name="mini_humanoid">']
    torso_inertia = 'ixx="0.001" iyy="0.001" izz="0.0025" ixy="0" ixz="0" iyz="0"' if bad_inertia else ""
    parts.append(_link("torso", 0.45, (0.08, 0.14, 0.16), "0 0 0.08", inertia=torso_inertia, yaw=-turn_yaw_rad))
    if base != "torso":
        parts.append(f'<link name="{base}"><inertial><mass value="0.0001"/><inertia ixx="1e-9" iyy="1e-9" izz="1e-9" ixy="0" ixz="0" iyz="0"/></inertial></link>')
        parts.append(_fixed(base, "torso"))
    head_geom = f'<mesh filename="{head_mesh}"/>' if head_mesh else ""
    parts.append(_link("head", 0.08, (0.06, 0.06, 0.06), "0 0 0.04", collision=head_geom))
    lo, hi, effort = (-math.pi, math.pi, 1000.0) if placeholder_head else (-1.5, 1.5, 1.5)
    parts.append(_joint("neck_yaw", "torso", "head", at(0, 0, 0.18), ax(0, 0, 1), lo, hi, effort))
    if frames:
        for name, xyz in (("camera_frame", at(0.03, 0, 0.22)), ("imu_frame", at(0, 0, 0.05))):
            parts.append(f'<link name="{name}"/>')
            parts.append(_fixed("torso" if name == "imu_frame" else "head", name, xyz if name == "imu_frame" else "0.03 0 0.04"))
    for side, y in (("l", 1.0), ("r", -1.0)):
        # leg: hip roll, hip pitch, knee, ankle pitch, ankle roll
        parts.append(_link(f"{side}_hip", 0.04, (0.03, 0.03, 0.03), "0 0 0"))
        parts.append(_link(f"{side}_thigh", 0.12, (0.04, 0.04, 0.1), "0 0 -0.06"))
        parts.append(_link(f"{side}_shin", 0.1, (0.035, 0.035, 0.1), "0 0 -0.06"))
        parts.append(_link(f"{side}_ankle", 0.03, (0.03, 0.03, 0.03), "0 0 0"))
        foot = f'<mesh filename="{foot_mesh}"/>' if foot_mesh else ""
        parts.append(_link(f"{side}_foot", 0.08, (0.12, 0.07, 0.01), at(0.015, 0, -0.03), collision=foot, yaw=-turn_yaw_rad))
        parts.append(_joint(f"{side}_hip_roll", "torso", f"{side}_hip", at(0, 0.04 * y, -0.01), ax(1, 0, 0), -0.5, 0.5))
        parts.append(_joint(f"{side}_hip_flex", f"{side}_hip", f"{side}_thigh", "0 0 0", ax(0, 1, 0), -1.8, 0.6))
        parts.append(_joint(f"{side}_knee", f"{side}_thigh", f"{side}_shin", at(0, 0, -0.12), ax(0, 1, 0), 0.0, 2.3))
        parts.append(_joint(f"{side}_ankle_pitch", f"{side}_shin", f"{side}_ankle", at(0, 0, -0.12), ax(0, 1, 0), -1.2, 1.2))
        parts.append(_joint(f"{side}_ankle_roll", f"{side}_ankle", f"{side}_foot", "0 0 0", ax(1, 0, 0), -0.5, 0.5))
        # arm: shoulder pitch, shoulder roll, elbow
        parts.append(_link(f"{side}_shoulder", 0.02, (0.02, 0.02, 0.02), "0 0 0"))
        parts.append(_link(f"{side}_upper_arm", 0.06, (0.03, 0.03, 0.08), "0 0 -0.05"))
        parts.append(_link(f"{side}_forearm", 0.05, (0.025, 0.025, 0.08), "0 0 -0.05"))
        parts.append(_joint(f"{side}_shoulder_pitch", "torso", f"{side}_shoulder", at(0, 0.09 * y, 0.15), ax(0, 1, 0), -3.0, 3.0))
        parts.append(_joint(f"{side}_shoulder_roll", f"{side}_shoulder", f"{side}_upper_arm", "0 0 0", ax(1, 0, 0), -0.3 if y > 0 else -1.6, 1.6 if y > 0 else 0.3))
        parts.append(_joint(f"{side}_elbow", f"{side}_upper_arm", f"{side}_forearm", at(0, 0, -0.1), ax(0, 1, 0), -2.0, 0.0))
        if massless_wrist:
            parts.append(f'<link name="{side}_hand"><inertial><mass value="0"/><inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial></link>')
            parts.append(_joint(f"{side}_wrist", f"{side}_forearm", f"{side}_hand", at(0, 0, -0.1), ax(0, 0, 1), -1.0, 1.0))
        if frames:
            parts.append(f'<link name="{side}_sole"/>')
            parts.append(_fixed(f"{side}_foot", f"{side}_sole", at(0.015, 0, -0.035)))
            parts.append(f'<link name="{side}_wrist_frame"/>')
            parts.append(_fixed(f"{side}_forearm", f"{side}_wrist_frame", at(0, 0, -0.1)))
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


_PACKAGE_XML = """<?xml version="1.0"?>
<package format="2"><name>{name}</name><version>0.0.1</version><description>synthetic</description>
<maintainer email="x@example.com">x</maintainer><license>MIT</license></package>
"""


def _package(root: Path, name: str) -> Path:
    pkg = root / name
    (pkg / "urdf").mkdir(parents=True, exist_ok=True)
    (pkg / "package.xml").write_text(_PACKAGE_XML.format(name=name))
    write_box_stl(pkg / "meshes" / "Foot.STL", (0.06, 0.035, 0.005))  # placed by the link's collision origin
    write_box_stl(pkg / "meshes" / "head.stl", (0.03, 0.03, 0.03))
    return pkg


def _ros_package(d: Path) -> ImportCase:
    pkg = _package(d / "ws" / "src", "mini_description")
    urdf = humanoid_urdf(foot_mesh="package://mini_description/meshes/foot.stl", head_mesh="package:///meshes/head.stl")
    (pkg / "urdf" / "mini.URDF").write_text(urdf)
    return ImportCase(
        "ros_package", pkg / "urdf" / "mini.URDF",
        expect_notes=("package://mini_description/meshes/foot.stl: no such file; took", "(the name differs in case)", "package:///meshes/head.stl ->"),
        feature="ROS package: package://NAME found among the file's ancestors, package:/// the package root, a .URDF suffix, a mesh name in other case",
    )  # fmt: skip


def _package_path(d: Path) -> ImportCase:
    _package(d / "elsewhere", "mini_meshes")
    model = d / "robot" / "mini.urdf"
    model.parent.mkdir(parents=True)
    model.write_text(humanoid_urdf(foot_mesh="package://mini_meshes/meshes/Foot.STL"))
    return ImportCase(
        "package_path", model, package_paths=(d / "elsewhere",), expect_notes=("package://mini_meshes/meshes/Foot.STL ->",),
        feature="package:// found only through --package-path (a package beside, not above, the file)",
    )  # fmt: skip


_XACRO = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="mini_xacro">
  <xacro:property name="foot" value="$(find mini_description)/meshes/Foot.STL"/>
  <xacro:include filename="$(find mini_description)/urdf/body.xacro"/>
</robot>
"""


def _xacro(d: Path) -> ImportCase:
    pkg = _package(d / "src", "mini_description")
    body = humanoid_urdf(foot_mesh="${foot}")
    body = body.replace('<?xml version="1.0"?>\n<robot name="mini_humanoid">', '<?xml version="1.0"?>\n<robot xmlns:xacro="http://www.ros.org/wiki/xacro">')
    (pkg / "urdf" / "body.xacro").write_text(body)
    (pkg / "urdf" / "mini.urdf.xacro").write_text(_XACRO)
    return ImportCase(
        "xacro", pkg / "urdf" / "mini.urdf.xacro", expect_notes=("(xacro)",),
        feature="xacro with $(find NAME), an included macro file and properties, expanded by xacrodoc",
    )  # fmt: skip


def _cad_urdf(d: Path) -> ImportCase:
    model = d / "cad.urdf"
    model.write_text(humanoid_urdf(bad_inertia=True, massless_wrist=True))
    return ImportCase(
        "cad_urdf", model, expect_notes=("triangle inequality", "mass floor", "mass "),
        feature="a CAD URDF: a torso inertia that breaks the triangle inequality, massless wrist links on joints",
    )  # fmt: skip


def _cad_mjcf(d: Path) -> ImportCase:
    import re  # noqa: PLC0415

    import mujoco  # noqa: PLC0415 (the bench's cases need MuJoCo only to write these)

    spec = mujoco.MjSpec.from_string(humanoid_urdf())
    spec.worldbody.bodies[0].add_freejoint()
    spec.compiler.discardvisual = False
    text = spec.to_xml()
    write_box_stl(d / "meshes" / "badge.stl", (0.02, 0.02, 0.0), flat=True)  # a decal: 40 mm across, no thickness
    asset = '<mesh name="badge" file="meshes/badge.stl"/>'
    text = text.replace("<asset>", f"<asset>\n    {asset}", 1) if "<asset>" in text else text.replace("<worldbody>", f"<asset>\n    {asset}\n  </asset>\n  <worldbody>", 1)
    # a visual shell of zero volume on the head (MuJoCo refuses its solid inertia), and a torso
    # inertia that breaks the triangle inequality
    head = text.index('<body name="head"')
    head_end = text.index(">", head) + 1
    text = text[:head_end] + '\n        <geom name="badge_visual" type="mesh" mesh="badge" contype="0" conaffinity="0" group="1" pos="0.03 0 0.04"/>' + text[head_end:]
    torso = text.index('<body name="torso"')
    inertial = re.compile(r"<inertial[^>]*/>")
    found = inertial.search(text, torso)
    assert found is not None
    text = text[: found.start()] + '<inertial pos="0 0 0.08" mass="0.45" diaginertia="0.001 0.001 0.0025"/>' + text[found.end() :]
    model = d / "cad.xml"
    model.write_text(text)
    return ImportCase(
        "cad_mjcf", model, expect_notes=("triangle inequality", "shell inertia"),
        feature="a CAD MJCF: a zero-volume visual mesh (MuJoCo: 'try setting inertia to shell'), a torso inertia off the triangle inequality",
    )  # fmt: skip


def _fixed_links(d: Path) -> ImportCase:
    model = d / "frames.urdf"
    model.write_text(humanoid_urdf(base="base_link", frames=True))
    return ImportCase(
        "fixed_links", model, expect_notes=("URDF root link 'base_link' (free joint added)",),
        feature="a 0.1 g base_link fixed to the torso, no floating joint, camera, IMU, wrist and sole frames",
    )  # fmt: skip


def _torso_frame_mjcf(d: Path) -> ImportCase:
    from xml.etree import ElementTree  # noqa: PLC0415

    import mujoco  # noqa: PLC0415

    spec = mujoco.MjSpec.from_string(humanoid_urdf())
    spec.compiler.fusestatic = False
    spec.worldbody.bodies[0].add_freejoint()
    root = ElementTree.fromstring(spec.to_xml())
    torso = root.find("worldbody/body")
    assert torso is not None
    # a jointless frame body between the floating base and every limb (as CAD trees have)
    frame = ElementTree.Element("body", {"name": "torso_frame", "pos": "0 0 0.001"})
    for child in [c for c in torso if c.tag == "body"]:
        torso.remove(child)
        frame.append(child)
    torso.append(frame)
    model = d / "torso_frame.xml"
    model.write_text(ElementTree.tostring(root, encoding="unicode"))
    return ImportCase(
        "torso_frame", model, expect_notes=("floating base: body 'torso'",),
        feature="MJCF with a jointless torso frame body between the free body and the limbs",
    )  # fmt: skip


_SCENE_MAIN = """<mujoco model="mini_scene">
  <compiler angle="radian" meshdir="parts"/>
  <default>
    <default class="servo"><joint damping="0.1" armature="0.002"/></default>
    <default class="shell"><geom rgba="0.8 0.8 0.8 1"/></default>
  </default>
  <include file="body.xml"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <light pos="0 0 2"/>
  </worldbody>
  <contact>
    <pair name="left_sole_floor" geom1="l_foot_geom" geom2="floor"/>
    <pair name="right_sole_ground" geom1="r_foot_geom" geom2="ground_plane"/>
    <exclude body1="torso" body2="head"/>
  </contact>
</mujoco>
"""


def _scene_mjcf(d: Path) -> ImportCase:
    from xml.etree import ElementTree  # noqa: PLC0415

    import mujoco  # noqa: PLC0415

    write_box_stl(d / "parts" / "head.stl", (0.03, 0.03, 0.03))
    spec = mujoco.MjSpec.from_string(humanoid_urdf(head_mesh=str(d / "parts" / "head.stl")))
    spec.worldbody.bodies[0].add_freejoint()
    for g in spec.geoms:
        if g.parent.name in ("l_foot", "r_foot"):
            g.name = f"{g.parent.name}_geom"
    full = ElementTree.fromstring(spec.to_xml())
    body = ElementTree.Element("mujoco")
    for tag in ("asset", "worldbody"):
        part = full.find(tag)
        assert part is not None
        body.append(part)
    for mesh in body.iter("mesh"):
        mesh.set("file", "head.stl")  # relative to the main file's meshdir
    for joint in body.iter("joint"):
        if joint.get("name", "").endswith("_knee"):
            joint.set("class", "servo")
    (d / "body.xml").write_text(ElementTree.tostring(body, encoding="unicode"))
    model = d / "scene.xml"
    model.write_text(_SCENE_MAIN)
    return ImportCase(
        "scene_mjcf", model,
        expect_notes=("removed 1 world geoms (floor)", "pair left_sole_floor (floor)", "pair right_sole_ground (ground_plane)"),
        feature="MJCF written for a scene: <include>d body, default classes, an asset directory, a floor and contact pairs naming it",
    )  # fmt: skip


def _turned_frame(d: Path) -> ImportCase:
    model = d / "turned.urdf"
    model.write_text(humanoid_urdf(turn_yaw_rad=math.pi / 2))
    return ImportCase(
        "turned_frame", model, expect_notes=("stand frame: the file's root frame is not x forward",),
        feature="the root frame turned a quarter about z (forward is the file's -y), as CAD exports write it",
    )  # fmt: skip


def _limits(d: Path) -> ImportCase:
    model = d / "limits.urdf"
    model.write_text(humanoid_urdf(placeholder_head=True))
    rows = []
    for i, (joint, lo, hi) in enumerate(
        [("neck_yaw", -1.2, 1.2)]
        + [(f"{s}_{j}", lo, hi) for s in "lr" for j, lo, hi in (("hip_roll", -0.5, 0.5), ("hip_flex", -1.8015, 0.6), ("knee", 0.0, 2.3),
                                                            ("ankle_pitch", -1.2, 1.2), ("ankle_roll", -0.5, 0.5), ("shoulder_pitch", -3.0, 3.0),
                                                            ("elbow", -2.0, 0.0))]
        + [("l_shoulder_roll", -0.3, 1.6), ("r_shoulder_roll", -1.6, 0.3)]
    ):  # fmt: skip
        rows.append(f'[[servo]]\nid = {i + 1}\njoint = "{joint}"\nmodel = "{SERVO}"\ndirection = 1\nzero_offset = 0.0\nmin = {lo}\nmax = {hi}\n')
    servos = d / "servos.toml"
    servos.write_text('format = "robot-rise/servos@1"\nrobot = "mini_limits"\n\n' + "\n".join(rows))
    return ImportCase(
        "limits", model, servos=servos,
        expect_notes=("placeholder ranges, replaced by the servo map's: neck_yaw", "taken as the model's: l_hip_flex"),
        feature="a servo map limit 1.5 mrad past the model's (rounding), a placeholder range (effort 1000, +-pi) the servo map replaces",
    )  # fmt: skip


def _mjcf_tree(fusestatic: bool = False):  # type: ignore[no-untyped-def]
    """The humanoid as an MJCF element tree (a free joint on the torso)."""
    from xml.etree import ElementTree  # noqa: PLC0415

    import mujoco  # noqa: PLC0415

    spec = mujoco.MjSpec.from_string(humanoid_urdf())
    spec.compiler.fusestatic = fusestatic
    spec.worldbody.bodies[0].add_freejoint()
    return ElementTree.fromstring(spec.to_xml())


def _four_bar_knee(d: Path) -> ImportCase:
    """Each knee a parallelogram four-bar: beside the knee joint (thigh -> shin) a rocker on a
    passive hinge of the thigh, a coupler on a passive hinge of the rocker, the coupler's far end
    pinned to the shin by an equality ``connect``; the file actuates the driven joints."""
    from xml.etree import ElementTree  # noqa: PLC0415

    root = _mjcf_tree()
    bodies = {b.get("name"): b for b in root.iter("body")}
    equality = ElementTree.SubElement(root, "equality")
    actuator = ElementTree.SubElement(root, "actuator")
    thin = {"contype": "0", "conaffinity": "0", "mass": "0.005"}
    for side in "lr":
        # knee A at (0, 0, -0.12) of the thigh; rocker pivot C = A + (0.012, 0, -0.028) on a bracket;
        # rocker and crank 40 mm long, the coupler as long as A-C: a parallelogram, one degree of
        # freedom, its links collinear only at knee angles outside the knee's range (-0.41, 2.74 rad)
        rocker = ElementTree.SubElement(bodies[f"{side}_thigh"], "body", {"name": f"{side}_knee_rocker", "pos": "0.012 0 -0.148"})
        ElementTree.SubElement(rocker, "joint", {"name": f"{side}_knee_rocker", "axis": "0 1 0", "range": "-2.8 2.8"})
        ElementTree.SubElement(rocker, "geom", {"type": "capsule", "fromto": "0 0 0 0 0 -0.04", "size": "0.003", **thin})
        coupler = ElementTree.SubElement(rocker, "body", {"name": f"{side}_knee_coupler", "pos": "0 0 -0.04"})
        ElementTree.SubElement(coupler, "joint", {"name": f"{side}_knee_coupler", "axis": "0 1 0", "range": "-2.8 2.8"})
        ElementTree.SubElement(coupler, "geom", {"type": "capsule", "fromto": "0 0 0 -0.012 0 0.028", "size": "0.003", **thin})
        ElementTree.SubElement(equality, "connect", {"name": f"{side}_knee_loop", "body1": f"{side}_knee_coupler", "body2": f"{side}_shin", "anchor": "-0.012 0 0.028"})
    for j in root.iter("joint"):
        name = j.get("name", "")
        if name and "_knee_" not in name:
            ElementTree.SubElement(actuator, "position", {"name": name, "joint": name, "kp": "10"})
    model = d / "four_bar.xml"
    model.write_text(ElementTree.tostring(root, encoding="unicode"))
    return ImportCase(
        "four_bar_knee", model, expect_notes=("passive joints", "closed loops: l_knee_rocker, l_knee_coupler, r_knee_rocker, r_knee_coupler"),
        feature="closed four-bar knees (rocker and coupler on passive hinges, pinned to the shin by an equality connect), the file actuating the driven joints",
    )  # fmt: skip


def _coupled_joints(d: Path) -> ImportCase:
    """A neck of two yaw joints, the upper following the lower (equality ``joint``), and each
    forearm's passive wrist turned through a tendon coupled to the elbow (equality ``tendon``)."""
    from xml.etree import ElementTree  # noqa: PLC0415

    root = _mjcf_tree()
    bodies = {b.get("name"): b for b in root.iter("body")}
    head = bodies["head"]
    top = ElementTree.SubElement(head, "body", {"name": "head_top", "pos": "0 0 0.06"})
    ElementTree.SubElement(top, "joint", {"name": "neck_yaw_upper", "axis": "0 0 1", "range": "-1 1"})
    ElementTree.SubElement(top, "geom", {"type": "sphere", "size": "0.015", "mass": "0.01"})
    tendon = ElementTree.SubElement(root, "tendon")
    equality = ElementTree.SubElement(root, "equality")
    ElementTree.SubElement(equality, "joint", {"name": "neck_coupling", "joint1": "neck_yaw_upper", "joint2": "neck_yaw", "polycoef": "0 0.5 0 0 0"})
    for side in "lr":
        hand = ElementTree.SubElement(bodies[f"{side}_forearm"], "body", {"name": f"{side}_hand", "pos": "0 0 -0.1"})
        ElementTree.SubElement(hand, "joint", {"name": f"{side}_wrist", "axis": "0 0 1", "range": "-1.5 1.5"})
        ElementTree.SubElement(hand, "geom", {"type": "box", "size": "0.01 0.015 0.02", "pos": "0 0 -0.02", "mass": "0.02"})
        for name, joint in ((f"{side}_wrist_drive", f"{side}_wrist"), (f"{side}_elbow_drive", f"{side}_elbow")):
            fixed = ElementTree.SubElement(tendon, "fixed", {"name": name})
            ElementTree.SubElement(fixed, "joint", {"joint": joint, "coef": "1"})
        ElementTree.SubElement(equality, "tendon", {"name": f"{side}_wrist_coupling", "tendon1": f"{side}_wrist_drive", "tendon2": f"{side}_elbow_drive", "polycoef": "0 0.3 0 0 0"})
    model = d / "coupled.xml"
    model.write_text(ElementTree.tostring(root, encoding="unicode"))
    return ImportCase(
        "coupled_joints", model, expect_notes=("passive joints", "joint couplings: neck_yaw_upper, l_wrist, r_wrist"),
        feature="coupled joints: an upper neck joint following the lower (equality joint, polycoef) and wrists driven by tendons coupled to the elbows",
    )  # fmt: skip


CASES: dict[str, Callable[[Path], ImportCase]] = {
    "ros_package": _ros_package,
    "package_path": _package_path,
    "xacro": _xacro,
    "cad_urdf": _cad_urdf,
    "cad_mjcf": _cad_mjcf,
    "fixed_links": _fixed_links,
    "torso_frame": _torso_frame_mjcf,
    "scene_mjcf": _scene_mjcf,
    "turned_frame": _turned_frame,
    "limits": _limits,
    "four_bar_knee": _four_bar_knee,
    "coupled_joints": _coupled_joints,
}


def write_case(name: str, directory: Path) -> ImportCase:
    """Write case ``name`` into ``directory`` (created) and say how to import it."""
    directory.mkdir(parents=True, exist_ok=True)
    return CASES[name](directory)
