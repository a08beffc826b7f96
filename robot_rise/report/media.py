"""The report's replay section: the video (MP4, or an animated GIF without an MP4 encoder) and the key-frame sheet.

Drawn only through :mod:`robot_rise.render` from the recording the check already made; the video
file is also written beside the page.
"""

from __future__ import annotations

import html
import io
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from robot_rise.model import Robot
from robot_rise.render import CameraSpec, contact_sheet, key_frame_times, mp4_encoder_available, render, render_frames
from robot_rise.report.page import data_uri, img_html
from robot_rise.sim.player import Recording
from robot_rise.trajectory import Trajectory

__all__ = [
    "VIDEO_SIZE_PX",
    "VIDEO_FPS",
    "GIF_SIZE_PX",
    "GIF_FPS",
    "KEY_FRAME_SIZE_PX",
    "ReplayMedia",
    "replay_media",
]

VIDEO_SIZE_PX = (480, 360)  # width, height of the embedded video
VIDEO_FPS = 20.0  # frame rate of the embedded video [1/s]
GIF_SIZE_PX = (320, 240)  # fallback animation without an MP4 encoder
GIF_FPS = 10.0  # frame rate of the fallback animation [1/s]
KEY_FRAME_SIZE_PX = (320, 240)  # width, height of one key frame in the sheet


@dataclass(frozen=True)
class ReplayMedia:
    """The replay section of the page and what went into it.

    Attributes:
        html: the section's HTML (video or GIF, then the key-frame sheet), everything embedded.
        video: the video (or GIF) file written beside the page, None if none.
        n_images: images embedded (the GIF counts, the MP4 does not).
    """

    html: str
    video: Path | None
    n_images: int


def replay_media(
    robot: Robot,
    trajectory: Trajectory,
    rec: Recording,
    out_dir: Path,
    *,
    scene: str | os.PathLike[str] | None,
    camera: CameraSpec,
    video: bool,
    key_frames: int,
    progress: Callable[[int, int], None] | None = None,
    stage: Callable[[str], None] | None = None,
) -> ReplayMedia:
    """Render ``rec`` (the replay of ``trajectory``) as a video in ``out_dir`` and as ``key_frames`` key frames.

    Args:
        robot: the robot.
        trajectory: the trajectory that was replayed.
        rec: its recording.
        out_dir: where the video file goes.
        scene: scene name or MJCF path it was replayed in.
        camera: camera of the video and key frames.
        video: make a video (MP4, or a GIF without imageio-ffmpeg); False for key frames only.
        key_frames: number of key frames in the contact sheet (>= 1).
        progress: called with (frames done, frames total) while rendering the video, then the key frames.
        stage: called with a short description at the start of each stage.

    Raises:
        RenderError: rendering is impossible here.
    """
    parts: list[str] = []
    video_path: Path | None = None
    images = 0
    if video:
        if mp4_encoder_available():
            video_path = out_dir / "video.mp4"
            vw, vh = VIDEO_SIZE_PX
            res = render(
                robot, trajectory, video_path, scene=scene, recording=rec, camera=camera, width=vw, height=vh, fps=VIDEO_FPS, progress=progress,
                stage=stage
            )
            parts.append(
                f'<video controls loop muted playsinline width="{vw}" height="{vh}" src="{data_uri("video/mp4", video_path.read_bytes())}"></video>'
                f'<p class="note">{res.n_frames} frames at {res.fps:.0f} fps, real time; also saved as {html.escape(video_path.name)}.</p>'
            )
        else:
            video_path = out_dir / "video.gif"
            gw, gh = GIF_SIZE_PX
            res = render(
                robot, trajectory, video_path, scene=scene, recording=rec, camera=camera, width=gw, height=gh, fps=GIF_FPS, progress=progress,
                stage=stage
            )
            parts.append(img_html(video_path.read_bytes(), "animation of the replay", "image/gif"))
            parts.append('<p class="note">Animated GIF: install imageio-ffmpeg for an MP4 video.</p>')
            images += 1
    times = key_frame_times(rec, key_frames)
    kw, kh = KEY_FRAME_SIZE_PX
    if stage is not None:
        stage(f"rendering {len(times)} key frames")
    frames = list(render_frames(robot, rec, times, scene=scene, camera=camera, width=kw, height=kh, shadows=True, label=False, progress=progress))
    sheet = contact_sheet(frames, [f"t = {t:.2f} s" for t in times])
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(sheet).save(buf, format="PNG")
    parts.append(img_html(buf.getvalue(), "key frames of the replay"))
    images += 1
    return ReplayMedia(html="".join(parts), video=video_path, n_images=images)
