"""OpenGL contexts without a screen: which backends to try here, and the first one that works.

MuJoCo offers EGL and OSMesa on Linux; with Mesa's EGL (``libegl1``, ``libegl-mesa0``,
``libgl1-mesa-dri``) EGL runs on the CPU (llvmpipe), no GPU needed. ``MUJOCO_GL`` picks the
backend as in MuJoCo (``egl``, ``osmesa``, ``glfw``); unset, EGL is tried, then OSMesa, then GLFW
where a display exists. Where none works :class:`RenderError` says what was tried and what to
install.
"""

from __future__ import annotations

import logging
import os
from typing import Any

from robot_rise.render.errors import RenderError

__all__ = ["display_available", "gl_backends", "open_gl_context"]

log = logging.getLogger(__name__)


def display_available() -> bool:
    """True where a window could open (an X11 or Wayland display is set, or not on Linux)."""
    if os.name != "posix" or os.uname().sysname != "Linux":
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


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


def open_gl_context(width: int, height: int) -> tuple[Any, str]:
    """The first backend of :func:`gl_backends` that gives a working context, and its name.

    Args:
        width, height: size of the context's framebuffer [px].

    Returns:
        The current GL context (MuJoCo's ``GLContext`` of that backend) and the backend's name.

    Raises:
        RenderError: no backend works; the message lists each one's first error line.
    """
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
