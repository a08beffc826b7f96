"""The recording's plots as PNG bytes: joint tracking, the torque-speed envelope, envelope use, the judge's bounds, contacts.

Each function draws what the recording (and the check's verdict) already holds; nothing is computed
beyond unit conversions and maxima. The balance plot, which needs the model, is in
:mod:`robot_rise.report.support`.
"""

from __future__ import annotations

import math

import numpy as np

from robot_rise.report.figures import grid_shape, mark_trajectory_end, new_figure, png_bytes
from robot_rise.sim.player import Recording
from robot_rise.sim.standing import StandVerdict

__all__ = ["RATIO_COLOUR_MAX", "plot_joints", "plot_envelope", "plot_ratio", "plot_judge", "plot_contacts"]

RATIO_COLOUR_MAX = 1.2  # colour scale top of the envelope-use heat map


def plot_joints(rec: Recording) -> bytes:
    """Servo goal vs simulated position per joint over time [deg]."""
    n = len(rec.joint_names)
    rows, cols = grid_shape(n)
    fig = new_figure(2.6 * cols, 1.7 * rows + 0.4)
    axes = fig.subplots(rows, cols, sharex=True, squeeze=False)
    for j, name in enumerate(rec.joint_names):
        ax = axes.flat[j]
        ax.plot(rec.t, np.degrees(rec.goal[:, j]), color="tab:orange", lw=1.2, ls="--", label="target")
        ax.plot(rec.t, np.degrees(rec.q[:, j]), color="tab:blue", lw=1.0, label="simulated")
        err = float(np.degrees(np.abs(rec.goal[:, j] - rec.q[:, j]).max()))
        ax.set_title(f"{name}  (max err {err:.0f}°)", fontsize=8)
        ax.tick_params(labelsize=7)
        mark_trajectory_end(ax, rec)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7, loc="best")
    fig.supxlabel("time [s] (dotted: trajectory end)", fontsize=9)
    fig.supylabel("angle [deg]", fontsize=9)
    return png_bytes(fig)


def plot_envelope(rec: Recording, stall_nm: np.ndarray, no_load_rad_s: np.ndarray, limit: float) -> bytes:
    """Motor torque against joint speed per joint, inside the servo's torque-speed envelope.

    Args:
        rec: the recording.
        stall_nm: stall torque per joint [N m], shape (n,).
        no_load_rad_s: no-load speed per joint [rad/s], shape (n,).
        limit: the allowed fraction of the envelope (1 - margin), drawn dashed.
    """
    n = len(rec.joint_names)
    rows, cols = grid_shape(n)
    fig = new_figure(2.6 * cols, 2.0 * rows + 0.4)
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
    return png_bytes(fig)


def plot_ratio(rec: Recording, limit: float) -> bytes:
    """Envelope use per joint over time (heat map) and its maximum with the limit line."""
    fig = new_figure(11, 6.5)
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
    mark_trajectory_end(bottom, rec)
    bottom.set_ylabel("max over joints")
    bottom.set_xlabel("time [s]")
    bottom.set_ylim(0, max(1.2, float(np.nanmax(peak)) * 1.05 if peak.size else 1.2))
    bottom.legend(fontsize=7, loc="upper left")
    return png_bytes(fig)


def plot_judge(rec: Recording, verdict: StandVerdict) -> bytes:
    """Torso tilt and height over time against the standing judge's bounds."""
    from robot_rise.constants import STAND_MAX_TILT_RAD, STAND_MIN_HEIGHT_FRACTION

    fig = new_figure(11, 3.6)
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
        mark_trajectory_end(ax, rec)
        if math.isfinite(verdict.stood_from_s):
            ax.axvspan(verdict.stood_from_s, float(rec.t[-1]), color="tab:green", alpha=0.12, label="standing (judge)")
        ax.set_xlabel("time [s]")
        ax.legend(fontsize=7, loc="best")
    return png_bytes(fig)


def plot_contacts(rec: Recording) -> bytes:
    """Which robot geoms touch the ground over time, plus self and obstacle contact."""
    touched = np.flatnonzero(rec.ground_contact.any(axis=0))
    rows = [rec.robot_geom_names[g] for g in touched] + ["on feet only", "self contact", "obstacle contact"]
    data = np.vstack([rec.ground_contact[:, touched].T, rec.on_feet[None], rec.self_contact[None], rec.obstacle_contact[None]]).astype(float)
    fig = new_figure(11, 0.9 + 0.22 * len(rows))
    ax = fig.subplots()
    extent = (float(rec.t[0]), float(rec.t[-1]), len(rows) - 0.5, -0.5)
    ax.imshow(data, aspect="auto", extent=extent, cmap="Greys", vmin=0, vmax=1.3, interpolation="nearest")
    ax.set_yticks(range(len(rows)), rows, fontsize=7)
    ax.axhline(len(touched) - 0.5, color="tab:blue", lw=0.8)
    mark_trajectory_end(ax, rec)
    ax.set_xlabel("time [s] (dark: in contact)")
    ax.set_title("contacts over time", fontsize=9)
    return png_bytes(fig)
