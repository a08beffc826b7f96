"""The render entry: replay a trajectory and write it to a file whose suffix picks the kind.

Outputs by suffix: ``.mp4`` (H.264 video), ``.gif`` (animation), ``.png`` (contact sheet of key
frames). :func:`render` plays the trajectory first when no recording is given.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_rise.model import Robot
from robot_rise.render.camera import CameraSpec, check_camera
from robot_rise.render.encode import write_gif, write_mp4
from robot_rise.render.errors import RenderError
from robot_rise.render.frames import render_frames
from robot_rise.render.sheet import contact_sheet
from robot_rise.render.timing import DEFAULT_KEY_FRAMES, frame_times, key_frame_times
from robot_rise.sim.player import DEFAULT_HOLD_S, Recording, play
from robot_rise.trajectory import Trajectory

__all__ = ["RenderResult", "OUTPUT_SUFFIXES", "render"]

log = logging.getLogger(__name__)

OUTPUT_SUFFIXES = (".mp4", ".gif", ".png")
DEFAULT_SIZE_PX = {".mp4": (640, 480), ".gif": (400, 300), ".png": (320, 240)}  # width, height
DEFAULT_FPS = {".mp4": 30.0, ".gif": 15.0}


@dataclass(frozen=True)
class RenderResult:
    """What :func:`render` wrote.

    Attributes:
        path: the output file.
        kind: "mp4", "gif" or "png".
        n_frames: frames rendered (key frames for a contact sheet).
        width, height: size of one frame [px].
        fps: frame rate of the video [1/s] (0 for a contact sheet).
        duration_s: simulated time covered [s].
        render_wall_s: wall-clock time spent rendering and encoding [s] (playing excluded).
        render_fps: frames rendered per wall-clock second.
        backend: the OpenGL backend used (egl, osmesa, glfw).
    """

    path: Path
    kind: str
    n_frames: int
    width: int
    height: int
    fps: float
    duration_s: float
    render_wall_s: float
    render_fps: float
    backend: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly summary."""
        return {
            "path": str(self.path),
            "kind": self.kind,
            "n_frames": self.n_frames,
            "width": self.width,
            "height": self.height,
            "fps": self.fps,
            "duration_s": round(self.duration_s, 3),
            "render_wall_s": round(self.render_wall_s, 3),
            "render_fps": round(self.render_fps, 2),
            "backend": self.backend,
        }


def render(
    robot: Robot,
    trajectory: Trajectory,
    out: str | os.PathLike[str],
    *,
    scene: str | os.PathLike[str] | None = "flat",
    recording: Recording | None = None,
    camera: CameraSpec = CameraSpec(),
    width: int | None = None,
    height: int | None = None,
    fps: float | None = None,
    speed: float = 1.0,
    key_frames: int = DEFAULT_KEY_FRAMES,
    shadows: bool | None = None,
    hold_s: float = DEFAULT_HOLD_S,
    progress: Callable[[int, int], None] | None = None,
    stage: Callable[[str], None] | None = None,
) -> RenderResult:
    """Replay ``trajectory`` in MuJoCo and write it as a video, a GIF or a contact sheet.

    Args:
        robot: the robot.
        trajectory: the trajectory (played from its start posture unless ``recording`` is given).
        out: output file; the suffix picks the kind: .mp4, .gif, .png (contact sheet).
        scene: scene name or MJCF path.
        recording: an existing recording of this trajectory (skips playing).
        camera: how the camera moves.
        width, height: frame size [px] (default by kind: 640x480 mp4, 400x300 gif, 320x240 png tiles).
        fps: video frame rate [1/s] (default 30 mp4, 15 gif; ignored for png).
        speed: playback speed, x real time (0.5 is slow motion).
        key_frames: number of tiles of a contact sheet.
        shadows: draw shadows (default: on for a contact sheet, off for videos, where they
            cost two thirds of the frame rate of a CPU renderer).
        hold_s: time the last goal is held after the trajectory, when playing [s].
        progress: called with (frames done, frames total).
        stage: called with a short description at the start of each stage (replay, frames).

    Raises:
        RenderError: unknown suffix, no OpenGL backend, no encoder.
    """
    path = Path(out)
    suffix = path.suffix.lower()
    if suffix not in OUTPUT_SUFFIXES:
        raise RenderError(f"cannot tell the output kind of {path.name!r}; use one of {', '.join(OUTPUT_SUFFIXES)}")
    dw, dh = DEFAULT_SIZE_PX[suffix]
    w, h = int(width or dw), int(height or dh)
    if suffix == ".mp4" and (w % 2 or h % 2):
        raise RenderError(f"MP4 frames need an even width and height, got {w}x{h}")
    if suffix == ".png" and key_frames < 1:
        raise RenderError(f"need at least one key frame, got {key_frames}")
    if suffix != ".png":
        frame_times(1.0, float(DEFAULT_FPS[suffix] if fps is None else fps), speed=speed)  # checks fps and speed
    check_camera(robot, scene, camera)
    if shadows is None:
        shadows = suffix == ".png"
    say = stage or (lambda text: None)
    if recording is None:
        say(f"replaying {trajectory.duration_s:.2f} s + {hold_s:g} s hold through the servo model")
        recording = play(robot, trajectory, scene=scene, hold_s=hold_s)
    rec = recording
    path.parent.mkdir(parents=True, exist_ok=True)
    backend: list[str] = []
    t0 = time.perf_counter()
    if suffix == ".png":
        times = key_frame_times(rec, key_frames)
        say(f"rendering {len(times)} key frames to {path.name}")
        imgs = list(
            render_frames(
                robot, rec, times, scene=scene, camera=camera, width=w, height=h, shadows=shadows, label=False, progress=progress, backend_out=backend
            )
        )
        title = f"{robot.name} in {scene}: {trajectory.duration_s:.2f} s trajectory + {rec.t[-1] - trajectory.duration_s:.2f} s hold"
        sheet = contact_sheet(imgs, [f"t = {t:.2f} s" for t in times], title=title)
        from PIL import Image

        Image.fromarray(sheet).save(path)
        n, rate = len(imgs), 0.0
    else:
        rate = float(DEFAULT_FPS[suffix] if fps is None else fps)
        times = frame_times(float(rec.t[-1]), rate, speed=speed)
        say(f"rendering {len(times)} frames to {path.name}")
        frames = render_frames(
            robot, rec, times, scene=scene, camera=camera, width=w, height=h, shadows=shadows, progress=progress, backend_out=backend
        )
        n = write_mp4(path, frames, width=w, height=h, fps=rate) if suffix == ".mp4" else write_gif(path, frames, fps=rate)
    wall = time.perf_counter() - t0
    result = RenderResult(
        path=path,
        kind=suffix[1:],
        n_frames=n,
        width=w,
        height=h,
        fps=rate,
        duration_s=float(rec.t[-1]),
        render_wall_s=wall,
        render_fps=n / wall if wall > 0 else 0.0,
        backend=backend[0] if backend else "",
    )
    log.info("wrote %s: %d frames %dx%d in %.1f s (%.1f frames/s, %s)", path, n, w, h, wall, result.render_fps, result.backend)
    return result
