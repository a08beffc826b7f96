"""Writing the report: replay and judge a trajectory, then put the replay, plots and numbers on one page.

The trajectory is replayed from its start posture through the servo model and judged with
:func:`robot_rise.filter.prove` (the same check as ``robot-rise check``); the page only draws what
that recording and verdict say.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_rise.proof import ProofConfig
from robot_rise.proof import Proof, prove
from robot_rise.model import Robot
from robot_rise.render import CameraSpec, RenderError, check_camera
from robot_rise.report.media import replay_media
from robot_rise.report.page import img_html, page_html, value_html, verdict_html
from robot_rise.report.plots import plot_contacts, plot_envelope, plot_joints, plot_judge, plot_ratio
from robot_rise.report.support import plot_balance
from robot_rise.servo import servo_arrays
from robot_rise.sim.standing import StandVerdict
from robot_rise.trajectory import Trajectory

__all__ = ["REPORT_FILE", "ReportResult", "write_report"]

log = logging.getLogger(__name__)

REPORT_FILE = "report.html"


@dataclass(frozen=True)
class ReportResult:
    """What :func:`write_report` wrote and found.

    Attributes:
        path: the HTML page.
        video: the video (or GIF) file written beside it, None if none.
        verdict: the standing judge's verdict.
        proof: the check's proof (``robot_rise.filter.prove``): proven, problems, peaks, ...
        n_images: images embedded in the page.
        size_bytes: size of the page [bytes].
        wall_s: wall-clock time to make it [s].
    """

    path: Path
    video: Path | None
    verdict: StandVerdict
    proof: Proof
    n_images: int
    size_bytes: int
    wall_s: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly summary."""
        return {
            "path": str(self.path),
            "video": str(self.video) if self.video else None,
            "proven": self.proof.proven,
            "standing": self.verdict.standing,
            "judge": self.verdict.summary(),
            "problems": list(self.proof.problems),
            "n_images": self.n_images,
            "size_bytes": self.size_bytes,
            "wall_s": round(self.wall_s, 2),
        }


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
    proof_config: ProofConfig = ProofConfig(),
    progress: Callable[[int, int], None] | None = None,
    stage: Callable[[str], None] | None = None,
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
        proof_config: the check's standard (envelope margin, hold time).
        progress: called with (frames done, frames total) while rendering (video, then key frames).
        stage: called with a short description at the start of each stage (replay, video, key
            frames, plots, page).

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
    say = stage or (lambda text: None)
    say(f"replaying {trajectory.duration_s:.2f} s through the servo model and judging it")
    rec, verdict, proof = prove(robot, trajectory, scene=scene, config=proof_config)
    limit = proof.envelope_limit

    media = replay_media(robot, trajectory, rec, out, scene=scene, camera=camera, video=video, key_frames=key_frames, progress=progress,
                         stage=stage)
    images = media.n_images
    sections: list[tuple[str, str]] = [("Replay", media.html)]

    say("drawing the plots")
    servos = servo_arrays(robot.servo_datasheets(), robot.supply_voltage_v)
    plots = [
        ("Joint targets vs simulated positions", plot_joints(rec), "joint targets and simulated positions"),
        (
            "Servo torque vs the torque-speed envelope",
            plot_envelope(rec, servos.stall_torque_nm, servos.no_load_speed_rad_s, limit),
            "motor torque against joint speed inside the envelope",
        ),
        ("Envelope use over time", plot_ratio(rec, limit), "torque over envelope per joint over time"),
        ("ZMP and support polygon while on feet", plot_balance(robot, rec, scene), "ZMP and support polygon"),
        ("Torso tilt and height (the judge's bounds)", plot_judge(rec, verdict), "torso tilt and height"),
        ("Contacts over time", plot_contacts(rec), "ground contacts over time"),
    ]
    for heading, payload, alt in plots:
        sections.append((heading, img_html(payload, alt)))
        images += 1
    sections.append(("Check (replayed through the servo model)", value_html(proof.to_dict())))
    sections.append(("The trajectory's report", value_html(trajectory.report) if trajectory.report else "<p><i>the file has no report</i></p>"))
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
    sections.append(("Trajectory", value_html(facts)))

    say(f"writing {REPORT_FILE}")
    head = verdict_html(proof.proven, str(scene), verdict.summary(), proof.problems)
    page = page_html(f"{robot.name}: {title_name}", sections, head)
    path = out / REPORT_FILE
    tmp = path.with_suffix(".html.tmp")
    tmp.write_text(page, encoding="utf-8")
    os.replace(tmp, path)
    wall = time.perf_counter() - t0
    log.info("wrote %s (%d images, %.1f MB) in %.1f s", path, images, path.stat().st_size / 1e6, wall)
    return ReportResult(path=path, video=media.video, verdict=verdict, proof=proof, n_images=images, size_bytes=path.stat().st_size, wall_s=wall)
