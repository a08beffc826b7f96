"""The HTML report: self-contained, complete, and its images load in a real headless Chromium."""

from __future__ import annotations

import contextlib
import html
import io
import json
import os
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from robot_rise.cli import main
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.trajectory import Trajectory, write_trajectory

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
# The flags this machine's Chromium needs headless, as root, with no network (see the env notes).
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
)
TRAJECTORY_REPORT = {
    "planner": "test-wave",
    "filter": {"iterations": 3, "peak_torque_ratio": 0.8125, "windows_s": [0.25, 0.75]},
    "timings_s": {"plan": 1.5, "filter": 12.25},
    "candidates": [{"motion": "wave", "distance": 0.4375}],
}


def arm_wave(robot: Robot) -> Trajectory:
    """From the stand keyframe, raise the arms forward and back down in 1 s."""
    names = robot.joint_names
    start = Posture(robot.name, robot.stand_qpos[:3], robot.stand_qpos[3:7], dict(zip(names, robot.stand_qpos[7:])))
    t = np.linspace(0.0, 1.0, 21)
    q = np.tile(robot.stand_qpos[7:], (t.size, 1))
    for name in ("l_sho_pitch", "r_sho_pitch"):
        q[:, names.index(name)] += 1.2 * np.sin(np.pi * t)
    return Trajectory(robot.name, names, t, q, start, report=TRAJECTORY_REPORT)


class _Tags(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))


def tags_of(page: str) -> list[tuple[str, dict[str, str | None]]]:
    parser = _Tags()
    parser.feed(page)
    return parser.tags


@pytest.fixture(scope="module")
def report(robot: Robot, tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, str, int]:
    """The report of a 1 s arm wave, made by the command as a user would: (JSON summary, page, exit code)."""
    out = tmp_path_factory.mktemp("report")
    traj = out / "wave.json"
    write_trajectory(traj, arm_wave(robot))
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = main(["report", str(traj), "--out", str(out / "report"), "--json"])
    summary = json.loads(stdout.getvalue())
    return summary, Path(summary["path"]).read_text(encoding="utf-8"), code


def test_report_command_writes_the_page_and_video_and_exits_by_the_verdict(report):
    summary, _, code = report
    assert code == (0 if summary["proven"] else 1)
    assert Path(summary["path"]).name == "report.html" and Path(summary["path"]).is_file()
    assert summary["video"] is not None and Path(summary["video"]).is_file()
    assert summary["n_images"] == 7  # key frames + 6 plots (the video is a <video>)


def test_report_page_embeds_every_image_and_the_video_and_links_nothing_outside(report):
    summary, page, _ = report
    tags = tags_of(page)
    images = [a for t, a in tags if t == "img"]
    videos = [a for t, a in tags if t == "video"]
    assert len(images) == summary["n_images"]
    assert all((a.get("src") or "").startswith("data:image/png;base64,") for a in images)
    assert all(a.get("alt") for a in images)
    if summary["video"].endswith(".mp4"):
        assert len(videos) == 1 and (videos[0].get("src") or "").startswith("data:video/mp4;base64,")
    for tag, attrs in tags:
        assert tag not in ("script", "link", "iframe"), tag
        for key in ("src", "href"):
            assert not (attrs.get(key) or "").startswith(("http:", "https:", "file:", "//")), (tag, key)


def test_report_shows_the_verdict_and_every_number_of_the_trajectory_report(report):
    summary, page, _ = report
    assert ("PROVEN" if summary["proven"] else "NOT PROVEN") in page
    assert html.escape(summary["judge"]) in page
    for problem in summary["problems"]:
        assert html.escape(problem) in page
    for heading in (
        "Joint targets vs simulated positions",
        "Servo torque vs the torque-speed envelope",
        "ZMP and support polygon while on feet",
        "Contacts over time",
        "The trajectory&#x27;s report",
    ):
        assert heading in page, heading
    for key in ("planner", "iterations", "peak_torque_ratio", "windows_s", "timings_s", "candidates", "distance"):
        assert f"<th>{key}</th>" in page, key
    for number in ("0.8125", "0.25", "0.75", "1.5", "12.25", "0.4375", "test-wave"):
        assert f">{number}<" in page or f"{number}," in page or f", {number}" in page, number
    for key in ("peak_torque_ratio_per_joint", "envelope_limit", "min_zmp_margin_m", "stood_from_s"):  # the check's own numbers
        assert f"<th>{key}</th>" in page, key


def _browser_or_skip():
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not shutil.which(p)]
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        missing.append("selenium (pip)")
    if missing:
        message = f"headless browser test needs {', '.join(missing)} (.ci/system-deps installs Chromium)"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    return webdriver, Service


def test_report_images_and_video_load_in_headless_chromium(report, tmp_path):
    webdriver, Service = _browser_or_skip()
    summary, _, _ = report
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (*CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'chromium-profile'}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        driver.set_page_load_timeout(60)
        driver.get(Path(summary["path"]).resolve().as_uri())  # returns after the load event: images decoded
        images = driver.execute_script(
            "return Array.from(document.images).map(i => ({alt: i.alt, complete: i.complete, w: i.naturalWidth, h: i.naturalHeight}))"
        )
        assert len(images) == summary["n_images"]
        for img in images:
            assert img["complete"] and img["w"] > 100 and img["h"] > 100, img
        if summary["video"].endswith(".mp4"):
            driver.set_script_timeout(30)
            video = driver.execute_async_script(
                "const done = arguments[arguments.length - 1]; const v = document.querySelector('video');"
                "const report = () => done({ready: v.readyState, width: v.videoWidth, duration: v.duration, error: v.error && v.error.code});"
                "if (v.readyState >= 1) report(); else { v.addEventListener('loadedmetadata', report); v.addEventListener('error', report); v.load(); }"
            )
            assert video["error"] is None and video["ready"] >= 1 and video["width"] > 0, video
            assert video["duration"] > 1.0  # 1 s of motion + the 3 s hold
    finally:
        driver.quit()


def test_without_an_mp4_encoder_the_report_embeds_a_gif_instead(robot, tmp_path, monkeypatch):
    import sys

    from robot_rise.report import write_report

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # importing it now raises ImportError
    result = write_report(robot, arm_wave(robot), tmp_path, key_frames=2)
    page = result.path.read_text(encoding="utf-8")
    assert result.video == tmp_path / "video.gif" and result.video.is_file()
    assert 'src="data:image/gif;base64,' in page and "<video" not in page
    assert result.n_images == 8  # the GIF, the key-frame sheet and six plots


def test_sole_polygons_at_the_stand_are_the_two_soles_hull(robot):
    from robot_rise.report.support import sole_polygons
    from robot_rise.sim.player import play

    rec = play(robot, arm_wave(robot), hold_s=0.0)
    (poly,) = sole_polygons(robot, rec, "flat", [0])
    x, y = poly[:, 0], poly[:, 1]
    area_m2 = 0.5 * abs(float(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))
    assert len(poly) >= 4
    assert 0.005 < area_m2 < 0.1  # two small humanoid soles and the gap between them


def test_json_values_become_tables_inline_lists_and_escaped_text():
    from robot_rise.report.page import value_html

    assert value_html({"a": 1.23456789, "b": [True, None, "<x>"]}) == (
        '<table><tr><th>a</th><td class="num">1.23457</td></tr><tr><th>b</th><td>true, null, &lt;x&gt;</td></tr></table>'
    )
    assert value_html([]) == "<i>none</i>" and value_html({}) == "<i>empty</i>"
    assert value_html([{"k": 1}]) == '<ol start=0><li><table><tr><th>k</th><td class="num">1</td></tr></table></li></ol>'
