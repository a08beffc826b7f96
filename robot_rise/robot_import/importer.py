"""``import_robot``: a robot directory (robot.xml, robot.toml, servos.toml, assets) from an MJCF, URDF or xacro file.

The steps, each a module: read the file and find every file it names
(:mod:`~robot_rise.robot_import.source`: ROS packages, xacro, file-name case), take out what
belongs to a scene, give the robot its floating base, fix the physics a CAD export gets wrong
(:mod:`~robot_rise.robot_import.repair`), reconcile the joint ranges with the servo map
(:mod:`~robot_rise.robot_import.limits`), infer limbs and roles through fixed links
(:mod:`~robot_rise.robot_import.roles`), add sole and torso sites, find the stand
(:mod:`~robot_rise.robot_import.stand`) and hold it with the servo model. What robot_rise
supplies itself is stripped (actuators, sensors, keyframes other than ``stand``: the servo model
and the judge are ours); collision filters, defaults, equality constraints and tendons are kept.
Every inference and fix is a note for the user; wrong guesses are corrected in ``robot.toml``.
The directory is written next to its destination and renamed into place, so a failed import
leaves nothing behind; a dry run does all of it in a scratch directory and writes nothing.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from robot_files.servo_map import BusSettings, read_servo_map
from robot_rise.errors import ConfigError, as_config_error, mujoco_reason
from robot_rise.model import load_robot, supply_voltage
from robot_rise.linkage import close_loops, linkage_of
from robot_rise.robot_import.constraints import passive_joints
from robot_rise.robot_import.directory import SOLE_SITE, TORSO_SITE, template_servo_map, write_robot_toml, write_servos
from robot_rise.robot_import.frame import BASE_BODY, reframe_root, stand_frame
from robot_rise.robot_import.limits import joint_ranges, urdf_limit_tags
from robot_rise.robot_import.repair import PhysicsRepair, repair_physics
from robot_rise.robot_import.roles import foot_geoms, geom_points, infer_roles, jointed_limbs
from robot_rise.robot_import.source import read_model
from robot_rise.robot_import.stand import stand_candidates
from robot_rise.servo import servo_datasheet

__all__ = ["ImportResult", "import_robot", "SOLE_SITE", "TORSO_SITE", "STAND_CHECK_S"]

STAND_CHECK_S = 3.0  # a found standing posture must be held this long by the servo model
STAND_SETTLE_S = 1.0  # of which the first second settles it (a weak robot sinks onto its stops)
ASSET_DIR = "assets"


@dataclass(frozen=True)
class ImportResult:
    """What an import did.

    Attributes:
        directory: the robot directory written (the destination it would have had, on a dry run).
        name: the robot's name.
        notes: every inference and fix, one line each.
        kind: the file's kind (mjcf, urdf, xacro).
        mass_kg, declared_mass_kg: the imported body's mass, and what the file declares.
        collision_geoms, declared_collision_geoms: collision geoms kept, and in the file.
        roles: joint roles found (``left.knee`` ...), missing: roles the robot has no joint for.
        stand: how the standing posture was found.
        written: False on a dry run.
    """

    directory: Path
    name: str
    notes: tuple[str, ...] = field(default_factory=tuple)
    kind: str = ""
    mass_kg: float = 0.0
    declared_mass_kg: float = 0.0
    collision_geoms: int = 0
    declared_collision_geoms: int = 0
    roles: tuple[str, ...] = ()
    missing_roles: tuple[str, ...] = ()
    stand: str = ""
    written: bool = True


_GENERIC_NAMES = ("robot", "model", "mujoco", "urdf", "main")  # file or model names that do not name the robot


def _plain_name(text: str) -> str:
    """A model's own name as a robot name: lower case, letters, digits and _ only ('' if generic)."""
    name = "".join(c if c.isalnum() else "_" for c in text.strip().lower()).strip("_")
    return "" if name in ("", *_GENERIC_NAMES) else name


def _copy_assets(spec: mujoco.MjSpec, out: Path) -> list[str]:
    """Copy every mesh/texture/height field the model loads (absolute paths: ``read_model``) into
    ``out/assets``, names lower-cased (MuJoCo picks a mesh's decoder by its suffix); point the spec there."""
    notes = []
    copied: dict[Path, str] = {}
    for el in [*spec.meshes, *spec.skins, *spec.hfields, *spec.textures]:
        names = [el.file] + (list(el.cubefiles) if hasattr(el, "cubefiles") else [])
        new = []
        for name in names:
            if not name:
                new.append(name)
                continue
            src = Path(name)
            target = copied.get(src) or f"{len(copied):03d}_{src.stem}{src.suffix.lower()}"
            copied[src] = target
            (out / ASSET_DIR).mkdir(exist_ok=True)
            shutil.copy2(src, out / ASSET_DIR / target)
            new.append(target)
        el.file = new[0]
        if len(new) > 1:
            el.cubefiles = new[1:]
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


def _strip_scene(spec: mujoco.MjSpec) -> list[str]:
    """What belongs to a scene, not to the robot: world geoms (a floor), and contact pairs and
    excludes that name geoms or bodies the robot lacks (a scene file's floor)."""
    notes = []
    world_geoms = list(spec.worldbody.geoms)
    for g in world_geoms:
        spec.delete(g)
    if world_geoms:
        notes.append(f"removed {len(world_geoms)} world geoms ({', '.join(g.name or 'unnamed' for g in world_geoms[:4])}): the scene is robot_rise's")
    geoms = {g.name for g in spec.geoms if g.name}
    bodies = {b.name for b in spec.bodies if b.name}
    dropped = []
    for pair in list(spec.pairs):
        gone = [n for n in (pair.geomname1, pair.geomname2) if n not in geoms]
        if gone:
            dropped.append(f"pair {pair.name or '(unnamed)'} ({', '.join(gone)})")
            spec.delete(pair)
    for ex in list(spec.excludes):
        gone = [n for n in (ex.bodyname1, ex.bodyname2) if n not in bodies]
        if gone:
            dropped.append(f"exclude {ex.name or '(unnamed)'} ({', '.join(gone)})")
            spec.delete(ex)
    if dropped:
        notes.append(f"removed contact filters naming what the robot does not have (a scene's floor): {'; '.join(dropped)}")
    return notes


def _collision_geoms(m: mujoco.MjModel) -> int:
    return int(sum(1 for g in range(m.ngeom) if m.geom_bodyid[g] != 0 and (m.geom_contype[g] or m.geom_conaffinity[g])))


def _declared_collision_geoms(spec: mujoco.MjSpec) -> int:
    return int(sum(1 for g in spec.geoms if (g.contype or g.conaffinity)))


def _foot_sole(m: mujoco.MjModel, d: mujoco.MjData, foot: int) -> np.ndarray:
    """Sole point of a foot in its body frame: under the middle of its lowest geoms, at their lowest point."""
    pts = [geom_points(m, d, g) for g in foot_geoms(m, foot)]
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
    package_paths: Sequence[str | os.PathLike[str]] = (),
    stand: str | os.PathLike[str] | None = None,
    dry_run: bool = False,
) -> ImportResult:
    """Write a robot directory from a model file.

    Args:
        model_path: MJCF, URDF or xacro (the suffix in any case; ``.urdf.xacro`` is xacro).
        out_dir: the robot directory to write (must not exist unless ``force``).
        servos: the user's servo map (format ``robot-rise/servos@1``): IDs, models, directions,
            offsets, limits. Mutually exclusive with ``servo_models``.
        servo_models: template servo map: ``{"*": model}`` for every joint and/or per-joint models.
        name: robot name (default: the model file's name without its suffixes).
        supply_voltage_v: the servos' supply [V], written to the servo map's ``[bus]`` (default:
            the servo map's, else 12 V).
        force: replace an existing ``out_dir``.
        package_paths: directories holding ROS packages (``package://NAME``, ``$(find NAME)``),
            searched after the model's own ancestors and before ``ROS_PACKAGE_PATH``.
        stand: a posture file (format ``robot-rise/posture@1``) of the robot standing, tried
            before the model's ``stand`` keyframe and the search.
        dry_run: do everything, print it, write nothing.

    Raises:
        ConfigError: the model or servo map cannot be imported (one line naming the problem).
    """
    src = Path(model_path)
    out = Path(out_dir)
    if (servos is None) == (not servo_models):
        raise ConfigError("give either a servo map (--servos FILE) or servo models (--servo-model M [--servo-model JOINT=M ...])")
    if out.exists() and not force and not dry_run and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"{out} exists and is not empty", hint="choose another --out or pass --force")
    if stand is not None and not Path(stand).is_file():
        raise ConfigError(f"--stand {stand}: no such posture file")
    source = read_model(src, package_paths)
    spec = source.spec
    notes: list[str] = [f"model: {src} ({source.kind})", *source.notes]
    notes += _strip_scene(spec)
    base, base_notes = _free_joint(spec, source.kind, src)
    notes += base_notes
    # what robot_rise supplies itself: the servo model (actuators), the judge (sensors), keyframes
    ctrlranges = {}
    actuated = {a.target for a in spec.actuators if a.trntype == mujoco.mjtTrn.mjTRN_JOINT}
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
    declared_geoms = _declared_collision_geoms(spec)
    m, repair = repair_physics(spec, str(src))
    notes += list(repair.notes)
    notes.append(_mass_note(repair))
    hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    others = [m.joint(j).name for j in range(m.njnt) if int(m.jnt_type[j]) not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_FREE))]
    if others:
        raise ConfigError(f"{src}: only hinge joints are supported besides the floating base; not: {', '.join(others)}")
    if not hinges:
        raise ConfigError(f"{src}: no hinge joints")
    with as_config_error():  # the one servos.toml reader: every row with its limits
        user_map = read_servo_map(Path(servos)) if servos is not None else None
    servo_rows = user_map.servos if user_map is not None else None
    # the name: given, else the servo map's (the user's), else the model's own, else the file's
    stem = src.name.split(".")[0]
    map_name = user_map.robot if user_map is not None else ""
    robot_name = name or map_name or (stem if stem.lower() not in _GENERIC_NAMES else _plain_name(spec.modelname) or stem)
    bus = user_map.bus if user_map is not None else BusSettings()  # the user's [bus] kept as given
    if supply_voltage_v is not None:  # checked before writing: the standing search swallows load_robot's errors
        bus = dataclasses.replace(bus, supply_voltage_v=supply_voltage(supply_voltage_v, "--supply-voltage"))
    if servo_rows is not None:
        names = {m.joint(j).name for j in hinges}
        unknown = [r.joint for r in servo_rows if r.joint not in names]
        if unknown:
            raise ConfigError(f"{servos}: names joints the model lacks: {', '.join(unknown)}")
    root_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, base.name)
    chains = {j for chain, _ in jointed_limbs(m, root_body)[0] for b in chain for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])}
    servo_joints = [r.joint for r in servo_rows] if servo_rows is not None else None
    passive, passive_notes = passive_joints(m, servo_joints, actuated, chains, str(src))
    notes += passive_notes
    tags = urdf_limit_tags(source.urdf_text) if source.urdf_text else {}
    reconciled = joint_ranges(m, ctrlranges, servo_rows, tags, str(src), str(servos), passive)
    ranges, servo_rows = reconciled.ranges, reconciled.servo_rows
    notes += list(reconciled.notes)
    for j in spec.joints:
        if j.type == mujoco.mjtJoint.mjJNT_HINGE and j.name in ranges:
            j.range = list(ranges[j.name])
            j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    m = _compile(spec, src)
    root_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, base.name)
    skip = frozenset(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in passive)
    frame = stand_frame(m, root_body, skip)
    if not frame.is_root_frame:
        notes += list(frame.notes)
        spec, turn = reframe_root(spec, base.name, frame)
        base = spec.body(BASE_BODY)
        m = _compile(spec, src)
        root_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, BASE_BODY)
        if stand_key is not None:
            free = int(m.jnt_qposadr[m.body_jntadr[root_body]])
            quat = np.zeros(4)
            mujoco.mju_mulQuat(quat, stand_key[free + 3 : free + 7].copy(), turn)
            stand_key[free + 3 : free + 7] = quat

    notes += _name_geoms(spec)
    notes += _exclude_designed_overlaps(spec, m, src)
    m = _compile(spec, src)

    # roles at the neutral zero pose (the root frame is the stand frame)
    q_zero = m.qpos0.copy()
    inferred = infer_roles(m, q_zero, root_body, passive)
    notes += list(inferred.notes)
    roles = inferred.roles
    legs = {lb.side: lb for lb in inferred.limbs if lb.kind == "leg"}
    notes.append("legs: " + ", ".join(f"{s} foot {m.body(legs[s].tip).name!r}" for s in ("left", "right")))
    missing = roles.missing_roles()
    if missing:
        notes.append(f"roles this robot has no joint for: {', '.join(missing)}")

    # sites: soles under the feet, the torso at the floating base, placed at the neutral pose
    # (the legs hanging, the soles flat: robot_import.roles), the root upright
    d = mujoco.MjData(m)
    d.qpos[:] = q_zero
    free = int(m.jnt_qposadr[m.body_jntadr[root_body]])
    d.qpos[free + 3 : free + 7] = [1, 0, 0, 0]
    for r in roles.joints:
        d.qpos[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, r.joint)]] = r.neutral_rad
    mujoco.mj_kinematics(m, d)
    for side in ("left", "right"):
        foot = legs[side].tip
        site = spec.body(m.body(foot).name).add_site()
        site.name = SOLE_SITE.format(side=side)
        site.pos = _foot_sole(m, d, foot)
        # the sole frame is the stand frame (x forward, z up) at the neutral pose, whatever the foot body's frame
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, d.xmat[foot].reshape(3, 3).T.copy().ravel())
        site.quat = quat
        site.group = 5
    torso = spec.body(base.name).add_site()
    torso.name = TORSO_SITE
    torso.group = 5
    m = _compile(spec, src)
    sole_ids = tuple(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, SOLE_SITE.format(side=s)) for s in ("left", "right"))

    # servo map
    joint_names = [m.joint(j).name for j in hinges if m.joint(j).name not in passive]
    if servo_rows is None:
        servo_rows = template_servo_map(joint_names, ranges, dict(servo_models or {}))
        notes.append(f"servo map: template (IDs 1-{len(joint_names)} in model order, direction 1, limits = joint ranges): edit servos.toml to your hardware")
    for r in servo_rows:
        servo_datasheet(r.model)  # one line naming an unknown model

    scratch_parent = Path(tempfile.gettempdir()) if dry_run else out.parent
    scratch_parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=scratch_parent))
    try:
        notes += _copy_assets(spec, tmp)
        candidates = _stand_options(m, roles, root_body, sole_ids, legs, stand_key, stand, joint_names, notes)
        write_servos(tmp / "servos.toml", robot_name, servo_rows, bus)
        stand_note = ""
        tried = []
        for cand_q, label in candidates:
            for k in list(spec.keys):
                spec.delete(k)
            key = spec.add_key()
            key.name = "stand"
            key.qpos = _closed(m, cand_q, passive)
            (tmp / "robot.xml").write_text(spec.to_xml())
            write_robot_toml(tmp / "robot.toml", robot_name, m, inferred, passive)
            ok, why = _holds_standing(tmp)
            if ok:
                stand_note = f"standing posture: {label}, held {STAND_CHECK_S:.0f} s by the servo model"
                break
            tried.append(f"{label}: {why}")
            notes.append(f"standing posture {label}: rejected ({why})")
        if not stand_note:
            raise ConfigError(
                f"{src}: found no standing posture the servo model holds; tried {'; '.join(tried)}",
                hint="give one: a keyframe named 'stand' in the model, or --stand POSTURE.json (format robot-rise/posture@1)",
            )
        notes.append(stand_note)
        robot = load_robot(tmp)  # the directory as written must load
        if not dry_run:
            if out.exists():
                shutil.rmtree(out) if out.is_dir() else out.unlink()
            os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if dry_run:
        shutil.rmtree(tmp, ignore_errors=True)
    have = robot.roles.by_role() if robot.roles is not None else {}
    return ImportResult(
        out,
        robot_name,
        tuple(notes),
        kind=source.kind,
        mass_kg=float(m.body_mass.sum()),
        declared_mass_kg=repair.declared_mass_kg,
        collision_geoms=_collision_geoms(m),
        declared_collision_geoms=declared_geoms,
        roles=tuple(sorted(have)),
        missing_roles=tuple(missing),
        stand=stand_note,
        written=not dry_run,
    )


OVERLAP_EXCLUDE_M = 1e-3  # bodies whose collision geoms overlap by more than this at the file's zero pose


def _name_geoms(spec: mujoco.MjSpec) -> list[str]:
    """Name unnamed geoms after their body (``pelvis_geom0``): messages and reports name what touches."""
    taken = {g.name for g in spec.geoms if g.name}
    count, first = 0, ""
    for body in spec.bodies:
        for k, g in enumerate(body.geoms):
            if g.name:
                continue
            name = f"{body.name or 'body'}_geom{k}"
            while name in taken:
                name += "_"
            g.name = name
            taken.add(name)
            count += 1
            first = first or name
    return [f"named {count} unnamed geoms after their bodies ({first}, ...)"] if count else []


def _exclude_designed_overlaps(spec: mujoco.MjSpec, m: mujoco.MjModel, src: Path) -> list[str]:
    """Exclude contacts between bodies whose collision geoms overlap at the file's zero pose: CAD
    meshes of neighbouring links drawn into each other (a servo case inside the next bracket) are
    how the robot is built, not a collision (MuJoCo leaves out parent and child, not grandparents)."""
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    mujoco.mj_forward(m, d)
    pairs: dict[tuple[str, str], float] = {}
    for c in d.contact[: d.ncon]:
        b1, b2 = int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])
        if b1 == 0 or b2 == 0 or c.dist > -OVERLAP_EXCLUDE_M:
            continue
        key = tuple(sorted((m.body(b1).name, m.body(b2).name)))
        pairs[key] = max(pairs.get(key, 0.0), -float(c.dist))  # type: ignore[index]
    if not pairs:
        return []
    if any(not a or not b for a, b in pairs):
        raise ConfigError(f"{src}: unnamed bodies overlap at the zero pose; name them to let the import exclude their contacts")
    for a, b in sorted(pairs):
        ex = spec.add_exclude()
        ex.bodyname1, ex.bodyname2 = a, b
    listed = ", ".join(f"{a} / {b} {1000 * v:.0f} mm" for (a, b), v in sorted(pairs.items()))
    return [f"collision excluded between {len(pairs)} body pairs that overlap in the file's zero pose (as built, not a collision): {listed}"]


def _closed(m: mujoco.MjModel, qpos: np.ndarray, passive: tuple[str, ...]) -> np.ndarray:
    """``qpos`` with its passive joints where the constraints put them."""
    if not passive:
        return qpos
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    close_loops(m, d, linkage_of(m, passive))
    return d.qpos.copy()


def _compile(spec: mujoco.MjSpec, src: Path) -> mujoco.MjModel:
    try:
        return spec.compile()
    except Exception as e:  # mujoco raises ValueError with its message
        raise ConfigError(f"{src}: does not compile: {mujoco_reason(e)}") from e


def _mass_note(repair: PhysicsRepair) -> str:
    change = repair.mass_change
    kept = "kept" if abs(change) <= 0.01 else "CHANGED by more than 1 %"
    return f"mass {repair.mass_kg:.4f} kg ({kept}: the file declares {repair.declared_mass_kg:.4f} kg, {100 * change:+.2f} %)"


def _stand_options(
    m: mujoco.MjModel, roles, root_body: int, sole_ids, legs, stand_key, stand_file, joint_names: list[str], notes: list[str]
) -> list[tuple[np.ndarray, str]]:
    """Standing postures to hold, in order: the user's file, the model's keyframe, the search's balanced ones."""
    options = []
    if stand_file is not None:
        options.append((_posture_qpos(m, Path(stand_file), root_body, sole_ids, joint_names), f"--stand {stand_file}"))
    if stand_key is not None:
        options.append((stand_key, "the model's 'stand' keyframe"))
    feet = (legs["left"].tip, legs["right"].tip)
    rejected = []
    for c in stand_candidates(m, roles, root_body, sole_ids, feet):
        if c.rejected:
            rejected.append(f"{c.label}: {c.rejected}")
            continue
        options.append((c.qpos, f"{c.label}, CoM {1000 * c.com_margin_m:.0f} mm inside the feet"))
    if rejected:
        notes.append(f"standing postures not statically balanced: {'; '.join(rejected)}")
    if not options:
        raise ConfigError(
            f"found no statically balanced standing posture; tried {'; '.join(rejected)}",
            hint="give one: a keyframe named 'stand' in the model, or --stand POSTURE.json (format robot-rise/posture@1)",
        )
    return options


def _posture_qpos(m: mujoco.MjModel, path: Path, root_body: int, sole_ids, joint_names: list[str]) -> np.ndarray:
    """A posture file's joints as robot-alone qpos, the root upright with the soles on the ground."""
    from robot_rise.placement import place_on_soles  # noqa: PLC0415
    from robot_rise.posture import read_posture  # noqa: PLC0415 (posture reads robots: after the model)

    posture = read_posture(path)
    unknown = [j for j in posture.joints if j not in joint_names]
    if unknown:
        raise ConfigError(f"--stand {path}: names joints the model lacks: {', '.join(unknown)}")
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    for j, q in posture.joints.items():
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        lo, hi = m.jnt_range[jid]
        d.qpos[m.jnt_qposadr[jid]] = float(np.clip(q, lo, hi))
    free = int(m.jnt_qposadr[m.body_jntadr[root_body]])
    place_on_soles(m, d, np.arange(free, free + 7), sole_ids)
    return d.qpos.copy()


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
        return False, "; ".join(report.reasons())
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.1]), np.array([q, q]), start)
    rec = Player(robot, "flat").play(tr, hold_s=STAND_CHECK_S)
    v = judge(rec, hold_s=STAND_CHECK_S - STAND_SETTLE_S)
    if v.standing:
        return True, ""
    torque = f"; servo torque at {rec.peak_envelope_ratio:.2f} of its envelope" if rec.peak_envelope_ratio > 0.9 else ""
    return False, v.reason + torque
