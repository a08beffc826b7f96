"""When frames are taken: video frame times, key frame times, and the recording sample nearest each."""

from __future__ import annotations

import numpy as np

from robot_rise.render.errors import RenderError
from robot_rise.sim.player import Recording

__all__ = ["DEFAULT_KEY_FRAMES", "frame_times", "key_frame_times", "sample_index"]

DEFAULT_KEY_FRAMES = 8


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


def sample_index(rec: Recording, times_s: np.ndarray) -> np.ndarray:
    """Index of the recording sample nearest each time, shape like ``times_s``."""
    idx = np.searchsorted(rec.t, times_s)
    idx = np.clip(idx, 1, len(rec.t) - 1) if len(rec.t) > 1 else np.zeros_like(idx)
    if len(rec.t) > 1:
        left_closer = np.abs(times_s - rec.t[idx - 1]) <= np.abs(rec.t[idx] - times_s)
        idx = np.where(left_closer, idx - 1, idx)
    return idx.astype(int)
