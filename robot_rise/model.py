"""The robot: loads a robot directory and composes it with a scene into a MuJoCo model.

A robot directory holds ``robot.toml`` (format ``robot-rise/robot@1``: metric groups, limbs,
sites), ``robot.xml`` (MJCF: bodies, joints with ranges, collision geoms, a ``stand`` keyframe,
a free joint at the root) and ``servos.toml`` (format ``robot-rise/servos@1``: servo per joint,
read by :func:`robot_files.servo_map.read_servo_map`, the reader ``drivers`` uses too). This is
the only module that knows MJCF layout details. Nothing here names a joint of a particular robot.
"""

from __future__ import annotations

import hashlib
import logging
import os
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import mujoco
import numpy as np

from robot_files.servo_map import SERVO_MAP_FILE, SUPPLY_RANGE_V, SUPPLY_VOLTAGE_V, check_supply_voltage, read_servo_map
from robot_files.toml_file import read_toml
from robot_rise.constants import ENVELOPE_MARGIN, METRIC_GROUP_WEIGHTS, ROOT_ORIENTATION_WEIGHT
from robot_rise.errors import ConfigError, SceneError, as_config_error, mujoco_reason
from robot_rise.linkage import Linkage, close_loops, linkage_of
from robot_rise.model_files import model_files
from robot_rise.tendons import attach_tendons, detach_tendons
from robot_rise.paths import default_robot_dir, scene_path
from robot_rise.roles import JointRole, RoleMap
from robot_rise.servo import ROBOT_SERVO_MODELS_FILE, ServoDatasheet, servo_datasheet

__all__ = [
    "Robot",
    "ServoAssignment",
    "ModelIndex",
    "load_robot",
    "model_files",
    "compose",
    "model_index",
    "GROUND_PREFIX",
    "GEOM_ROBOT",
    "GEOM_GROUND",
    "GEOM_OBSTACLE",
    "SIM_TIMESTEP_S",
    "SUPPLY_RANGE_V",
    "SUPPLY_VOLTAGE_V",
    "supply_voltage",
]

log = logging.getLogger(__name__)
_mujoco_log = logging.getLogger("mujoco")


def _mujoco_warning(message: str) -> None:
    _mujoco_log.warning("%s", message.strip())


# MuJoCo's own warning handler appends to MUJOCO_LOG.TXT in the working directory (a file the user
# never asked for, left behind by a model it warns about): its warnings go to logging instead,
# unless the program using robot_rise has set a handler of its own
if mujoco.get_mju_user_warning() is None:
    mujoco.set_mju_user_warning(_mujoco_warning)

ROBOT_FORMAT = "robot-rise/robot@1"
GROUND_PREFIX = "ground"  # world geoms named ground* are the ground; others are obstacles
GEOM_ROBOT, GEOM_GROUND, GEOM_OBSTACLE = 0, 1, 2  # ModelIndex.geom_kind values
SIM_TIMESTEP_S = 0.002  # physics step: 500 Hz (issue 4 asks for >= 500 Hz)
# SUPPLY_VOLTAGE_V (the supply a robot is modelled at unless its servo map gives one) and
# SUPPLY_RANGE_V (the typo guard on it) are the servo map format's: robot_files.servo_map.
_ATTACH_PREFIX = "robot_rise:"


@dataclass(frozen=True)
class ServoAssignment:
    """One row of ``servos.toml``: which servo drives which joint. Angles in radians."""

    id: int
    joint: str
    model: str
    direction: int
    zero_offset: float
    lower: float
    upper: float


@dataclass(frozen=True)
class Robot:
    """A loaded robot directory (no MuJoCo state; compose() builds models).

    Attributes:
        name: robot name (e.g. "op3"), written into posture and trajectory files.
        directory: the robot directory.
        joint_names: actuated joints in model order, shape (n,).
        joint_lower, joint_upper: joint ranges from the MJCF [rad], shape (n,).
        servos: servo assignment per joint, in joint order.
        metric_weights: per-joint weights w^i of paper 000 eq. (3), shape (n,).
        limbs: limb name -> joint names (paper 004's five linkages; partial-body planning).
        sole_sites, torso_site: site names for the standing judge.
        stand_qpos: qpos of the ``stand`` keyframe (robot alone), shape (7 + n,).
        xml_path: the robot MJCF.
        root_body: name of the body carrying the free joint.
        keyframes: every keyframe's qpos (robot alone) by name.
        library: the motion library the robot uses: a directory relative to the robot directory
            if one exists there (an imported robot's ``motions``), else a shipped library name
            (``configs/motions/<library>``); a retargeted variant keeps its source robot's library
            (paper 000 section 5.3).
        roles: joint roles (``[roles]`` of robot.toml, :mod:`robot_rise.roles`); None if not given.
        supply_voltage_v: the servos' supply [V] (servos.toml ``[bus] supply_voltage_v``): the
            stall torque, no-load speed and position gain every simulation of this robot uses.
        passive_joints: hinges no servo drives, moved by the model's equality constraints (a
            four-bar knee's rod, a coupled neck joint; ``robot.toml`` ``passive``): solved by
            :func:`robot_rise.linkage.close_loops` wherever a posture becomes a qpos.
        bus_protocol: the servos' Dynamixel protocol (servos.toml ``[bus] protocol``): an MX on
            Protocol 1.0 firmware has its own gains (the catalog's ``MX-28(1.0)``).
    """

    name: str
    directory: Path
    joint_names: tuple[str, ...]
    joint_lower: np.ndarray
    joint_upper: np.ndarray
    servos: tuple[ServoAssignment, ...]
    metric_weights: np.ndarray
    limbs: dict[str, tuple[str, ...]]
    sole_sites: tuple[str, ...]
    torso_site: str
    stand_qpos: np.ndarray
    xml_path: Path
    root_body: str
    keyframes: dict[str, np.ndarray] = field(default_factory=dict)
    library: str = ""
    roles: RoleMap | None = None
    supply_voltage_v: float = SUPPLY_VOLTAGE_V
    passive_joints: tuple[str, ...] = ()
    bus_protocol: float = 2.0

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def root_orientation_weight(self) -> float:
        """w_q of paper 000 eq. (1)."""
        return ROOT_ORIENTATION_WEIGHT

    def joint_index(self, name: str) -> int:
        """Index of a joint in joint_names; ConfigError naming the valid joints otherwise."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise ConfigError(f"robot {self.name} has no joint {name!r}; joints: {', '.join(self.joint_names)}") from None

    def servo_datasheets(self) -> tuple[ServoDatasheet, ...]:
        """Servo spec per joint, in joint order (looked up once per loaded robot, like its model)."""
        return self._servo_datasheets

    @cached_property
    def _servo_datasheets(self) -> tuple[ServoDatasheet, ...]:
        # once: the catalog lookup stats two files per joint (a planning timer asked 120 times
        # per rise, 0.25 s of a guard's 1-2 s thinking: profile of 2026-12-03)
        extra = self.directory / ROBOT_SERVO_MODELS_FILE
        return tuple(servo_datasheet(firmware_model(s.model, self.bus_protocol, extra), extra_catalog=extra) for s in self.servos)

    @cached_property
    def _stand(self) -> tuple[mujoco.MjModel, mujoco.MjData, ModelIndex]:
        """The robot alone (with its servos) in the ``stand`` keyframe, forward dynamics computed."""
        m = compose(self, None)
        d = mujoco.MjData(m)
        idx = model_index(m, self)
        d.qpos[:] = m.qpos0
        d.qpos[idx.qpos_root] = self.stand_qpos[:7]
        d.qpos[idx.qpos_joints] = self.stand_qpos[7:]
        if idx.linkage is not None:
            close_loops(m, d, idx.linkage)
        mujoco.mj_forward(m, d)
        return m, d, idx

    @cached_property
    def stand_height_m(self) -> float:
        """Height of the torso site above the soles in the ``stand`` keyframe [m]."""
        d = self._stand[1]
        sole_z = min(d.site(s).xpos[2] for s in self.sole_sites)
        return float(d.site(self.torso_site).xpos[2] - sole_z)

    @cached_property
    def joint_inertia_kg_m2(self) -> np.ndarray:
        """Each joint's inertia about its own axis in the ``stand`` keyframe, the servo's armature
        included [kg m^2], shape (n,): the diagonal of MuJoCo's joint-space inertia matrix."""
        m, d, idx = self._stand
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, full)
        return full[idx.dof_joints, idx.dof_joints].copy()

    def joint_accel_limits_rad_s2(self, speed_fraction: float) -> np.ndarray:
        """Per joint, the acceleration its servo can give the joint's own inertia while turning at
        ``speed_fraction`` of its no-load speed, within the envelope margin [rad/s^2], shape (n,).

        The DC-motor envelope leaves ``stall (1 - speed_fraction)`` at that speed, of which the
        filter lets a motion use ``1 - ENVELOPE_MARGIN`` (robot_rise/servo.py): so a trapezoid at
        this acceleration and speed stays inside the envelope for an unloaded limb (OP3: 28 rad/s^2
        for the hips, 60 for the arms at 0.8 of no-load). Loads (gravity, contacts) are the
        dynamics filter's to find: it slows what exceeds the envelope.
        """
        if not 0.0 <= speed_fraction < 1.0:
            raise ValueError(f"speed_fraction must lie in [0, 1), not {speed_fraction}")
        stall = np.array([s.stall_torque_at(self.supply_voltage_v) for s in self.servo_datasheets()])
        return (1.0 - ENVELOPE_MARGIN) * (1.0 - speed_fraction) * stall / self.joint_inertia_kg_m2

    def digest(self) -> str:
        """SHA-256 over every file of the robot (identifies the model a result was proven on).

        robot.toml, the MJCF and servos.toml, the datasheet figures of its servo models (the
        product catalog or the robot's ``servo_models.toml``), then every file the MJCF loads (included XML,
        meshes, skins, height fields, textures; ``model_files``), each by its path relative to the
        robot directory and its bytes. A robot of the three files alone keeps the digest of those.
        """
        h = hashlib.sha256()
        for path in (self.directory / "robot.toml", self.xml_path, self.directory / "servos.toml"):
            h.update(path.read_bytes())
        for sheet in sorted({repr(s) for s in self.servo_datasheets()}):  # the servo figures proofs rest on
            h.update(sheet.encode())
        for path in model_files(self.xml_path):
            h.update(os.path.relpath(path, self.directory).encode())
            h.update(path.read_bytes())
        return h.hexdigest()


def _read_toml(path: Path, fmt: str) -> dict:
    with as_config_error():
        data = read_toml(path, "file", hint="a robot directory needs robot.toml, robot.xml and servos.toml")
    if data.get("format") != fmt:
        raise ConfigError(f"{path}: format is {data.get('format')!r}, expected {fmt!r}")
    return data


def load_robot(directory: str | os.PathLike[str] | None = None) -> Robot:
    """Load a robot directory (default: the embedded OP3-class robot).

    Raises:
        ConfigError: a file is missing or malformed, or the files disagree with each other.
    """
    root = Path(directory) if directory is not None else default_robot_dir()
    if not root.is_dir():
        raise ConfigError(f"robot directory {root} does not exist", hint="pass --robot DIR with robot.toml, robot.xml, servos.toml")
    meta = _read_toml(root / "robot.toml", ROBOT_FORMAT)
    xml_path = root / meta.get("model", "robot.xml")
    try:
        spec = mujoco.MjSpec.from_file(str(xml_path))
        m = spec.compile()
    except Exception as e:  # mujoco raises ValueError with the parser message
        raise ConfigError(f"{xml_path}: cannot load MJCF: {mujoco_reason(e)}") from e

    free = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) != 1:
        raise ConfigError(f"{xml_path}: needs exactly one free joint at the root, found {len(free)}")
    root_body = m.body(m.jnt_bodyid[free[0]]).name
    hinge = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    if len(hinge) != m.njnt - 1:
        raise ConfigError(f"{xml_path}: only hinge joints (plus the root free joint) are supported")
    passive = meta.get("passive", [])
    if not isinstance(passive, list) or not all(isinstance(p, str) for p in passive):
        raise ConfigError(f"{root / 'robot.toml'}: passive must be a list of joint names")
    unknown = [p for p in passive if p not in {m.joint(j).name for j in hinge}]
    if unknown:
        raise ConfigError(f"{root / 'robot.toml'}: passive names joints {xml_path.name} lacks: {', '.join(unknown)}")
    if passive and not m.neq:
        raise ConfigError(f"{root / 'robot.toml'}: passive joints {', '.join(passive)}, but {xml_path.name} has no equality constraint to move them")
    hinge = [j for j in hinge if m.joint(j).name not in passive]
    joint_names = tuple(m.joint(j).name for j in hinge)
    if not all(m.jnt_limited[j] for j in hinge):
        bad = [m.joint(j).name for j in hinge if not m.jnt_limited[j]]
        raise ConfigError(f"{xml_path}: joints without range: {', '.join(bad)}")
    lower = np.array([m.jnt_range[j, 0] for j in hinge])
    upper = np.array([m.jnt_range[j, 1] for j in hinge])

    keyframes = {m.key(k).name: m.key_qpos[k].copy() for k in range(m.nkey)}
    if "stand" not in keyframes:
        raise ConfigError(f"{xml_path}: a keyframe named 'stand' is required")

    groups = meta.get("metric_groups", {})
    weights = np.full(len(joint_names), METRIC_GROUP_WEIGHTS["default"])
    for group, joints in groups.items():
        if group not in METRIC_GROUP_WEIGHTS:
            raise ConfigError(f"{root / 'robot.toml'}: unknown metric group {group!r}; known: {', '.join(METRIC_GROUP_WEIGHTS)}")
        for j in joints:
            if j not in joint_names:
                raise ConfigError(f"{root / 'robot.toml'}: metric group {group} names unknown joint {j!r}")
            weights[joint_names.index(j)] = METRIC_GROUP_WEIGHTS[group]

    limbs = {k: tuple(v) for k, v in meta.get("limbs", {}).items()}
    in_limbs = [j for v in limbs.values() for j in v]
    if limbs and sorted(in_limbs) != sorted(joint_names):
        raise ConfigError(f"{root / 'robot.toml'}: [limbs] must list every joint exactly once")

    sites = meta.get("sites", {})
    sole_sites = tuple(sites.get("soles", ()))
    torso_site = sites.get("torso", "")
    for s in (*sole_sites, torso_site):
        if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) < 0:
            raise ConfigError(f"{root / 'robot.toml'}: site {s!r} is not in {xml_path.name}")

    servos, supply_v, protocol = _load_servos(root / meta.get("servos", SERVO_MAP_FILE), joint_names, lower, upper, root / ROBOT_SERVO_MODELS_FILE)
    roles = _load_roles(root / "robot.toml", meta.get("roles"), joint_names)

    # Key qpos in the robot-alone model: root (7) then hinges in order (jnt_qposadr increasing).
    stand = keyframes["stand"]
    key_joint = np.array([stand[m.jnt_qposadr[j]] for j in hinge])
    qpos_stand = np.concatenate([stand[m.jnt_qposadr[free[0]] : m.jnt_qposadr[free[0]] + 7], key_joint])
    return Robot(
        name=meta.get("name", root.name),
        directory=root,
        joint_names=joint_names,
        joint_lower=lower,
        joint_upper=upper,
        servos=servos,
        metric_weights=weights,
        limbs=limbs,
        sole_sites=sole_sites,
        torso_site=torso_site,
        stand_qpos=qpos_stand,
        xml_path=xml_path,
        root_body=root_body,
        keyframes=keyframes,
        library=str(meta.get("library", meta.get("name", root.name))),
        roles=roles,
        supply_voltage_v=supply_v,
        passive_joints=tuple(passive),
        bus_protocol=protocol,
    )


def _load_roles(path: Path, table: object, joint_names: tuple[str, ...]) -> RoleMap | None:
    """``[roles]``: joint = {role, sign, neutral}; every joint once (``extra`` for the unroled)."""
    if table is None:
        return None
    if not isinstance(table, dict):
        raise ConfigError(f"{path}: [roles] must be a table of joint = {{ role, sign, neutral }}")
    unknown = [j for j in table if j not in joint_names]
    if unknown:
        raise ConfigError(f"{path}: [roles] names unknown joints {', '.join(unknown)}")
    missing = [j for j in joint_names if j not in table]
    if missing:
        raise ConfigError(f"{path}: [roles] lacks joints {', '.join(missing)} (give them role = \"extra\" to hold them)")
    try:
        rows = tuple(
            JointRole(j, str(table[j]["role"]), int(table[j].get("sign", 1)), float(table[j].get("neutral", 0.0))) for j in joint_names
        )
        return RoleMap(rows)
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise ConfigError(f"{path}: [roles]: {e}") from e


def supply_voltage(value: object, where: str) -> float:
    """``value`` as a servo supply [V]; ConfigError naming ``where`` unless a number in ``SUPPLY_RANGE_V``."""
    with as_config_error():
        return check_supply_voltage(value, where)


def firmware_model(model: str, protocol: float, extra_catalog: Path | None = None) -> str:
    """The catalog entry of a servo model on a bus of ``protocol``: ``MX-28`` on Protocol 1.0 is
    the catalog's ``MX-28(1.0)`` where there is one (another control table, other gain units)."""
    if float(protocol) == 1.0 and not model.endswith(")"):
        candidate = f"{model}(1.0)"
        try:
            servo_datasheet(candidate, extra_catalog=extra_catalog)
            return candidate
        except ConfigError:
            return model
    return model


def _load_servos(
    path: Path, joint_names: tuple[str, ...], lower: np.ndarray, upper: np.ndarray, extra_catalog: Path
) -> tuple[tuple[ServoAssignment, ...], float, float]:
    """The servo per joint, in joint order, the supply voltage [V] and the protocol of ``[bus]``.

    The file is read by :func:`robot_files.servo_map.read_servo_map` (every row gives min and
    max); here it must also fit the model: known joints, each one driven, limits inside the
    model's ranges, models in the servo catalog.
    """
    with as_config_error():
        smap = read_servo_map(path)
    by_joint: dict[str, ServoAssignment] = {}
    for row in smap.servos:
        s = ServoAssignment(row.id, row.joint, row.model, row.direction, row.zero_offset, row.min, row.max)
        if s.joint not in joint_names:
            raise ConfigError(f"{path}: servo {s.id} drives unknown joint {s.joint!r}; joints: {', '.join(joint_names)}")
        i = joint_names.index(s.joint)
        if s.lower < lower[i] - 1e-6 or s.upper > upper[i] + 1e-6:
            raise ConfigError(
                f"{path}: servo {s.id} ({s.joint}) limits [{s.lower}, {s.upper}] must lie inside the model range [{lower[i]}, {upper[i]}]"
            )
        servo_datasheet(s.model, extra_catalog=extra_catalog)  # raises on an unknown model
        by_joint[s.joint] = s
    missing = [j for j in joint_names if j not in by_joint]
    if missing:
        raise ConfigError(f"{path}: no servo for joints {', '.join(missing)}")
    return tuple(by_joint[j] for j in joint_names), smap.bus.supply_voltage_v, smap.bus.protocol


@dataclass(frozen=True)
class ModelIndex:
    """Where the robot lives in a composed model's arrays (read-only index arrays).

    Attributes:
        qpos_root: 7 indices (position xyz, quaternion wxyz) of the root free joint.
        qvel_root: 6 indices of the root free joint in qvel.
        qpos_joints, dof_joints: per-joint indices in qpos / qvel, shape (n,).
        actuators: per-joint actuator indices, shape (n,) (empty if composed without actuators).
        robot_geoms, ground_geoms, obstacle_geoms: geom id arrays.
        root_body: body id of the root.
        geom_kind: per geom of the model, GEOM_ROBOT, GEOM_GROUND or GEOM_OBSTACLE, shape (ngeom,).
        linkage: the constraints and passive joints to close after setting a qpos (None: the
            robot has no passive joints; :func:`robot_rise.linkage.close_loops`).
    """

    qpos_root: np.ndarray
    qvel_root: np.ndarray
    qpos_joints: np.ndarray
    dof_joints: np.ndarray
    actuators: np.ndarray
    robot_geoms: np.ndarray
    ground_geoms: np.ndarray
    obstacle_geoms: np.ndarray
    root_body: int
    geom_kind: np.ndarray
    linkage: Linkage | None = None


def model_index(m: mujoco.MjModel, robot: Robot) -> ModelIndex:
    """Index the robot's joints, actuators and geoms in a composed model."""
    root_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, robot.root_body)
    free = int(m.body_jntadr[root_body])
    jids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in robot.joint_names]
    acts = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in robot.joint_names]
    world = m.geom_bodyid == 0
    names = [m.geom(g).name for g in range(m.ngeom)]
    ground = np.array([g for g in range(m.ngeom) if world[g] and names[g].startswith(GROUND_PREFIX)], dtype=int)
    obstacles = np.array([g for g in range(m.ngeom) if world[g] and not names[g].startswith(GROUND_PREFIX)], dtype=int)
    robot_geoms = np.array([g for g in range(m.ngeom) if not world[g]], dtype=int)

    def ro(a: list[int] | np.ndarray) -> np.ndarray:
        arr = np.asarray(a, dtype=int)
        arr.setflags(write=False)
        return arr

    kind = np.full(m.ngeom, GEOM_ROBOT, dtype=np.int8)
    kind[ground] = GEOM_GROUND
    kind[obstacles] = GEOM_OBSTACLE
    qa, da = int(m.jnt_qposadr[free]), int(m.jnt_dofadr[free])
    return ModelIndex(
        qpos_root=ro(np.arange(qa, qa + 7)),
        qvel_root=ro(np.arange(da, da + 6)),
        qpos_joints=ro([m.jnt_qposadr[j] for j in jids]),
        dof_joints=ro([m.jnt_dofadr[j] for j in jids]),
        actuators=ro([a for a in acts if a >= 0]),
        robot_geoms=ro(robot_geoms),
        ground_geoms=ro(ground),
        obstacle_geoms=ro(obstacles),
        root_body=root_body,
        geom_kind=ro(kind),
        linkage=linkage_of(m, robot.passive_joints) if getattr(robot, "passive_joints", ()) else None,
    )


def compose(
    robot: Robot,
    scene: str | os.PathLike[str] | None = "flat",
    *,
    with_actuators: bool = True,
    voltage_v: float | None = None,
    friction_scale: float = 1.0,
    mass_scale: float = 1.0,
) -> mujoco.MjModel:
    """Compose robot + scene (+ servo actuators) into one MuJoCo model.

    Args:
        robot: the loaded robot.
        scene: scene MJCF path or shipped scene name; None for the robot alone (no ground).
        with_actuators: add one Dynamixel position servo per joint (see robot_rise/servo.py):
            a position actuator with kp_eff and force range +-stall torque, plus back-EMF and gear
            damping, armature and friction loss on the joint.
        voltage_v: servo supply voltage [V] (None: the robot's own, ``Robot.supply_voltage_v``).
        friction_scale: multiplies every geom's sliding friction (robustness tests).
        mass_scale: multiplies every robot body's mass and inertia (robustness tests).

    Raises:
        SceneError: the scene cannot be read or composed.
    """
    rspec = mujoco.MjSpec.from_file(str(robot.xml_path))
    for k in list(rspec.keys):
        rspec.delete(k)
    rspec.nkey = 0  # a <size nkey> of the robot file would conflict with the scene's on attach
    if scene is None:
        spec = rspec
    else:
        path = scene_path(scene)
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except Exception as e:
            raise SceneError(f"cannot read scene {path}: {mujoco_reason(e)}", hint="shipped scenes: flat, beam, low_bed, table, slope, icy, soft") from e
        # Attach under a temporary prefix, then strip it: names stay the robot's own and MuJoCo
        # does not warn about an empty prefix.
        tendons = detach_tendons(rspec)
        frame = spec.worldbody.add_frame()
        frame.attach_body(rspec.body(robot.root_body), _ATTACH_PREFIX, "")
        for elements in (spec.bodies, spec.joints, spec.geoms, spec.sites, spec.cameras):
            for el in elements:
                if el.name.startswith(_ATTACH_PREFIX):
                    el.name = el.name[len(_ATTACH_PREFIX) :]
        # the robot's own collision filters name the renamed bodies and geoms
        for el, fields in [(e, ("bodyname1", "bodyname2")) for e in spec.excludes] + [(p, ("geomname1", "geomname2")) for p in spec.pairs]:
            for f in fields:
                if getattr(el, f).startswith(_ATTACH_PREFIX):
                    setattr(el, f, getattr(el, f)[len(_ATTACH_PREFIX) :])
        # closed linkages: equality constraints name the renamed bodies, joints and tendons
        for eq in spec.equalities:
            eq.name = eq.name.removeprefix(_ATTACH_PREFIX)
            eq.name1, eq.name2 = eq.name1.removeprefix(_ATTACH_PREFIX), eq.name2.removeprefix(_ATTACH_PREFIX)
        attach_tendons(spec, tendons)
    if voltage_v is None:
        voltage_v = robot.supply_voltage_v
    if with_actuators:
        for s, servo in zip(robot.servos, robot.servo_datasheets()):
            j = spec.joint(s.joint)
            j.damping[0] = servo.back_emf_damping_nm_s + servo.viscous_damping_nm_s
            j.armature = servo.armature_kg_m2
            j.frictionloss = servo.friction_loss_nm
            kp = servo.position_gain_nm_per_rad(voltage_v)
            act = spec.add_actuator()
            act.name = s.joint
            act.target = s.joint
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            act.gainprm[0] = kp
            act.biasprm[0:3] = [0.0, -kp, 0.0]
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = [s.lower, s.upper]
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            stall = servo.stall_torque_at(voltage_v)
            act.forcerange = [-stall, stall]
    spec.option.timestep = SIM_TIMESTEP_S
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    try:
        m = spec.compile()
    except Exception as e:
        raise SceneError(f"cannot compose robot {robot.name} with scene {scene}: {mujoco_reason(e)}") from e
    if friction_scale != 1.0:
        m.geom_friction[:, 0] *= friction_scale
    if mass_scale != 1.0:
        bodies = np.arange(1, m.nbody)  # every body but the world (scenes have static geoms only)
        m.body_mass[bodies] *= mass_scale
        m.body_inertia[bodies] *= mass_scale
    return m
