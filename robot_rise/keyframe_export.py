"""A trajectory as MuJoCo keyframes of the robot's own model (``<mujoco><keyframe><key .../>``).

Each row (or each sample at ``rate_hz``) becomes one ``<key name time qpos ctrl>``:

- ``qpos`` in the model's order: the root free joint from the trajectory's ``root`` rows where the
  file has them, else the start posture's root pose (the quaternion made unit length, as MuJoCo
  makes a key's on loading); each joint by name from the rows (a joint the
  rows lack from the start posture, else the model's ``qpos0``); the passive joints
  (``robot.toml`` ``passive``) solved from the driven ones by :func:`robot_rise.linkage.close_loops`.
- ``ctrl`` in actuator order: a position actuator on a joint gets that joint's target (times its
  gear: the actuator length MuJoCo compares the control with); any other actuator 0, MuJoCo's
  default. A model without actuators gets no ``ctrl``.

The file is MuJoCo's format: an ``<include file="keys.xml"/>`` in the robot's MJCF (or a scene
that includes it) loads the keys. MuJoCo refuses attributes it does not know, so the format
string (:data:`KEYFRAMES_FORMAT`) and the source sit in the leading comment. Numbers are written
to full precision (shortest round-trip repr), so a key's qpos is the row's to the last bit.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from xml.etree import ElementTree

import mujoco
import numpy as np

from robot_rise.errors import ConfigError, RobotRiseError, mujoco_reason
from robot_rise.fileio import write_text_atomic
from robot_rise.linkage import close_loops, linkage_of
from robot_rise.model import Robot
from robot_rise.trajectory import Trajectory

__all__ = ["Keyframes", "KEYFRAMES_FORMAT", "trajectory_keyframes", "keyframes_xml", "write_keyframes"]

KEYFRAMES_FORMAT = "robot-rise/mujoco-keyframes@1"


@dataclass(frozen=True)
class Keyframes:
    """Keyframes of one trajectory for one model.

    Attributes:
        robot: the robot's name.
        model_file: the MJCF the qpos and ctrl are ordered for.
        names: key names, shape (K,).
        time_s: key times [s], shape (K,).
        qpos: shape (K, nq) in the model's qpos order [m, quaternion wxyz, rad].
        ctrl: shape (K, nu) in actuator order (nu = 0: the model has no actuators).
        loop_residual: the largest constraint residual left after solving the passive joints
            [m or rad] (0 without passive joints).
    """

    robot: str
    model_file: str
    names: tuple[str, ...]
    time_s: np.ndarray
    qpos: np.ndarray
    ctrl: np.ndarray
    loop_residual: float = 0.0


def _load_model(robot: Robot) -> mujoco.MjModel:
    try:
        return mujoco.MjSpec.from_file(str(robot.xml_path)).compile()
    except Exception as e:  # mujoco raises ValueError with the parser message
        raise ConfigError(f"{robot.xml_path}: cannot load MJCF: {mujoco_reason(e)}") from e


def _slerp(q0: np.ndarray, q1: np.ndarray, a: float) -> np.ndarray:
    """Unit quaternion between ``q0`` (a = 0) and ``q1`` (a = 1), wxyz, the short way round."""
    q0 = q0 / np.linalg.norm(q0)
    q1 = q1 / np.linalg.norm(q1)
    dot = float(q0 @ q1)
    if dot < 0.0:
        q1, dot = -q1, -dot
    if dot > 0.9995:  # nearly the same orientation: the normalized chord
        q = q0 + a * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = np.arccos(dot)
    return (np.sin((1 - a) * theta) * q0 + np.sin(a * theta) * q1) / np.sin(theta)


def _root_at(root: np.ndarray, t: np.ndarray, times_s: np.ndarray) -> np.ndarray:
    """Root rows (x y z qw qx qy qz) at ``times_s``: position linear, orientation by slerp."""
    out = np.empty((len(times_s), 7))
    for k, tau in enumerate(np.clip(times_s, t[0], t[-1])):
        i = int(np.clip(np.searchsorted(t, tau, side="right"), 1, len(t) - 1))
        a = float((tau - t[i - 1]) / (t[i] - t[i - 1]))
        out[k, :3] = root[i - 1, :3] + a * (root[i, :3] - root[i - 1, :3])
        out[k, 3:] = root[i - 1, 3:] if a == 0.0 else root[i, 3:] if a == 1.0 else _slerp(root[i - 1, 3:], root[i, 3:], a)
    return out


def _is_position_actuator(m: mujoco.MjModel, a: int) -> bool:
    """MuJoCo's ``<position>``: fixed gain kp, affine bias (0, -kp, -kv) on a joint."""
    return (int(m.actuator_trntype[a]) in (mujoco.mjtTrn.mjTRN_JOINT, mujoco.mjtTrn.mjTRN_JOINTINPARENT)
            and int(m.actuator_gaintype[a]) == mujoco.mjtGain.mjGAIN_FIXED
            and int(m.actuator_biastype[a]) == mujoco.mjtBias.mjBIAS_AFFINE
            and m.actuator_biasprm[a, 0] == 0.0 and m.actuator_gainprm[a, 0] > 0.0
            and m.actuator_biasprm[a, 1] == -m.actuator_gainprm[a, 0])


def trajectory_keyframes(robot: Robot, tr: Trajectory, *, rate_hz: float | None = None,
                         name: str = "key") -> Keyframes:
    """The keyframes of ``tr`` for ``robot``'s model (see the module docstring).

    Args:
        robot: the robot the trajectory is for.
        tr: the trajectory.
        rate_hz: resample at this rate [Hz] (linear in the joints, slerp in the root orientation);
            None: one key per row.
        name: key names are ``f"{name}_{k}"`` with k zero-padded.

    Raises:
        ConfigError: another robot's trajectory, a joint the model lacks, a bad rate, or a model
            MuJoCo cannot load.
    """
    if tr.robot and tr.robot != robot.name:
        raise ConfigError(f"trajectory is for robot {tr.robot!r}, not {robot.name!r}", hint="pass --robot DIR of its robot")
    if rate_hz is not None and not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ConfigError(f"rate {rate_hz} Hz must be a positive number")
    m = _load_model(robot)
    joint_adr = {}
    for j in range(m.njnt):
        if int(m.jnt_type[j]) in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            joint_adr[m.joint(j).name] = int(m.jnt_qposadr[j])
    missing = [j for j in tr.joint_names if j not in joint_adr]
    if missing:
        raise ConfigError(f"{robot.xml_path.name} has no joint {', '.join(missing)}; its joints: {', '.join(joint_adr)}")
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, robot.root_body)
    root_adr = int(m.jnt_qposadr[m.body_jntadr[body]])

    if rate_hz is None:
        times = np.asarray(tr.t, dtype=float)
        rows = np.asarray(tr.q, dtype=float)
        root = None if tr.root is None else np.asarray(tr.root, dtype=float)
    else:
        times = np.minimum(np.arange(0.0, tr.duration_s + 0.5 / rate_hz, 1.0 / rate_hz), tr.duration_s)
        rows = tr.sample(times)
        root = None if tr.root is None else _root_at(np.asarray(tr.root, dtype=float), np.asarray(tr.t, dtype=float), times)

    base = np.array(m.qpos0, dtype=float)
    for j, v in tr.start.joints.items():  # joints the rows lack: as at the start
        if j in joint_adr and j not in tr.joint_names:
            base[joint_adr[j]] = v
    base[root_adr:root_adr + 3] = tr.start.root_pos
    base[root_adr + 3:root_adr + 7] = tr.start.root_quat_wxyz
    cols = np.array([joint_adr[j] for j in tr.joint_names], dtype=int)
    qpos = np.tile(base, (len(times), 1))
    qpos[:, cols] = rows
    if root is not None:
        qpos[:, root_adr:root_adr + 7] = root
    # unit quaternions, as MuJoCo normalizes a key's on loading (the file's rows are rounded to
    # 6 decimals, ~1e-7 off unit length): what is written is what MuJoCo holds
    quat = qpos[:, root_adr + 3:root_adr + 7]
    qpos[:, root_adr + 3:root_adr + 7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)

    residual = 0.0
    passive = [j for j in robot.passive_joints if j in joint_adr]
    if passive:
        linkage = linkage_of(m, tuple(passive))
        d = mujoco.MjData(m)
        d.qpos[:] = base
        driven = np.ones(m.nq, dtype=bool)
        driven[linkage.passive_qpos] = False
        for k in range(len(times)):  # each solve starts from the last key's rods
            d.qpos[driven] = qpos[k, driven]
            residual = max(residual, close_loops(m, d, linkage))
            qpos[k, linkage.passive_qpos] = d.qpos[linkage.passive_qpos]

    ctrl = np.zeros((len(times), m.nu))
    for a in range(m.nu):
        if _is_position_actuator(m, a):
            ctrl[:, a] = m.actuator_gear[a, 0] * qpos[:, int(m.jnt_qposadr[m.actuator_trnid[a, 0]])]
    width = len(str(max(len(times) - 1, 0)))
    names = tuple(f"{name}_{k:0{width}d}" for k in range(len(times)))
    return Keyframes(robot.name, robot.xml_path.name, names, times, qpos, ctrl, residual)


def _numbers(values: np.ndarray) -> str:
    return " ".join(repr(float(x)) for x in values)


def keyframes_xml(keys: Keyframes, *, source: str = "") -> str:
    """The keyframes as a MuJoCo XML file (text), the format string in its leading comment."""
    root = ElementTree.Element("mujoco")
    what = f" from {source}" if source else ""
    root.append(ElementTree.Comment(
        f" {KEYFRAMES_FORMAT}: {len(keys.names)} keys{what} for robot {keys.robot}'s {keys.model_file} "
        f"(qpos in its order, ctrl in its actuator order); include it in that model "))
    keyframe = ElementTree.SubElement(root, "keyframe")
    for k, key_name in enumerate(keys.names):
        attrs = {"name": key_name, "time": repr(float(keys.time_s[k])), "qpos": _numbers(keys.qpos[k])}
        if keys.ctrl.shape[1]:
            attrs["ctrl"] = _numbers(keys.ctrl[k])
        ElementTree.SubElement(keyframe, "key", attrs)
    ElementTree.indent(root, space="  ")
    return ElementTree.tostring(root, encoding="unicode") + "\n"


def write_keyframes(path: str | os.PathLike[str], robot: Robot, tr: Trajectory, *, rate_hz: float | None = None,
                    name: str = "key", source: str = "") -> Keyframes:
    """Write ``tr`` as MuJoCo keyframes of ``robot``'s model to ``path`` (atomically); return them.

    Raises:
        ConfigError: as :func:`trajectory_keyframes`.
        RobotRiseError: the file cannot be written.
    """
    keys = trajectory_keyframes(robot, tr, rate_hz=rate_hz, name=name)
    try:
        write_text_atomic(path, keyframes_xml(keys, source=source))
    except OSError as e:
        raise RobotRiseError(f"cannot write {path}: {e.strerror or e}") from e
    return keys
