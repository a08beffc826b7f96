"""Pictures of a played trajectory: offscreen frames, MP4, GIF, a PNG contact sheet, the viewer.

Nothing here simulates: frames are drawn from a :class:`robot_rise.sim.Recording`.
:func:`render` plays the trajectory first when no recording is given.

- :mod:`~robot_rise.render.errors`: ``RenderError``.
- :mod:`~robot_rise.render.gl`: OpenGL backends and the offscreen context (EGL, OSMesa, GLFW).
- :mod:`~robot_rise.render.renderer`: ``OffscreenRenderer``, RGB frames of one model.
- :mod:`~robot_rise.render.labels`: text drawn onto frames.
- :mod:`~robot_rise.render.timing`: frame times, key frame times, the nearest recording sample.
- :mod:`~robot_rise.render.camera`: ``CameraSpec``, its presets, the camera track, the name check.
- :mod:`~robot_rise.render.pose`: ``pose_sample``, the robot posed at one recording sample.
- :mod:`~robot_rise.render.frames`: ``render_frames``, a recording drawn frame by frame.
- :mod:`~robot_rise.render.sheet`: ``contact_sheet``, key frames tiled into one picture.
- :mod:`~robot_rise.render.encode`: MP4 and GIF writers, and whether MP4 can be written here.
- :mod:`~robot_rise.render.output`: ``render``, a trajectory to a file whose suffix picks the kind.
- :mod:`~robot_rise.render.viewer`: ``view``, MuJoCo's interactive window, and the display check.
"""

from robot_rise.render.camera import CAMERA_PRESETS, CameraSpec, camera_track, check_camera
from robot_rise.render.encode import mp4_encoder_available
from robot_rise.render.errors import RenderError
from robot_rise.render.frames import render_frames
from robot_rise.render.gl import display_available, gl_backends
from robot_rise.render.output import OUTPUT_SUFFIXES, RenderResult, render
from robot_rise.render.pose import pose_sample
from robot_rise.render.renderer import OffscreenRenderer
from robot_rise.render.sheet import contact_sheet
from robot_rise.render.timing import frame_times, key_frame_times
from robot_rise.render.viewer import require_display, view

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
    "pose_sample",
    "render_frames",
    "contact_sheet",
    "render",
    "mp4_encoder_available",
    "view",
    "display_available",
    "require_display",
    "check_camera",
]
