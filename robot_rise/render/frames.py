"""Frames of a recording: the robot posed at each sample and drawn offscreen, one frame at a time.

Nothing here simulates: each frame is the robot posed at the nearest sample
(:func:`~robot_rise.render.pose.pose_sample`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import mujoco
import numpy as np

from robot_rise.model import Robot, compose, model_index
from robot_rise.render.camera import CAMERA_PRESETS, CameraSpec, camera_track, check_camera_in_model
from robot_rise.render.errors import RenderError
from robot_rise.render.pose import pose_sample
from robot_rise.render.renderer import OffscreenRenderer
from robot_rise.render.timing import sample_index
from robot_rise.sim.player import Recording

__all__ = ["render_frames"]


def render_frames(
    robot: Robot,
    rec: Recording,
    times_s: Sequence[float] | np.ndarray,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    camera: CameraSpec = CameraSpec(),
    width: int = 640,
    height: int = 480,
    shadows: bool = False,
    label: bool = True,
    progress: Callable[[int, int], None] | None = None,
    backend_out: list[str] | None = None,
) -> Iterator[np.ndarray]:
    """Frames of ``rec`` at the given times, drawn one at a time (a generator).

    Args:
        robot: the robot that was played.
        rec: the recording (root pose and joint angles per sample).
        times_s: simulated times of the frames [s], shape (F,); each uses the nearest sample.
        scene: the scene it was played in (shipped name, path, or None for no ground).
        camera: how the camera moves.
        width, height: frame size [px].
        shadows: draw shadows.
        label: write "t = ... s" in the top left corner.
        progress: called with (frames done, frames total) after each frame.
        backend_out: if given, the OpenGL backend's name is appended once the context exists.

    Yields:
        RGB images, shape (height, width, 3), uint8.

    Raises:
        RenderError: no OpenGL backend, unknown camera, bad size.
    """
    times = np.asarray(times_s, dtype=float)
    if len(rec.t) == 0:
        raise RenderError("the recording is empty")
    m = compose(robot, scene, with_actuators=False)
    check_camera_in_model(m, camera)
    d = mujoco.MjData(m)
    index = model_index(m, robot)
    samples = sample_index(rec, times)
    cam = mujoco.MjvCamera()
    track: dict[str, Any] | None = None
    if camera.name in CAMERA_PRESETS:
        track = camera_track(robot, rec, camera, times)
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.azimuth = float(track["azimuth_deg"])
        cam.elevation = float(track["elevation_deg"])
        cam.distance = float(track["distance_m"])
    else:
        cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        cam.fixedcamid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, camera.name)
    with OffscreenRenderer(m, width, height, shadows=shadows) as renderer:
        if backend_out is not None:
            backend_out.append(renderer.backend)
        for f, k in enumerate(samples):
            pose_sample(m, d, index, rec, int(k))
            mujoco.mj_kinematics(m, d)
            mujoco.mj_camlight(m, d)
            if track is not None:
                cam.lookat[:] = track["lookat"][f]
            yield renderer.render(d, cam, label=f"t = {times[f]:.2f} s" if label else "")
            if progress is not None:
                progress(f + 1, len(samples))
