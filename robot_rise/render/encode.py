"""Frames to video files: MP4 (H.264 through imageio-ffmpeg's bundled ffmpeg) and GIF (Pillow)."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from robot_rise.render.errors import RenderError

__all__ = ["mp4_encoder_available", "write_mp4", "write_gif"]


def mp4_encoder_available() -> bool:
    """Whether MP4 can be written here: imageio-ffmpeg (which bundles ffmpeg) is installed."""
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        return False
    return True


def write_mp4(path: Path, frames: Iterator[np.ndarray], *, width: int, height: int, fps: float) -> int:
    """Encode ``frames`` (RGB, shape (height, width, 3), uint8) as an H.264 MP4 at ``fps`` [1/s].

    Written to a ``.partial`` file first and renamed at the end, so a failed run leaves no
    truncated video under ``path``.

    Returns:
        The number of frames written.

    Raises:
        RenderError: imageio-ffmpeg is missing, or ffmpeg fails.
    """
    if not mp4_encoder_available():
        raise RenderError("MP4 output needs imageio-ffmpeg", hint="pip install imageio-ffmpeg, or write a .gif")
    import imageio_ffmpeg

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


def write_gif(path: Path, frames: Iterator[np.ndarray], *, fps: float) -> int:
    """Write ``frames`` (RGB, uint8) as a looping GIF at ``fps`` [1/s], one shared palette.

    Returns:
        The number of frames written.

    Raises:
        RenderError: there are no frames.
    """
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
