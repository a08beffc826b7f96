"""Offscreen rendering: a short trajectory to PNG, GIF and MP4; frames not blank and different."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.render import (
    CameraSpec,
    RenderError,
    camera_track,
    frame_times,
    key_frame_times,
    mp4_encoder_available,
    pose_sample,
    render,
    render_frames,
    view,
)
from robot_rise.sim.player import Recording, play
from robot_rise.trajectory import Trajectory

ARM_JOINTS = ("l_sho_pitch", "r_sho_pitch", "l_el", "r_el")
SMALL = {"width": 160, "height": 120}


def arm_wave(robot: Robot, duration_s: float = 1.0) -> Trajectory:
    """From the stand keyframe, raise the arms forward and bring them back in ``duration_s``."""
    names = robot.joint_names
    start = Posture(robot.name, robot.stand_qpos[:3], robot.stand_qpos[3:7], dict(zip(names, robot.stand_qpos[7:])))
    t = np.linspace(0.0, duration_s, 21)
    q = np.tile(robot.stand_qpos[7:], (t.size, 1))
    for name in ARM_JOINTS:
        j = names.index(name)
        q[:, j] = np.clip(q[:, j] + 1.3 * np.sin(np.pi * t / duration_s), robot.joint_lower[j], robot.joint_upper[j])
    return Trajectory(robot.name, names, t, q, start, report={"note": "test arm wave"})


@pytest.fixture(scope="module")
def wave(robot: Robot) -> tuple[Trajectory, Recording]:
    tr = arm_wave(robot)
    return tr, play(robot, tr, hold_s=0.5)


def assert_not_blank(img: np.ndarray) -> None:
    assert img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8
    assert img.std() > 10.0, "frame is (nearly) one colour"
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 20, "frame has almost no colours"


def mean_abs_diff(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(int) - b.astype(int)).mean())


def changed_pixels(a: np.ndarray, b: np.ndarray, threshold: int = 60) -> int:
    """Pixels whose colour changed a lot (a moving limb, not the floor sliding by a pixel)."""
    return int((np.abs(a.astype(int) - b.astype(int)).max(axis=2) > threshold).sum())


def test_frames_of_a_moving_robot_are_not_blank_and_differ(robot, wave):
    _, rec = wave
    frames = list(render_frames(robot, rec, [0.0, 0.5, 1.5], camera=CameraSpec("front"), label=False, **SMALL))
    assert len(frames) == 3
    for img in frames:
        assert_not_blank(img)
        assert img.shape == (120, 160, 3)
    # arms raised at 0.5 s; back down once the motion has ended and settled
    assert changed_pixels(frames[0], frames[1]) > 100
    assert changed_pixels(frames[0], frames[1]) > 3 * changed_pixels(frames[0], frames[2])


def test_png_output_is_a_contact_sheet_of_the_key_frames(robot, wave, tmp_path):
    from PIL import Image

    tr, rec = wave
    res = render(robot, tr, tmp_path / "sheet.png", recording=rec, key_frames=4, **SMALL)
    assert res.kind == "png" and res.n_frames == 4 and res.backend
    sheet = np.asarray(Image.open(res.path).convert("RGB"))
    assert sheet.shape[1] >= 4 * 160 and sheet.shape[0] >= 120
    assert_not_blank(sheet)
    tiles = [sheet[-140:-20, x : x + 160] for x in (4, 4 + 164)]  # bottom row: the first two tiles
    for tile in tiles:
        assert tile.std() > 10.0


def test_gif_output_has_one_frame_per_tick_not_blank_and_changing(robot, wave, tmp_path):
    from PIL import Image, ImageSequence

    tr, rec = wave
    res = render(robot, tr, tmp_path / "wave.gif", recording=rec, fps=10, camera=CameraSpec("front"), **SMALL)
    expected = len(frame_times(float(rec.t[-1]), 10.0))
    assert res.kind == "gif" and res.n_frames == expected
    gif = Image.open(res.path)
    frames = [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(gif)]
    assert len(frames) == expected
    for img in frames:
        assert_not_blank(img)
    assert changed_pixels(frames[0], frames[5]) > 100  # arms up at t = 0.5 s
    assert mean_abs_diff(frames[0], frames[5]) > 1.0
    assert gif.info.get("loop") == 0


def test_mp4_output_decodes_to_the_rendered_frame_count(robot, wave, tmp_path):
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    tr, rec = wave
    res = render(robot, tr, tmp_path / "wave.mp4", recording=rec, fps=10, **SMALL)
    reader = imageio_ffmpeg.read_frames(str(res.path))
    meta = next(reader)
    frames = [np.frombuffer(f, np.uint8).reshape(120, 160, 3) for f in reader]
    assert meta["size"] == (160, 120)
    assert len(frames) == res.n_frames == len(frame_times(float(rec.t[-1]), 10.0))
    assert_not_blank(frames[len(frames) // 2])


def test_render_plays_the_trajectory_itself_when_given_no_recording(robot, tmp_path):
    res = render(robot, arm_wave(robot, 0.4), tmp_path / "one.png", key_frames=1, hold_s=0.0, **SMALL)
    assert res.n_frames == 1 and res.duration_s == pytest.approx(0.4, abs=0.01)


def test_unknown_output_suffix_is_refused_with_the_valid_ones(robot, wave, tmp_path):
    tr, rec = wave
    with pytest.raises(RenderError, match=r"use one of \.mp4, \.gif, \.png"):
        render(robot, tr, tmp_path / "x.avi", recording=rec)


def test_unknown_camera_is_refused_with_the_valid_names(robot, wave, tmp_path):
    tr, rec = wave
    with pytest.raises(RenderError, match="unknown camera 'nope'; cameras: follow, front, side, back, top, fixed"):
        render(robot, tr, tmp_path / "x.png", recording=rec, camera=CameraSpec("nope"))


def test_no_opengl_backend_gives_one_clear_error_with_a_hint(robot, wave, monkeypatch):
    import robot_rise.render.gl as gl_module

    def broken(backend: str, width: int, height: int) -> None:
        raise ImportError(f"no {backend} here")

    monkeypatch.setattr(gl_module, "_make_gl_context", broken)
    _, rec = wave
    with pytest.raises(RenderError) as info:
        list(render_frames(robot, rec, [0.0], **SMALL))
    assert str(info.value).startswith("offscreen rendering is impossible here: no OpenGL backend works (egl: no egl here")
    assert "libegl" in info.value.hint


def test_follow_camera_tracks_the_root_and_fixed_camera_stays_still(robot, wave):
    _, rec = wave
    moving = rec.root_pose.copy()
    moving[:, 0] += np.linspace(0.0, 1.0, len(rec.t))  # slide 1 m along x
    rec = dataclasses.replace(rec, root_pose=moving)
    times = np.array([0.0, float(rec.t[-1]) / 2, float(rec.t[-1])])
    follow = camera_track(robot, rec, CameraSpec("follow"), times)["lookat"]
    fixed = camera_track(robot, rec, CameraSpec("fixed"), times)["lookat"]
    assert follow[-1, 0] - follow[0, 0] > 0.6
    assert np.allclose(fixed, fixed[0])
    assert camera_track(robot, rec, CameraSpec("side", distance_m=2.5), times)["distance_m"] == 2.5


def test_frame_times_step_by_speed_over_fps_and_key_frames_span_the_recording(wave):
    _, rec = wave
    assert np.allclose(frame_times(1.0, 10.0), np.arange(11) / 10)
    assert np.allclose(frame_times(1.0, 10.0, speed=2.0), np.arange(6) / 5)
    keys = key_frame_times(rec, 5)
    assert keys[0] == 0.0 and keys[-1] == pytest.approx(rec.t[-1]) and len(keys) == 5
    with pytest.raises(RenderError, match="fps and speed must be > 0"):
        frame_times(1.0, 0.0)


def test_viewer_without_a_display_says_so_and_suggests_render(robot, wave, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    _, rec = wave
    with pytest.raises(RenderError, match="no display") as info:
        view(robot, rec)
    assert "robot-rise render" in info.value.hint


def test_pose_sample_sets_the_root_and_joints_of_that_sample_over_the_rest_pose(robot, wave):
    import mujoco

    from robot_rise.model import compose, model_index

    _, rec = wave
    m = compose(robot, "flat", with_actuators=False)
    d = mujoco.MjData(m)
    index = model_index(m, robot)
    d.qpos[:] = 123.0  # stale values from elsewhere must not survive
    k = len(rec.t) // 3
    pose_sample(m, d, index, rec, k)
    assert np.array_equal(d.qpos[index.qpos_root], rec.root_pose[k])
    assert np.array_equal(d.qpos[index.qpos_joints], rec.q[k])
    rest = np.ones(m.nq, dtype=bool)
    rest[index.qpos_root] = rest[index.qpos_joints] = False
    assert np.array_equal(d.qpos[rest], m.qpos0[rest])


def test_without_imageio_ffmpeg_mp4_is_unavailable_and_refused_with_a_hint(robot, wave, tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # importing it now raises ImportError
    assert not mp4_encoder_available()
    tr, rec = wave
    with pytest.raises(RenderError, match="MP4 output needs imageio-ffmpeg") as info:
        render(robot, tr, tmp_path / "x.mp4", recording=rec, **SMALL)
    assert ".gif" in info.value.hint
    assert not (tmp_path / "x.mp4").exists()
