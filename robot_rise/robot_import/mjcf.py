"""``import_robot``: a robot directory (robot.xml, robot.toml, servos.toml, assets) from an MJCF, URDF or xacro file.

What robot_rise supplies itself is stripped from the model (actuators, sensors, keyframes other
than ``stand``: the servo model and the judge are ours); collision filters, defaults and geometry
are kept. Joint ranges missing from the joints come from the user's servo map, else from the
actuators' ``ctrlrange``; a joint with neither is refused by name. Sites are added for the soles
(under each foot's lowest geoms) and the torso (the floating base). The standing posture is the
model's ``stand`` keyframe, else searched (:mod:`robot_rise.robot_import.stand`) and checked by
holding it with the servo model. Every inference is returned as a note for the user; wrong
guesses are corrected in ``robot.toml``. The directory is written next to its destination and
renamed into place, so a failed import leaves nothing behind.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from robot_rise.errors import ConfigError
from robot_rise.model import ROBOT_FORMAT, SERVOS_FORMAT, SUPPLY_VOLTAGE_V, load_robot, supply_voltage
from robot_rise.robot_import.roles import InferredRoles, infer_roles, subtree_geoms
from robot_rise.robot_import.stand import stand_candidates
from robot_rise.servo import servo_datasheet

__all__ = ["ImportResult", "import_robot", "SOLE_SITE", "TORSO_SITE", "STAND_CHECK_S"]

SOLE_SITE = "robot_rise_{side}_sole"
TORSO_SITE = "robot_rise_torso"
STAND_CHECK_S = 2.0  # a found standing posture must be held this long by the servo model
ASSET_DIR = "assets"
POSITION_MODE_HALF_TURN_RAD = 3.14  # within +-pi, one tick clear of the wrap (4096 ticks per turn)


@dataclass(frozen=True)
class ImportResult:
    directory: Path
    name: str
    notes: tuple[str, ...] = field(default_factory=tuple)


def _load_spec(path: Path) -> tuple[mujoco.MjSpec, str]:
    """The model as an MjSpec and its kind (mjcf, urdf, xacro)."""
    if not path.is_file():
        raise ConfigError(f"{path}: no such model file")
    suffix = path.suffix.lower()
    if suffix == ".xacro":
        try:
            import xacrodoc  # type: ignore[import-not-found]
        except ImportError:
            raise ConfigError(f"{path}: a .xacro file needs the xacrodoc package", hint="pip install xacrodoc, or expand it to URDF first") from None
        try:
            urdf = xacrodoc.XacroDoc.from_file(str(path)).to_urdf_string()
            return mujoco.MjSpec.from_string(urdf), "xacro"
        except Exception as e:  # xacrodoc and mujoco raise various errors with their message
            raise ConfigError(f"{path}: cannot expand xacro: {str(e).splitlines()[0]}") from e
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except Exception as e:
        raise ConfigError(f"{path}: cannot load the model: {str(e).strip().splitlines()[-1]}") from e
    return spec, "urdf" if suffix == ".urdf" else "mjcf"


def _read_servo_map(path: Path) -> tuple[dict, list[dict]]:
    """The user's ``[bus]`` table (kept as given: baud rate, supply voltage) and servo rows."""
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise ConfigError(f"{path}: cannot read servo map: {e}") from e
    if data.get("format") != SERVOS_FORMAT:
        raise ConfigError(f"{path}: format is {data.get('format')!r}, expected {SERVOS_FORMAT!r}")
    rows = data.get("servo", [])
    if not rows:
        raise ConfigError(f"{path}: no [[servo]] rows")
    bus = data.get("bus", {})
    if not isinstance(bus, dict):
        raise ConfigError(f"{path}: [bus] must be a table")
    return bus, rows


def _copy_assets(spec: mujoco.MjSpec, source: Path, out: Path) -> list[str]:
    """Copy every mesh/texture/height field the model loads into ``out/assets``; point the spec there."""
    notes = []
    base = source.parent
    copied: dict[Path, str] = {}
    for kind, elements, directory in (
        ("mesh", list(spec.meshes) + list(spec.skins) + list(spec.hfields), spec.meshdir),
        ("texture", list(spec.textures), spec.texturedir),
    ):
        for el in elements:
            if not el.file:
                continue
            src = (base / directory / el.file).resolve()
            if not src.is_file():
                raise ConfigError(f"{source}: {kind} file {src} does not exist")
            name = copied.get(src) or f"{len(copied):03d}_{src.name}"
            copied[src] = name
            (out / ASSET_DIR).mkdir(exist_ok=True)
            shutil.copy2(src, out / ASSET_DIR / name)
            el.file = name
    spec.meshdir = ASSET_DIR
    spec.texturedir = ASSET_DIR
    spec.modelfiledir = str(out)  # assets resolve next to the written robot.xml
    if copied:
        notes.append(f"copied {len(copied)} asset files (meshes, textures) into {ASSET_DIR}/")
    return notes


def _free_joint(spec: mujoco.MjSpec, kind: str, path: Path) -> tuple[mujoco.MjsBody, list[str]]:
    roots = [b for b in spec.worldbody.bodies]
    free = [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) == 1:
        body = next(b for b in spec.bodies if any(j.name == free[0].name and j.type == free[0].type for j in b.joints))
        return body, [f"floating base: body {body.name!r} (free joint {free[0].name or '(unnamed)'})"]
    if len(free) > 1:
        raise ConfigError(f"{path}: {len(free)} free joints; a robot has one floating base")
    if kind in ("urdf", "xacro") and len(roots) == 1:
        # URDF cannot say "floating": its root link is the base
        roots[0].add_freejoint()
        return roots[0], [f"floating base: URDF root link {roots[0].name!r} (free joint added)"]
    raise ConfigError(f"{path}: no floating base (no free joint at the root body)", hint="a humanoid that falls and gets up needs a <freejoint/> on its root body")


def _ranges(
    m: mujoco.MjModel, spec: mujoco.MjSpec, ctrlranges: Mapping[str, tuple[float, float]], servo_rows: list[dict] | None, path: Path
) -> tuple[dict[str, tuple[float, float]], list[str]]:
    """Joint range per hinge: the model's, else the servo map's, else the actuator's ctrlrange."""
    notes = []
    servo_limits = {str(r.get("joint")): (float(r["min"]), float(r["max"])) for r in servo_rows or () if "min" in r and "max" in r}
    out: dict[str, tuple[float, float]] = {}
    missing = []
    for j in range(m.njnt):
        if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        name = m.joint(j).name
        if m.jnt_limited[j]:
            out[name] = (float(m.jnt_range[j, 0]), float(m.jnt_range[j, 1]))
        elif name in servo_limits:
            out[name] = servo_limits[name]
            notes.append(f"{name}: no range in the model; range from the servo map {servo_limits[name]}")
        elif name in ctrlranges:
            out[name] = ctrlranges[name]
            notes.append(f"{name}: no range in the model; range from its actuator ctrlrange [{ctrlranges[name][0]:.4f}, {ctrlranges[name][1]:.4f}]")
        else:
            missing.append(name)
    if missing:
        raise ConfigError(f"{path}: no joint limit known for {', '.join(missing)}", hint="give them min/max in a servo map (--servos) or a range in the model")
    for name, (lo, hi) in out.items():  # a servo in position mode turns less than one revolution
        clipped = (max(lo, -POSITION_MODE_HALF_TURN_RAD), min(hi, POSITION_MODE_HALF_TURN_RAD))
        if clipped != (lo, hi):
            out[name] = clipped
            notes.append(f"{name}: range [{lo:.4f}, {hi:.4f}] is more than a position-mode servo turns; kept [{clipped[0]:.4f}, {clipped[1]:.4f}]")
    return out, notes


def _foot_sole(m: mujoco.MjModel, d: mujoco.MjData, foot: int) -> np.ndarray:
    """Sole point of a foot in its body frame: under the middle of its lowest geoms, at their lowest point."""
    geoms = [g for g in subtree_geoms(m, foot) if m.geom_contype[g] or m.geom_conaffinity[g]] or subtree_geoms(m, foot)
    pts = []
    for g in geoms:
        half = m.geom_aabb[g, 3:]
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half + m.geom_aabb[g, :3]
        pts.append(corners @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g])
    p = np.concatenate(pts) if pts else d.xpos[foot][None, :]
    zmin = p[:, 2].min()
    low = p[p[:, 2] < zmin + 0.01]
    world = np.array([0.5 * (low[:, 0].min() + low[:, 0].max()), 0.5 * (low[:, 1].min() + low[:, 1].max()), zmin])
    R = d.xmat[foot].reshape(3, 3)
    return R.T @ (world - d.xpos[foot])


def import_robot(
    model_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    servos: str | os.PathLike[str] | None = None,
    servo_models: Mapping[str, str] | None = None,
    name: str | None = None,
    supply_voltage_v: float | None = None,
    force: bool = False,
) -> ImportResult:
    """Write a robot directory from a model file.

    Args:
        model_path: MJCF (``.xml``), URDF (``.urdf``) or ``.xacro`` (needs xacrodoc).
        out_dir: the robot directory to write (must not exist unless ``force``).
        servos: the user's servo map (format ``robot-rise/servos@1``): IDs, models, directions,
            offsets, limits. Mutually exclusive with ``servo_models``.
        servo_models: template servo map: ``{"*": model}`` for every joint and/or per-joint models.
        name: robot name (default: the model file's stem).
        supply_voltage_v: the servos' supply [V], written to the servo map's ``[bus]`` (default:
            the servo map's, else 12 V).
        force: replace an existing ``out_dir``.

    Raises:
        ConfigError: the model or servo map cannot be imported (one line naming the problem).
    """
    src = Path(model_path)
    out = Path(out_dir)
    if (servos is None) == (not servo_models):
        raise ConfigError("give either a servo map (--servos FILE) or servo models (--servo-model M [--servo-model JOINT=M ...])")
    if out.exists() and not force and any(out.iterdir()):
        raise ConfigError(f"{out} exists and is not empty", hint="choose another --out or pass --force")
    robot_name = name or src.stem
    spec, kind = _load_spec(src)
    notes: list[str] = [f"model: {src} ({kind})"]
    base, base_notes = _free_joint(spec, kind, src)
    notes += base_notes
    # what robot_rise supplies itself: the servo model (actuators), the judge (sensors), keyframes
    ctrlranges = {}
    for a in list(spec.actuators):
        if a.trntype == mujoco.mjtTrn.mjTRN_JOINT and a.ctrllimited != mujoco.mjtLimited.mjLIMITED_FALSE and a.ctrlrange[1] > a.ctrlrange[0]:
            ctrlranges[a.target] = (float(a.ctrlrange[0]), float(a.ctrlrange[1]))
    n_act, n_sens = len(spec.actuators), len(spec.sensors)
    for el in list(spec.actuators) + list(spec.sensors):
        spec.delete(el)
    stand_key = None
    for k in list(spec.keys):
        if k.name == "stand":
            stand_key = np.array(k.qpos)
        spec.delete(k)
    spec.option.noslip_iterations = 0  # simulation options are the scene's (robot_rise composes)
    if n_act or n_sens:
        notes.append(f"removed {n_act} actuators and {n_sens} sensors (robot_rise adds its own servo model)")
    try:
        m = spec.compile()
    except Exception as e:
        raise ConfigError(f"{src}: does not compile: {str(e).strip().splitlines()[-1]}") from e
    hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    others = [m.joint(j).name for j in range(m.njnt) if int(m.jnt_type[j]) not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_FREE))]
    if others:
        raise ConfigError(f"{src}: only hinge joints are supported besides the floating base; not: {', '.join(others)}")
    if not hinges:
        raise ConfigError(f"{src}: no hinge joints")
    bus, servo_rows = _read_servo_map(Path(servos)) if servos is not None else ({}, None)
    bus = {"protocol": 2.0, "baud_rate": 1000000, "return_delay_time_us": 0, "supply_voltage_v": SUPPLY_VOLTAGE_V} | bus
    if supply_voltage_v is not None:
        bus["supply_voltage_v"] = supply_voltage_v
    odd = [k for k, v in bus.items() if not isinstance(v, (int, float, str)) or not str(k).replace("_", "").isalnum()]
    if odd:
        raise ConfigError(f"{servos}: [bus] keys must be plain settings (number or text); not: {', '.join(map(str, odd))}")
    # checked before writing: the standing search swallows load_robot's errors
    supply_voltage(bus["supply_voltage_v"], "--supply-voltage" if supply_voltage_v is not None else f"{servos}: [bus] supply_voltage_v")
    if servo_rows is not None:
        names = {m.joint(j).name for j in hinges}
        unknown = [str(r.get("joint")) for r in servo_rows if str(r.get("joint")) not in names]
        if unknown:
            raise ConfigError(f"{servos}: names joints the model lacks: {', '.join(unknown)}")
    ranges, range_notes = _ranges(m, spec, ctrlranges, servo_rows, src)
    notes += range_notes
    if servo_rows is not None:
        for r in servo_rows:
            lo, hi = ranges[str(r["joint"])]
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, str(r["joint"]))
            if m.jnt_limited[j] and (float(r["min"]) < lo - 1e-6 or float(r["max"]) > hi + 1e-6):
                raise ConfigError(f"{servos}: servo {r.get('id')} ({r['joint']}) limits [{r['min']}, {r['max']}] lie outside the model range [{lo}, {hi}]")
    for j in spec.joints:
        if j.type == mujoco.mjtJoint.mjJNT_HINGE:
            j.range = list(ranges[j.name])
            j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    m = spec.compile()
    root_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, base.name)

    # roles at the neutral zero pose (the root frame is the stand frame)
    q_zero = m.qpos0.copy()
    inferred = infer_roles(m, q_zero, root_body)
    notes += list(inferred.notes)
    roles = inferred.roles
    legs = {lb.side: lb for lb in inferred.limbs if lb.kind == "leg"}
    notes.append("legs: " + ", ".join(f"{s} foot {m.body(legs[s].tip).name!r}" for s in ("left", "right")))
    missing = roles.missing_roles()
    if missing:
        notes.append(f"roles this robot has no joint for: {', '.join(missing)}")

    # sites: soles under the feet, the torso at the floating base
    d = mujoco.MjData(m)
    d.qpos[:] = q_zero
    mujoco.mj_kinematics(m, d)
    for side in ("left", "right"):
        foot = legs[side].tip
        site = spec.body(m.body(foot).name).add_site()
        site.name = SOLE_SITE.format(side=side)
        site.pos = _foot_sole(m, d, foot)
        # the sole frame is the stand frame (x forward, z up) at the zero pose, whatever the foot body's frame
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, d.xmat[foot].reshape(3, 3).T.copy().ravel())
        site.quat = quat
        site.group = 5
    torso = spec.body(base.name).add_site()
    torso.name = TORSO_SITE
    torso.group = 5
    m = spec.compile()
    sole_ids = tuple(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, SOLE_SITE.format(side=s)) for s in ("left", "right"))

    # servo map
    joint_names = [m.joint(j).name for j in hinges]
    if servo_rows is None:
        servo_rows = _template_servo_map(joint_names, ranges, dict(servo_models or {}))
        notes.append(f"servo map: template (IDs 1-{len(joint_names)} in model order, direction 1, limits = joint ranges): edit servos.toml to your hardware")
    for r in servo_rows:
        servo_datasheet(str(r.get("model")))  # one line naming an unknown model

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        notes += _copy_assets(spec, src, tmp)
        candidates = _stand_options(m, roles, root_body, sole_ids, legs, stand_key, notes)
        _write_servos(tmp / "servos.toml", robot_name, servo_rows, bus)
        stand_note = ""
        for cand_q, label in candidates:
            for k in list(spec.keys):
                spec.delete(k)
            key = spec.add_key()
            key.name = "stand"
            key.qpos = cand_q
            (tmp / "robot.xml").write_text(spec.to_xml())
            _write_robot_toml(tmp / "robot.toml", robot_name, m, inferred)
            ok, why = _holds_standing(tmp)
            if ok:
                stand_note = f"standing posture: {label}, held {STAND_CHECK_S:.0f} s by the servo model"
                break
            notes.append(f"standing posture {label}: rejected ({why})")
        if not stand_note:
            raise ConfigError(f"{src}: found no standing posture the servo model holds", hint="add a keyframe named 'stand' to the model")
        notes.append(stand_note)
        load_robot(tmp)  # the directory as written must load
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return ImportResult(out, robot_name, tuple(notes))


def _stand_options(m, roles, root_body, sole_ids, legs, stand_key, notes) -> list[tuple[np.ndarray, str]]:
    options = []
    if stand_key is not None:
        options.append((stand_key, "the model's 'stand' keyframe"))
    feet = (legs["left"].tip, legs["right"].tip)
    for c in stand_candidates(m, roles, root_body, sole_ids, feet):
        options.append((c.qpos, f"knees {np.degrees(2 * c.knee_bend_rad):.0f} deg, lean {np.degrees(c.lean_rad):+.1f} deg, CoM {1000 * c.com_margin_m:.0f} mm inside the feet"))
    if not options:
        raise ConfigError("found no statically balanced standing posture", hint="add a keyframe named 'stand' to the model")
    return options


def _holds_standing(directory: Path) -> tuple[bool, str]:
    """Hold the stand keyframe with the servo model on flat ground: still upright and not lower at the end?"""
    from robot_rise.posture import stand_posture  # noqa: PLC0415 (needs the robot written)
    from robot_rise.sim.player import Player  # noqa: PLC0415
    from robot_rise.sim.standing import judge  # noqa: PLC0415
    from robot_rise.trajectory import Trajectory  # noqa: PLC0415
    from robot_rise.validity import ValidityChecker  # noqa: PLC0415

    try:
        robot = load_robot(directory)
    except ConfigError as e:
        return False, str(e)
    start = stand_posture(robot)
    report = ValidityChecker(robot, "flat").check(start)
    if report.self_collision:
        return False, "self collision: " + "; ".join(report.reasons())
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.1]), np.array([q, q]), start)
    rec = Player(robot, "flat").play(tr, hold_s=STAND_CHECK_S)
    v = judge(rec, hold_s=STAND_CHECK_S - 0.5)
    return bool(v.standing), v.reason


def _template_servo_map(joints: list[str], ranges: Mapping[str, tuple[float, float]], models: dict[str, str]) -> list[dict]:
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


def _write_servos(path: Path, robot: str, rows: list[dict], bus: Mapping[str, object]) -> None:
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


def _write_robot_toml(path: Path, name: str, m: mujoco.MjModel, inferred: InferredRoles) -> None:
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
        if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        r = by_joint[m.joint(j).name]
        lines.append(f"{_toml_value(r.joint)} = {{ role = {_toml_value(r.role)}, sign = {r.sign}, neutral = {_toml_value(float(r.neutral_rad))} }}")
    path.write_text("\n".join(lines) + "\n")
