"""The interactive viewer: a recording shown in MuJoCo's window in real time, and the check that a window can open."""

from __future__ import annotations

import math
import os
import time

import numpy as np

from robot_rise.model import Robot, compose, model_index
from robot_rise.posture import yaw_rad
from robot_rise.render.camera import CAMERA_PRESETS, DISTANCE_PER_STAND_HEIGHT
from robot_rise.render.errors import RenderError
from robot_rise.render.gl import display_available
from robot_rise.render.pose import pose_sample
from robot_rise.render.timing import sample_index
from robot_rise.sim.player import Recording

__all__ = ["require_display", "view"]


def require_display() -> None:
    """Raise :class:`RenderError` (with what to do instead) where no window can open."""
    if not display_available():
        raise RenderError(
            "no display: the interactive viewer needs a screen (DISPLAY or WAYLAND_DISPLAY is not set)",
            hint="write a video instead: robot-rise render TRAJ --out rise.mp4 (or robot-rise report TRAJ --out DIR)",
        )


def view(
    robot: Robot,
    rec: Recording,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    speed: float = 1.0,
    loop: bool = True,
) -> None:
    """Show ``rec`` in MuJoCo's interactive viewer, in real time x ``speed``, until the window closes.

    Raises:
        RenderError: there is no display, or the viewer cannot start.
    """
    require_display()
    if speed <= 0:
        raise RenderError(f"speed must be > 0, got {speed}")
    import mujoco.viewer

    m = compose(robot, scene, with_actuators=False)
    d = mujoco.MjData(m)
    index = model_index(m, robot)
    try:
        handle = mujoco.viewer.launch_passive(m, d)
    except Exception as e:  # GLFW cannot open a window: no X server behind DISPLAY, no GL
        raise RenderError(f"the MuJoCo viewer cannot start: {e}", hint="check DISPLAY, or use robot-rise render") from e
    with handle:
        with handle.lock():  # a tracking camera on the root, from the follow preset's side
            az_rel, el = CAMERA_PRESETS["follow"]
            handle.cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            handle.cam.trackbodyid = index.root_body
            handle.cam.distance = DISTANCE_PER_STAND_HEIGHT * float(rec.stand_height_m)
            handle.cam.azimuth = math.degrees(yaw_rad(rec.root_pose[-1, 3:7])) + az_rel
            handle.cam.elevation = el
        t_wall0 = time.monotonic()
        while handle.is_running():
            t_sim = (time.monotonic() - t_wall0) * speed
            if t_sim > rec.t[-1]:
                if not loop:
                    break
                t_wall0 = time.monotonic()
                t_sim = 0.0
            k = int(sample_index(rec, np.array([t_sim]))[0])
            with handle.lock():
                pose_sample(m, d, index, rec, k)
                d.time = float(rec.t[k])
                mujoco.mj_forward(m, d)
            handle.sync()
            time.sleep(1 / 60)
