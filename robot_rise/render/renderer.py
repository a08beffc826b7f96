"""The offscreen renderer: RGB frames of one MuJoCo model drawn into an OpenGL context without a screen."""

from __future__ import annotations

import mujoco
import numpy as np

from robot_rise.render.errors import RenderError
from robot_rise.render.gl import open_gl_context
from robot_rise.render.labels import draw_label

__all__ = ["OffscreenRenderer"]

SHADOW_MAP_SIZE_PX = 1024  # shadow map resolution (MuJoCo's 4096 halves the CPU frame rate)
MAX_GL_SIZE_PX = 4096  # largest frame side accepted [px]
FAR_DEPTH = 1.0 - 1e-5  # normalised depth above which a pixel is background (far plane is 1)
SKY_TOP_RGB = (158, 190, 222)  # sky colour at the top of the frame (0-255)
SKY_HORIZON_RGB = (228, 236, 244)  # and at the bottom (seen only near the horizon)


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
        self._gl, self.backend = open_gl_context(self.width, self.height)
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
            img = draw_label(img, label)
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
