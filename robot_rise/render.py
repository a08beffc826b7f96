"""Pictures of a played trajectory: offscreen frames, MP4, GIF, a PNG contact sheet, the viewer.

Nothing here simulates: frames are drawn from a :class:`robot_rise.sim.Recording` (root pose and
joint angles per sample, which with a scene of static geoms is the whole qpos). :func:`render`
plays the trajectory first when no recording is given.

Offscreen rendering needs an OpenGL context without a screen. MuJoCo offers EGL and OSMesa on
Linux; with Mesa's EGL (``libegl1``, ``libegl-mesa0``, ``libgl1-mesa-dri``) EGL runs on the CPU
(llvmpipe), no GPU needed. ``MUJOCO_GL`` picks the backend as in MuJoCo (``egl``, ``osmesa``,
``glfw``); unset, EGL is tried, then OSMesa, then GLFW where a display exists. Where none works
:class:`RenderError` says what was tried and what to install.

Cameras (:class:`CameraSpec`): ``follow`` (default) tracks the robot's root, smoothed, from its
front-left; ``front``, ``side``, ``back`` and ``top`` follow from those sides of the robot's final
heading; ``fixed`` stays still and frames the whole motion; any other name is a camera of the
composed model. Azimuth, elevation and distance can be overridden.

Outputs by suffix: ``.mp4`` (H.264 through imageio-ffmpeg's bundled ffmpeg), ``.gif`` (Pillow),
``.png`` (contact sheet of key frames, Pillow).
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from robot_rise.errors import RobotRiseError
from robot_rise.model import Robot, compose, model_index
from robot_rise.posture import yaw_rad
from robot_rise.sim.player import DEFAULT_HOLD_S, Recording, play
from robot_rise.trajectory import Trajectory

__all__ = [
    "RenderError",
    "CameraSpec",
    "RenderResult",
    "OffscreenRenderer",
    "CAMERA_PRESETS",
    "OUTPUT_SUFFIXES",
    "gl_backends",
    "frame_times",
    "key_frame_times",
    "camera_track",
    "render_frames",
    "contact_sheet",
    "render",
    "view",
    "display_available",
    "require_display",
    "check_camera",
]

log = logging.getLogger(__name__)

OUTPUT_SUFFIXES = (".mp4", ".gif", ".png")
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
SHADOW_MAP_SIZE_PX = 1024  # shadow map resolution (MuJoCo's 4096 halves the CPU frame rate)
DEFAULT_SIZE_PX = {".mp4": (640, 480), ".gif": (400, 300), ".png": (320, 240)}  # width, height
DEFAULT_FPS = {".mp4": 30.0, ".gif": 15.0}
DEFAULT_KEY_FRAMES = 8
MAX_GL_SIZE_PX = 4096  # largest frame side accepted [px]
FAR_DEPTH = 1.0 - 1e-5  # normalised depth above which a pixel is background (far plane is 1)
SKY_TOP_RGB = (158, 190, 222)  # sky colour at the top of the frame (0-255)
SKY_HORIZON_RGB = (228, 236, 244)  # and at the bottom (seen only near the horizon)


class RenderError(RobotRiseError):
    """Rendering is impossible here (no OpenGL backend, no encoder) or was asked wrongly."""


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


# --- OpenGL context ------------------------------------------------------------------------------


def display_available() -> bool:
    """True where a window could open (an X11 or Wayland display is set, or not on Linux)."""
    if os.name != "posix" or os.uname().sysname != "Linux":
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def require_display() -> None:
    """Raise :class:`RenderError` (with what to do instead) where no window can open."""
    if not display_available():
        raise RenderError(
            "no display: the interactive viewer needs a screen (DISPLAY or WAYLAND_DISPLAY is not set)",
            hint="write a video instead: robot-rise render TRAJ --out rise.mp4 (or robot-rise report TRAJ --out DIR)",
        )


def gl_backends() -> tuple[str, ...]:
    """OpenGL backends to try, in order: ``MUJOCO_GL`` if set, else egl, osmesa (and glfw with a display)."""
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    if chosen in ("egl", "osmesa", "glfw"):
        return (chosen,)
    order = ["egl", "osmesa"]
    if display_available():
        order.insert(0, "glfw")
    return tuple(order)


def _make_gl_context(backend: str, width: int, height: int) -> Any:
    """An OpenGL context of ``backend`` (raises whatever the backend raises)."""
    if backend == "egl":
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
        from mujoco.osmesa import GLContext  # type: ignore[no-redef]
    elif backend == "glfw":
        from mujoco.glfw import GLContext  # type: ignore[no-redef]
    else:  # pragma: no cover - gl_backends() only yields the three above
        raise ValueError(backend)
    return GLContext(width, height)


def _open_gl_context(width: int, height: int) -> tuple[Any, str]:
    """The first backend of :func:`gl_backends` that gives a working context, and its name."""
    tried: list[str] = []
    for backend in gl_backends():
        try:
            ctx = _make_gl_context(backend, width, height)
            ctx.make_current()
        except Exception as e:  # each backend fails its own way (ImportError, RuntimeError, EGLError)
            first = (str(e).strip().splitlines() or [type(e).__name__])[0]
            tried.append(f"{backend}: {first[:160]}")
            log.debug("OpenGL backend %s failed: %r", backend, e)
            continue
        log.debug("OpenGL backend %s", backend)
        return ctx, backend
    raise RenderError(
        "offscreen rendering is impossible here: no OpenGL backend works (" + "; ".join(tried) + ")",
        hint="install Mesa's EGL (apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri, or run .ci/system-deps) "
        "and PyOpenGL; or set MUJOCO_GL=osmesa with libosmesa6",
    )


def _font(size_px: int) -> Any:
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size_px)
    except TypeError:  # Pillow < 10.1 has one fixed-size default font
        return ImageFont.load_default()


def _draw_label(img: np.ndarray, text: str) -> np.ndarray:
    """``img`` with ``text`` in its top left corner, dark on a light outline (any background)."""
    from PIL import Image, ImageDraw

    pil = Image.fromarray(img)
    size = max(10, img.shape[0] // 20)
    ImageDraw.Draw(pil).text(
        (size // 2, size // 2), text, fill=(20, 20, 20), font=_font(size), stroke_width=max(1, size // 8), stroke_fill=(255, 255, 255)
    )
    return np.asarray(pil).copy()


class OffscreenRenderer:
    """Draws RGB frames of one model offscreen. A context manager; not thread-safe.

    Args:
        model: the composed model (its offscreen buffer is enlarged to fit if needed).
        width, height: frame size [px].
        shadows: draw shadows (a third of the frame rate on a CPU renderer).
        sky: paint a sky gradient where nothing is drawn (MuJoCo leaves it black).

    Raises:
        RenderError: no OpenGL backend works, or the size is out of range.
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int, *, shadows: bool = True, sky: bool = True) -> None:
        if not (16 <= width <= MAX_GL_SIZE_PX and 16 <= height <= MAX_GL_SIZE_PX):
            raise RenderError(f"frame size {width}x{height} is out of range (16 to {MAX_GL_SIZE_PX} px a side)")
        self.model = model
        self.width, self.height = int(width), int(height)
        self.shadows = shadows
        model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), self.width)
        model.vis.global_.offheight = max(int(model.vis.global_.offheight), self.height)
        model.vis.quality.shadowsize = SHADOW_MAP_SIZE_PX
        self._gl, self.backend = _open_gl_context(self.width, self.height)
        self._ctx: mujoco.MjrContext | None = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100.value)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self._ctx)
        self._scene = mujoco.MjvScene(model, maxgeom=max(1000, 4 * model.ngeom))
        self._option = mujoco.MjvOption()
        self._perturb = mujoco.MjvPerturb()
        self._rect = mujoco.MjrRect(0, 0, self.width, self.height)
        self._depth = np.empty((self.height, self.width), dtype=np.float32)
        self._sky: np.ndarray | None = None
        if sky:
            rows = np.linspace(0.0, 1.0, self.height)[:, None, None]
            gradient = (1 - rows) * np.array(SKY_TOP_RGB) + rows * np.array(SKY_HORIZON_RGB)
            self._sky = np.broadcast_to(gradient, (self.height, self.width, 3)).astype(np.uint8)

    def render(self, data: mujoco.MjData, camera: mujoco.MjvCamera, *, label: str = "") -> np.ndarray:
        """One frame of ``data`` (kinematics already computed) seen by ``camera``.

        Returns:
            RGB image, shape (height, width, 3), uint8, top row first.
        """
        if self._ctx is None:
            raise RenderError("renderer is closed")
        self._gl.make_current()
        mujoco.mjv_updateScene(self.model, data, self._option, self._perturb, camera, mujoco.mjtCatBit.mjCAT_ALL.value, self._scene)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = self.shadows
        mujoco.mjr_render(self._rect, self._scene, self._ctx)
        buf = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(buf, self._depth if self._sky is not None else None, self._rect, self._ctx)
        img = np.ascontiguousarray(buf[::-1])
        if self._sky is not None:  # nothing drawn there (depth at the far plane): paint the sky
            empty = self._depth[::-1] >= FAR_DEPTH
            img[empty] = self._sky[empty]
        if label:
            img = _draw_label(img, label)
        return img

    def close(self) -> None:
        """Free the GL resources (idempotent)."""
        if self._ctx is not None:
            self._gl.make_current()
            self._ctx.free()
            self._ctx = None
            self._gl.free()

    def __enter__(self) -> OffscreenRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --- cameras and frame times ---------------------------------------------------------------------


def frame_times(duration_s: float, fps: float, *, speed: float = 1.0) -> np.ndarray:
    """Simulated times of the frames of a video at ``fps`` played at ``speed`` x real time [s].

    Returns:
        shape (F,), from 0, step ``speed / fps``, the last one <= ``duration_s``.
    """
    if fps <= 0 or speed <= 0:
        raise RenderError(f"fps and speed must be > 0 (got fps {fps}, speed {speed})")
    step = speed / fps
    return np.arange(0.0, duration_s + 1e-9, step)


def key_frame_times(rec: Recording, n: int = DEFAULT_KEY_FRAMES) -> np.ndarray:
    """``n`` evenly spaced sample times of ``rec`` from the start to the last sample [s], shape (n,)."""
    if n < 1:
        raise RenderError(f"need at least one key frame, got {n}")
    if len(rec.t) == 0:
        raise RenderError("the recording is empty")
    return np.linspace(0.0, float(rec.t[-1]), n)


def _sample_index(rec: Recording, times_s: np.ndarray) -> np.ndarray:
    """Index of the recording sample nearest each time, shape like ``times_s``."""
    idx = np.searchsorted(rec.t, times_s)
    idx = np.clip(idx, 1, len(rec.t) - 1) if len(rec.t) > 1 else np.zeros_like(idx)
    if len(rec.t) > 1:
        left_closer = np.abs(times_s - rec.t[idx - 1]) <= np.abs(rec.t[idx] - times_s)
        idx = np.where(left_closer, idx - 1, idx)
    return idx.astype(int)


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
        xy = smooth[_sample_index(rec, times_s)]
        lookat = np.column_stack([xy, np.full(len(times_s), z)])
    if camera.distance_m is not None:
        distance = camera.distance_m
    return {"lookat": lookat, "azimuth_deg": heading_deg + az_rel, "elevation_deg": el, "distance_m": distance}


def _model_camera_names(m: mujoco.MjModel) -> list[str]:
    return [m.camera(i).name for i in range(m.ncam) if m.camera(i).name]


def _check_camera(m: mujoco.MjModel, camera: CameraSpec) -> None:
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
        _check_camera(mujoco.MjModel.from_xml_string("<mujoco/>"), camera)
    else:
        _check_camera(compose(robot, scene, with_actuators=False), camera)


# --- frames --------------------------------------------------------------------------------------


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
    _check_camera(m, camera)
    d = mujoco.MjData(m)
    index = model_index(m, robot)
    samples = _sample_index(rec, times)
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
            d.qpos[:] = m.qpos0
            d.qpos[index.qpos_root] = rec.root_pose[k]
            d.qpos[index.qpos_joints] = rec.q[k]
            mujoco.mj_kinematics(m, d)
            mujoco.mj_camlight(m, d)
            if track is not None:
                cam.lookat[:] = track["lookat"][f]
            yield renderer.render(d, cam, label=f"t = {times[f]:.2f} s" if label else "")
            if progress is not None:
                progress(f + 1, len(samples))


def contact_sheet(frames: Sequence[np.ndarray], labels: Sequence[str], *, columns: int = 4, title: str = "") -> np.ndarray:
    """Tile frames into one picture with a caption under each.

    Args:
        frames: RGB images of one size, shape (H, W, 3) each, uint8.
        labels: one caption per frame.
        columns: tiles per row (fewer if there are fewer frames).
        title: optional line above the tiles.

    Returns:
        RGB image, uint8, shape (rows * (H + caption) + title, columns * W + gaps, 3).
    """
    from PIL import Image, ImageDraw

    if not frames:
        raise RenderError("no frames for a contact sheet")
    h, w = frames[0].shape[:2]
    cols = max(1, min(columns, len(frames)))
    rows = math.ceil(len(frames) / cols)
    gap = 4
    font_px = max(10, h // 14)
    caption = font_px + 6
    top = caption + gap if title else 0
    sheet = Image.new("RGB", (cols * w + (cols + 1) * gap, top + rows * (h + caption + gap) + gap), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    font = _font(font_px)
    if title:
        draw.text((gap, gap), title, fill=(0, 0, 0), font=font)
    for i, (img, text) in enumerate(zip(frames, labels)):
        r, c = divmod(i, cols)
        x = gap + c * (w + gap)
        y = top + gap + r * (h + caption + gap)
        sheet.paste(Image.fromarray(img), (x, y))
        draw.text((x + 2, y + h + 2), text, fill=(0, 0, 0), font=font)
    return np.asarray(sheet)


# --- writers -------------------------------------------------------------------------------------


def _write_mp4(path: Path, frames: Iterator[np.ndarray], *, width: int, height: int, fps: float) -> int:
    try:
        import imageio_ffmpeg
    except ImportError:
        raise RenderError("MP4 output needs imageio-ffmpeg", hint="pip install imageio-ffmpeg, or write a .gif") from None
    tmp = path.with_name(path.stem + ".partial" + path.suffix)
    writer = imageio_ffmpeg.write_frames(
        str(tmp),
        (width, height),
        fps=fps,
        codec="libx264",
        pix_fmt_out="yuv420p",
        quality=7,
        macro_block_size=2,
        ffmpeg_log_level="error",
        output_params=["-movflags", "+faststart"],
    )
    n = 0
    try:
        writer.send(None)
        for img in frames:
            writer.send(np.ascontiguousarray(img))
            n += 1
    except (OSError, RuntimeError) as e:
        raise RenderError(f"ffmpeg failed writing {path}: {e}") from e
    finally:
        writer.close()
    os.replace(tmp, path)
    return n


def _write_gif(path: Path, frames: Iterator[np.ndarray], *, fps: float) -> int:
    from PIL import Image

    images: list[Image.Image] = []
    palette: Image.Image | None = None
    for img in frames:
        pil = Image.fromarray(img)
        if palette is None:  # one palette for every frame: no flicker, and quantizing is cheaper
            palette = pil.quantize(colors=255, method=Image.Quantize.MEDIANCUT)
        images.append(pil.quantize(palette=palette, dither=Image.Dither.NONE))
    if not images:
        raise RenderError("no frames to write")
    images[0].save(path, save_all=True, append_images=images[1:], duration=max(20, round(1000 / fps)), loop=0, disposal=1)
    return len(images)


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
    if recording is None:
        recording = play(robot, trajectory, scene=scene, hold_s=hold_s)
    rec = recording
    path.parent.mkdir(parents=True, exist_ok=True)
    backend: list[str] = []
    t0 = time.perf_counter()
    if suffix == ".png":
        times = key_frame_times(rec, key_frames)
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
        frames = render_frames(
            robot, rec, times, scene=scene, camera=camera, width=w, height=h, shadows=shadows, progress=progress, backend_out=backend
        )
        n = _write_mp4(path, frames, width=w, height=h, fps=rate) if suffix == ".mp4" else _write_gif(path, frames, fps=rate)
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


# --- interactive viewer --------------------------------------------------------------------------


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
            k = int(_sample_index(rec, np.array([t_sim]))[0])
            with handle.lock():
                d.qpos[index.qpos_root] = rec.root_pose[k]
                d.qpos[index.qpos_joints] = rec.q[k]
                d.time = float(rec.t[k])
                mujoco.mj_forward(m, d)
            handle.sync()
            time.sleep(1 / 60)
