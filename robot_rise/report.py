"""One self-contained HTML page about a trajectory: the video, plots, the judge's verdict, its numbers.

The trajectory is replayed from its start posture through the servo model and judged with
:func:`robot_rise.filter.prove` (the same check as ``robot-rise check``); this module only draws
what that recording and verdict say. The page embeds everything (images and video as ``data:``
URIs, inline CSS, no script), so it can be mailed or archived as one file.

Sections: verdict and problems; video (MP4, or an animated GIF where imageio-ffmpeg is missing) and
key frames; joint targets vs simulated positions; servo torque against the torque-speed envelope
per joint, the limit and the (1 - margin) line drawn; envelope use over time; ZMP and support
polygon while on feet; torso tilt and height against the judge's bounds; ground contacts over time;
the check's numbers and every entry of the trajectory's own report.

The recording keeps the ZMP and its margin per sample but not the support polygon's vertices, so
the polygon is drawn from the sole geoms' bottom corners within ``SOLE_CONTACT_TOLERANCE_M`` of the
lowest one, at a few samples on the feet.

Plots use matplotlib's object API with the Agg canvas (no pyplot, no global backend change).
"""

from __future__ import annotations

import base64
import html
import io
import logging
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from robot_rise.filter import FilterSettings, prove
from robot_rise.sim.balance import convex_hull_2d
from robot_rise.sim.standing import StandVerdict
from robot_rise.model import SUPPLY_VOLTAGE_V, Robot, compose, model_index
from robot_rise.render import CameraSpec, RenderError, check_camera, contact_sheet, key_frame_times, render, render_frames
from robot_rise.servo import servo_arrays
from robot_rise.sim.player import Recording
from robot_rise.trajectory import Trajectory

__all__ = ["ReportResult", "write_report", "REPORT_FILE", "SOLE_CONTACT_TOLERANCE_M"]

log = logging.getLogger(__name__)

REPORT_FILE = "report.html"
SOLE_CONTACT_TOLERANCE_M = 0.005  # sole corners this close to the lowest one count as on the ground [m]
POLYGON_SAMPLES = 3  # support polygons drawn: first, middle and last sample on the feet
VIDEO_SIZE_PX = (480, 360)  # width, height of the embedded video
VIDEO_FPS = 20.0  # frame rate of the embedded video [1/s]
GIF_SIZE_PX = (320, 240)  # fallback animation without an MP4 encoder
GIF_FPS = 10.0
KEY_FRAME_SIZE_PX = (320, 240)
PLOT_DPI = 90
RATIO_COLOUR_MAX = 1.2  # colour scale top of the envelope-use heat map


@dataclass(frozen=True)
class ReportResult:
    """What :func:`write_report` wrote and found.

    Attributes:
        path: the HTML page.
        video: the video (or GIF) file written beside it, None if none.
        verdict: the standing judge's verdict.
        check: the check's report (``robot_rise.filter.prove``): proven, problems, peaks, ...
        n_images: images embedded in the page.
        size_bytes: size of the page [bytes].
        wall_s: wall-clock time to make it [s].
    """

    path: Path
    video: Path | None
    verdict: StandVerdict
    check: dict[str, Any]
    n_images: int
    size_bytes: int
    wall_s: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly summary."""
        return {
            "path": str(self.path),
            "video": str(self.video) if self.video else None,
            "proven": bool(self.check.get("proven")),
            "standing": self.verdict.standing,
            "judge": self.verdict.summary(),
            "problems": list(self.check.get("problems", [])),
            "n_images": self.n_images,
            "size_bytes": self.size_bytes,
            "wall_s": round(self.wall_s, 2),
        }


# --- plots ---------------------------------------------------------------------------------------


def _figure(width_in: float, height_in: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=PLOT_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _png(fig: Any) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=PLOT_DPI)
    return buf.getvalue()


def _grid(n: int, cols: int = 5) -> tuple[int, int]:
    return math.ceil(n / cols), min(cols, n)


def _mark_end(ax: Any, rec: Recording) -> None:
    ax.axvline(rec.trajectory_end_s, color="0.5", lw=0.8, ls=":")


def _plot_joints(rec: Recording) -> bytes:
    """Servo goal vs simulated position per joint over time [deg]."""
    n = len(rec.joint_names)
    rows, cols = _grid(n)
    fig = _figure(2.6 * cols, 1.7 * rows + 0.4)
    axes = fig.subplots(rows, cols, sharex=True, squeeze=False)
    for j, name in enumerate(rec.joint_names):
        ax = axes.flat[j]
        ax.plot(rec.t, np.degrees(rec.goal[:, j]), color="tab:orange", lw=1.2, ls="--", label="target")
        ax.plot(rec.t, np.degrees(rec.q[:, j]), color="tab:blue", lw=1.0, label="simulated")
        err = float(np.degrees(np.abs(rec.goal[:, j] - rec.q[:, j]).max()))
        ax.set_title(f"{name}  (max err {err:.0f}°)", fontsize=8)
        ax.tick_params(labelsize=7)
        _mark_end(ax, rec)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7, loc="best")
    fig.supxlabel("time [s] (dotted: trajectory end)", fontsize=9)
    fig.supylabel("angle [deg]", fontsize=9)
    return _png(fig)


def _plot_envelope(rec: Recording, stall_nm: np.ndarray, no_load_rad_s: np.ndarray, limit: float) -> bytes:
    """Motor torque against joint speed per joint, inside the servo's torque-speed envelope."""
    n = len(rec.joint_names)
    rows, cols = _grid(n)
    fig = _figure(2.6 * cols, 2.0 * rows + 0.4)
    axes = fig.subplots(rows, cols, squeeze=False)
    for j, name in enumerate(rec.joint_names):
        ax = axes.flat[j]
        w0, ts = float(no_load_rad_s[j]), float(stall_nm[j])
        w = np.linspace(-w0, w0, 50)
        ax.plot(w, ts * (1 - w / w0), color="tab:red", lw=1.2, label="envelope")
        ax.plot(w, -ts * (1 + w / w0), color="tab:red", lw=1.2)
        ax.plot(w, limit * ts * (1 - w / w0), color="tab:red", lw=0.8, ls="--", label=f"{limit:.0%} limit")
        ax.plot(w, -limit * ts * (1 + w / w0), color="tab:red", lw=0.8, ls="--")
        ax.scatter(rec.qd[:, j], rec.torque_nm[:, j], c=rec.t, s=3, cmap="viridis", linewidths=0)
        peak = float(rec.envelope_ratio[:, j].max())
        ax.set_title(f"{name}  (peak {peak:.2f})", fontsize=8, color="tab:red" if peak > limit else "black")
        ax.set_xlim(-1.05 * w0, 1.05 * w0)
        ax.set_ylim(-2.05 * ts, 2.05 * ts)
        ax.tick_params(labelsize=7)
        ax.axhline(0, color="0.8", lw=0.5)
        ax.axvline(0, color="0.8", lw=0.5)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=6, loc="lower left")
    fig.supxlabel("joint speed [rad/s] (dots coloured by time: dark early, yellow late)", fontsize=9)
    fig.supylabel("motor torque [N m]", fontsize=9)
    return _png(fig)


def _plot_ratio(rec: Recording, limit: float) -> bytes:
    """Envelope use per joint over time (heat map) and its maximum with the limit line."""
    fig = _figure(11, 6.5)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[2.2, 1])
    extent = (float(rec.t[0]), float(rec.t[-1]), len(rec.joint_names) - 0.5, -0.5)
    im = top.imshow(rec.envelope_ratio.T, aspect="auto", extent=extent, cmap="magma_r", vmin=0, vmax=RATIO_COLOUR_MAX, interpolation="nearest")
    top.set_yticks(range(len(rec.joint_names)), rec.joint_names, fontsize=7)
    top.set_title("torque / envelope per joint", fontsize=9)
    fig.colorbar(im, ax=top, label="torque / envelope")
    peak = rec.envelope_ratio.max(axis=1)
    bottom.plot(rec.t, peak, color="black", lw=1)
    bottom.axhline(1.0, color="tab:red", lw=1.2, label="envelope (1.0)")
    bottom.axhline(limit, color="tab:red", lw=0.8, ls="--", label=f"limit ({limit:.2f})")
    _mark_end(bottom, rec)
    bottom.set_ylabel("max over joints")
    bottom.set_xlabel("time [s]")
    bottom.set_ylim(0, max(1.2, float(np.nanmax(peak)) * 1.05 if peak.size else 1.2))
    bottom.legend(fontsize=7, loc="upper left")
    return _png(fig)


def _sole_polygons(robot: Robot, rec: Recording, scene: str | os.PathLike[str] | None, samples: list[int]) -> list[np.ndarray]:
    """Support polygon (hull of ground-touching sole box corners) at each sample, shapes (H, 2) [m]."""
    m = compose(robot, scene, with_actuators=False)
    d = mujoco.MjData(m)
    index = model_index(m, robot)
    names = [rec.robot_geom_names[g] for g in rec.foot_geoms]
    geoms = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n) for n in names]
    boxes = [g for g in geoms if g >= 0 and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX]
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    polygons = []
    for k in samples:
        d.qpos[:] = m.qpos0
        d.qpos[index.qpos_root] = rec.root_pose[k]
        d.qpos[index.qpos_joints] = rec.q[k]
        mujoco.mj_kinematics(m, d)
        corners = [d.geom_xpos[g] + (signs * m.geom_size[g]) @ d.geom_xmat[g].reshape(3, 3).T for g in boxes]
        if not corners:
            polygons.append(np.zeros((0, 2)))
            continue
        pts = np.concatenate(corners)
        low = pts[pts[:, 2] <= pts[:, 2].min() + SOLE_CONTACT_TOLERANCE_M]
        polygons.append(convex_hull_2d(low[:, :2]))
    return polygons


def _plot_balance(robot: Robot, rec: Recording, scene: str | os.PathLike[str] | None) -> bytes:
    """Top view of the ZMP and support polygons while on feet; the ZMP margin over time."""
    fig = _figure(11, 4.6)
    left, right = fig.subplots(1, 2, width_ratios=[1, 1.6])
    on = rec.on_feet & np.all(np.isfinite(rec.zmp), axis=1)
    idx = np.flatnonzero(on)
    if idx.size:
        picks = sorted({int(idx[0]), int(idx[idx.size // 2]), int(idx[-1])})[:POLYGON_SAMPLES]
        shades = np.linspace(0.75, 0.35, len(picks))
        for k, poly, shade in zip(picks, _sole_polygons(robot, rec, scene, picks), shades):
            if len(poly) >= 3:
                closed = np.vstack([poly, poly[:1]])
                left.fill(closed[:, 0], closed[:, 1], color=str(shade), alpha=0.35)
                left.plot(closed[:, 0], closed[:, 1], color=str(shade), lw=1, label=f"support polygon t = {rec.t[k]:.2f} s")
        sc = left.scatter(rec.zmp[idx, 0], rec.zmp[idx, 1], c=rec.t[idx], s=5, cmap="viridis", label="ZMP")
        fig.colorbar(sc, ax=left, label="time [s]")
        left.scatter(rec.com[idx, 0], rec.com[idx, 1], s=2, color="tab:red", alpha=0.4, label="CoM (ground projection)")
        left.set_aspect("equal", adjustable="datalim")
        left.legend(fontsize=6, loc="best")
    else:
        left.text(0.5, 0.5, "never only on the feet", ha="center", va="center", transform=left.transAxes)
    left.set_title("ZMP and support polygon while on feet (top view)", fontsize=9)
    left.set_xlabel("x [m]")
    left.set_ylabel("y [m]")
    margin_mm = np.where(on, rec.zmp_margin_m * 1000.0, np.nan)
    right.plot(rec.t, margin_mm, color="tab:blue", lw=1)
    right.axhline(0, color="tab:red", lw=1, label="polygon edge")
    _mark_end(right, rec)
    right.set_title("ZMP margin inside the support polygon (gaps: not only on feet)", fontsize=9)
    right.set_xlabel("time [s]")
    right.set_ylabel("margin [mm] (negative: outside)")
    right.set_xlim(float(rec.t[0]), float(rec.t[-1]))
    right.legend(fontsize=7)
    return _png(fig)


def _plot_judge(rec: Recording, verdict: StandVerdict) -> bytes:
    """Torso tilt and height over time against the standing judge's bounds."""
    from robot_rise.constants import STAND_MAX_TILT_RAD, STAND_MIN_HEIGHT_FRACTION

    fig = _figure(11, 3.6)
    a, b = fig.subplots(1, 2)
    a.plot(rec.t, np.degrees(rec.tilt_rad), color="tab:blue", lw=1)
    a.axhline(math.degrees(STAND_MAX_TILT_RAD), color="tab:red", ls="--", lw=1, label=f"bound {math.degrees(STAND_MAX_TILT_RAD):.0f}°")
    a.set_title("torso tilt from vertical", fontsize=9)
    a.set_ylabel("tilt [deg]")
    b.plot(rec.t, 100 * rec.torso_height_m / rec.stand_height_m, color="tab:blue", lw=1)
    b.axhline(100 * STAND_MIN_HEIGHT_FRACTION, color="tab:red", ls="--", lw=1, label=f"bound {STAND_MIN_HEIGHT_FRACTION:.0%}")
    b.set_title("torso height above the soles", fontsize=9)
    b.set_ylabel("% of the stand keyframe")
    for ax in (a, b):
        _mark_end(ax, rec)
        if math.isfinite(verdict.stood_from_s):
            ax.axvspan(verdict.stood_from_s, float(rec.t[-1]), color="tab:green", alpha=0.12, label="standing (judge)")
        ax.set_xlabel("time [s]")
        ax.legend(fontsize=7, loc="best")
    return _png(fig)


def _plot_contacts(rec: Recording) -> bytes:
    """Which robot geoms touch the ground over time, plus self and obstacle contact."""
    touched = np.flatnonzero(rec.ground_contact.any(axis=0))
    rows = [rec.robot_geom_names[g] for g in touched] + ["on feet only", "self contact", "obstacle contact"]
    data = np.vstack([rec.ground_contact[:, touched].T, rec.on_feet[None], rec.self_contact[None], rec.obstacle_contact[None]]).astype(float)
    fig = _figure(11, 0.9 + 0.22 * len(rows))
    ax = fig.subplots()
    extent = (float(rec.t[0]), float(rec.t[-1]), len(rows) - 0.5, -0.5)
    ax.imshow(data, aspect="auto", extent=extent, cmap="Greys", vmin=0, vmax=1.3, interpolation="nearest")
    ax.set_yticks(range(len(rows)), rows, fontsize=7)
    ax.axhline(len(touched) - 0.5, color="tab:blue", lw=0.8)
    _mark_end(ax, rec)
    ax.set_xlabel("time [s] (dark: in contact)")
    ax.set_title("contacts over time", fontsize=9)
    return _png(fig)


# --- HTML ----------------------------------------------------------------------------------------

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; padding: 0 1em; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; } h2 { font-size: 1.15em; margin-top: 1.8em; border-bottom: 1px solid #ccc; }
.verdict { padding: 0.8em 1em; border-radius: 6px; font-size: 1.1em; }
.ok { background: #e3f4e1; border: 1px solid #7bbf73; } .bad { background: #fbe4e1; border: 1px solid #d98277; }
img, video { max-width: 100%; height: auto; display: block; margin: 0.5em 0; }
table { border-collapse: collapse; font-size: 0.9em; margin: 0.4em 0; }
td, th { border: 1px solid #ddd; padding: 2px 8px; text-align: left; vertical-align: top; }
th { background: #f4f4f4; font-weight: 600; } td.num { font-family: ui-monospace, monospace; }
.note { color: #666; font-size: 0.85em; }
"""


def _data_uri(mime: str, payload: bytes) -> str:
    return f"data:{mime};base64,{base64.b64encode(payload).decode('ascii')}"


def _img(payload: bytes, alt: str, mime: str = "image/png") -> str:
    return f'<img src="{_data_uri(mime, payload)}" alt="{html.escape(alt)}">'


def _fmt(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return html.escape(str(value).lower() if isinstance(value, bool) else "null")
    if isinstance(value, float):
        return html.escape(f"{value:.6g}")
    return html.escape(str(value))


def _value_html(value: Any) -> str:
    """Any JSON value as HTML: objects as tables, lists of scalars inline, the rest recursively."""
    if isinstance(value, dict):
        if not value:
            return "<i>empty</i>"
        rows = "".join(f"<tr><th>{html.escape(str(k))}</th>{_cell(v)}</tr>" for k, v in value.items())
        return f"<table>{rows}</table>"
    if isinstance(value, (list, tuple)):
        if all(not isinstance(v, (dict, list, tuple)) for v in value):
            return ", ".join(_fmt(v) for v in value) if value else "<i>none</i>"
        return "<ol start=0>" + "".join(f"<li>{_value_html(v)}</li>" for v in value) + "</ol>"
    return _fmt(value)


def _cell(value: Any) -> str:
    numeric = isinstance(value, (int, float)) and not isinstance(value, bool)
    return f'<td class="num">{_value_html(value)}</td>' if numeric else f"<td>{_value_html(value)}</td>"


def _page(title: str, sections: list[tuple[str, str]], head: str) -> str:
    body = "".join(f"<h2>{html.escape(name)}</h2>\n{content}\n" for name, content in sections)
    return (
        "<!DOCTYPE html>\n<html lang=en>\n<head>\n<meta charset=utf-8>\n"
        f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
        f"<h1>{html.escape(title)}</h1>\n{head}\n{body}</body>\n</html>\n"
    )


def _encoder_available() -> bool:
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        return False
    return True


def write_report(
    robot: Robot,
    trajectory: Trajectory,
    out_dir: str | os.PathLike[str],
    *,
    scene: str | os.PathLike[str] | None = "flat",
    name: str = "",
    camera: CameraSpec = CameraSpec(),
    video: bool = True,
    key_frames: int = 8,
    settings: FilterSettings = FilterSettings(),
    progress: Callable[[int, int], None] | None = None,
) -> ReportResult:
    """Replay, judge and draw ``trajectory``; write ``out_dir/report.html`` (and the video beside it).

    Args:
        robot: the robot.
        trajectory: the trajectory, played from its start posture.
        out_dir: output directory (created).
        scene: scene name or MJCF path.
        name: what to call the trajectory on the page (e.g. its file name).
        camera: camera of the video and key frames.
        video: embed a video (MP4, or a GIF without imageio-ffmpeg); False for key frames only.
        key_frames: number of key frames in the contact sheet.
        settings: the check's settings (envelope margin, hold time).
        progress: called with (frames done, frames total) while rendering.

    Returns:
        the :class:`ReportResult`.

    Raises:
        RenderError: rendering is impossible here.
        RobotRiseError: the trajectory does not fit the robot.
    """
    t0 = time.perf_counter()
    check_camera(robot, scene, camera)  # fail before the replay, not after
    if key_frames < 1:
        raise RenderError(f"need at least one key frame, got {key_frames}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    title_name = name or "trajectory"
    rec, verdict, check = prove(robot, trajectory, scene=scene, settings=settings)
    limit = float(check.get("envelope_limit", 1.0 - settings.envelope_margin))
    images = 0
    sections: list[tuple[str, str]] = []

    # video and key frames
    media: list[str] = []
    video_path: Path | None = None
    if video:
        if _encoder_available():
            video_path = out / "video.mp4"
            vw, vh = VIDEO_SIZE_PX
            res = render(
                robot, trajectory, video_path, scene=scene, recording=rec, camera=camera, width=vw, height=vh, fps=VIDEO_FPS, progress=progress
            )
            media.append(
                f'<video controls loop muted playsinline width="{vw}" height="{vh}" src="{_data_uri("video/mp4", video_path.read_bytes())}"></video>'
                f'<p class="note">{res.n_frames} frames at {res.fps:.0f} fps, real time; also saved as {html.escape(video_path.name)}.</p>'
            )
        else:
            video_path = out / "video.gif"
            gw, gh = GIF_SIZE_PX
            res = render(
                robot, trajectory, video_path, scene=scene, recording=rec, camera=camera, width=gw, height=gh, fps=GIF_FPS, progress=progress
            )
            media.append(_img(video_path.read_bytes(), "animation of the replay", "image/gif"))
            media.append('<p class="note">Animated GIF: install imageio-ffmpeg for an MP4 video.</p>')
            images += 1
    times = key_frame_times(rec, key_frames)
    kw, kh = KEY_FRAME_SIZE_PX
    frames = list(render_frames(robot, rec, times, scene=scene, camera=camera, width=kw, height=kh, shadows=True, label=False))
    sheet = contact_sheet(frames, [f"t = {t:.2f} s" for t in times])
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(sheet).save(buf, format="PNG")
    media.append(_img(buf.getvalue(), "key frames of the replay"))
    images += 1
    sections.append(("Replay", "".join(media)))

    servos = servo_arrays(robot.servo_specs(), SUPPLY_VOLTAGE_V)
    plots = [
        ("Joint targets vs simulated positions", _plot_joints(rec), "joint targets and simulated positions"),
        (
            "Servo torque vs the torque-speed envelope",
            _plot_envelope(rec, servos.stall_torque_nm, servos.no_load_speed_rad_s, limit),
            "motor torque against joint speed inside the envelope",
        ),
        ("Envelope use over time", _plot_ratio(rec, limit), "torque over envelope per joint over time"),
        ("ZMP and support polygon while on feet", _plot_balance(robot, rec, scene), "ZMP and support polygon"),
        ("Torso tilt and height (the judge's bounds)", _plot_judge(rec, verdict), "torso tilt and height"),
        ("Contacts over time", _plot_contacts(rec), "ground contacts over time"),
    ]
    for heading, payload, alt in plots:
        sections.append((heading, _img(payload, alt)))
        images += 1
    sections.append(("Check (replayed through the servo model)", _value_html(check)))
    sections.append(("The trajectory's report", _value_html(trajectory.report) if trajectory.report else "<p><i>the file has no report</i></p>"))
    facts = {
        "robot": trajectory.robot,
        "joints": len(trajectory.joint_names),
        "rows": len(trajectory.t),
        "duration_s": trajectory.duration_s,
        "hold_s": float(rec.t[-1] - trajectory.duration_s) if len(rec.t) else 0.0,
        "scene": str(scene),
        "recording_hz": float(1.0 / (rec.t[1] - rec.t[0])) if len(rec.t) > 1 else None,
        "play_wall_s": rec.wall_time_s,
    }
    sections.append(("Trajectory", _value_html(facts)))

    ok = bool(check.get("proven"))
    problems = "".join(f"<li>{html.escape(p)}</li>" for p in check.get("problems", []))
    head = (
        f'<div class="verdict {"ok" if ok else "bad"}"><b>{"PROVEN" if ok else "NOT PROVEN"}</b> in scene '
        f"{html.escape(str(scene))} — {html.escape(verdict.summary())}" + (f"<ul>{problems}</ul>" if problems else "") + "</div>"
    )
    page = _page(f"{robot.name}: {title_name}", sections, head)
    path = out / REPORT_FILE
    tmp = path.with_suffix(".html.tmp")
    tmp.write_text(page, encoding="utf-8")
    os.replace(tmp, path)
    wall = time.perf_counter() - t0
    log.info("wrote %s (%d images, %.1f MB) in %.1f s", path, images, path.stat().st_size / 1e6, wall)
    return ReportResult(path=path, video=video_path, verdict=verdict, check=check, n_images=images, size_bytes=path.stat().st_size, wall_s=wall)
