"""How the camera moves: :class:`CameraSpec`, its presets, the track a preset follows, and the name check.

Presets: ``follow`` (default) tracks the robot's root, smoothed, from its front-left; ``front``,
``side``, ``back`` and ``top`` follow from those sides of the robot's final heading; ``fixed``
stays still and frames the whole motion; any other name is a camera of the composed model.
Azimuth, elevation and distance can be overridden.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_rise.model import Robot, compose
from robot_rise.posture import yaw_rad
from robot_rise.render.errors import RenderError
from robot_rise.render.timing import sample_index
from robot_rise.sim.player import Recording

__all__ = [
    "CameraSpec",
    "CAMERA_PRESETS",
    "DISTANCE_PER_STAND_HEIGHT",
    "camera_track",
    "check_camera",
    "check_camera_in_model",
]

# Camera presets: azimuth relative to the robot's final heading [deg], elevation [deg]. MuJoCo's
# azimuth is the direction the camera looks along, so 180 deg looks at the robot's front.
CAMERA_PRESETS: dict[str, tuple[float, float]] = {
    "follow": (210.0, -20.0),  # front-left three-quarter view
    "front": (180.0, -10.0),
    "side": (-90.0, -10.0),  # from the robot's left
    "back": (0.0, -15.0),
    "top": (90.0, -89.0),
    "fixed": (210.0, -20.0),  # still camera framing the whole motion
}
DISTANCE_PER_STAND_HEIGHT = 5.0  # default camera distance / torso height of the stand keyframe
LOOKAT_HEIGHT_PER_STAND_HEIGHT = 0.6  # camera target height / stand torso height (no bobbing)
FOLLOW_SMOOTHING_S = 0.5  # width of the moving average applied to the followed root path [s]


@dataclass(frozen=True)
class CameraSpec:
    """How the camera moves.

    Attributes:
        name: a preset (see ``CAMERA_PRESETS``: follow, front, side, back, top, fixed) or the
            name of a camera in the composed model.
        azimuth_deg: override of the preset's azimuth, relative to the robot's final heading [deg].
        elevation_deg: override of the preset's elevation [deg] (negative looks down).
        distance_m: override of the distance to the target [m].
    """

    name: str = "follow"
    azimuth_deg: float | None = None
    elevation_deg: float | None = None
    distance_m: float | None = None


def _moving_average(values: np.ndarray, width: int) -> np.ndarray:
    """Centred moving average along axis 0 with edge padding; shape unchanged."""
    if width <= 1 or len(values) < 2:
        return values.copy()
    pad = width // 2
    padded = np.concatenate([np.repeat(values[:1], pad, axis=0), values, np.repeat(values[-1:], width - 1 - pad, axis=0)])
    kernel = np.ones(width) / width
    return np.stack([np.convolve(padded[:, j], kernel, mode="valid") for j in range(values.shape[1])], axis=1)


def camera_track(robot: Robot, rec: Recording, camera: CameraSpec, times_s: np.ndarray) -> dict[str, np.ndarray | float]:
    """Where a preset camera looks at each frame.

    Args:
        robot: the robot (its stand height sets the default distance).
        rec: the recording.
        camera: a preset camera (see ``CAMERA_PRESETS``).
        times_s: frame times [s], shape (F,).

    Returns:
        ``lookat`` [m] shape (F, 3), ``azimuth_deg``, ``elevation_deg``, ``distance_m`` (floats).
    """
    az_rel, el = CAMERA_PRESETS[camera.name]
    if camera.azimuth_deg is not None:
        az_rel = camera.azimuth_deg
    if camera.elevation_deg is not None:
        el = camera.elevation_deg
    stand_h = float(rec.stand_height_m) if rec.stand_height_m > 0 else 0.28
    distance = DISTANCE_PER_STAND_HEIGHT * stand_h
    heading_deg = math.degrees(yaw_rad(rec.root_pose[-1, 3:7]))
    z = LOOKAT_HEIGHT_PER_STAND_HEIGHT * stand_h
    root_xy = rec.root_pose[:, :2]
    if camera.name == "fixed":
        lo, hi = root_xy.min(axis=0), root_xy.max(axis=0)
        centre = (lo + hi) / 2
        distance += 1.5 * float(np.linalg.norm(hi - lo))
        lookat = np.tile([centre[0], centre[1], z], (len(times_s), 1))
    else:
        dt = float(rec.t[1] - rec.t[0]) if len(rec.t) > 1 else 1.0
        smooth = _moving_average(root_xy, max(1, round(FOLLOW_SMOOTHING_S / dt)))
        xy = smooth[sample_index(rec, times_s)]
        lookat = np.column_stack([xy, np.full(len(times_s), z)])
    if camera.distance_m is not None:
        distance = camera.distance_m
    return {"lookat": lookat, "azimuth_deg": heading_deg + az_rel, "elevation_deg": el, "distance_m": distance}


def _model_camera_names(m: mujoco.MjModel) -> list[str]:
    return [m.camera(i).name for i in range(m.ncam) if m.camera(i).name]


def check_camera_in_model(m: mujoco.MjModel, camera: CameraSpec) -> None:
    """Raise :class:`RenderError` naming the valid cameras unless ``camera`` is a preset or a camera of ``m``."""
    if camera.distance_m is not None and not camera.distance_m > 0:
        raise RenderError(f"camera distance must be > 0 m, got {camera.distance_m}")
    if camera.name in CAMERA_PRESETS:
        return
    if camera.name not in _model_camera_names(m):
        valid = [*CAMERA_PRESETS, *_model_camera_names(m)]
        raise RenderError(f"unknown camera {camera.name!r}; cameras: {', '.join(valid)}")


def check_camera(robot: Robot, scene: str | os.PathLike[str] | None, camera: CameraSpec) -> None:
    """Raise :class:`RenderError` naming the valid cameras unless ``camera`` exists (cheap: no rendering)."""
    if camera.name in CAMERA_PRESETS:
        check_camera_in_model(mujoco.MjModel.from_xml_string("<mujoco/>"), camera)
    else:
        check_camera_in_model(compose(robot, scene, with_actuators=False), camera)
