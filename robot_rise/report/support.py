"""The balance plot: the ZMP against the support polygon while on the feet, and the ZMP margin over time.

The recording keeps the ZMP and its margin per sample but not the support polygon's vertices, so
the polygon is drawn from the sole geoms' bottom corners within ``SOLE_CONTACT_TOLERANCE_M`` of the
lowest one, at a few samples on the feet (the robot posed there, kinematics only).
"""

from __future__ import annotations

import os

import mujoco
import numpy as np

from robot_rise.model import Robot, compose, model_index
from robot_rise.render import pose_sample
from robot_rise.report.figures import mark_trajectory_end, new_figure, png_bytes
from robot_rise.sim.balance import convex_hull_2d
from robot_rise.sim.player import Recording

__all__ = ["SOLE_CONTACT_TOLERANCE_M", "POLYGON_SAMPLES", "sole_polygons", "plot_balance"]

SOLE_CONTACT_TOLERANCE_M = 0.005  # sole corners this close to the lowest one count as on the ground [m]
POLYGON_SAMPLES = 3  # support polygons drawn: first, middle and last sample on the feet


def sole_polygons(robot: Robot, rec: Recording, scene: str | os.PathLike[str] | None, samples: list[int]) -> list[np.ndarray]:
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
        pose_sample(m, d, index, rec, k)
        mujoco.mj_kinematics(m, d)
        corners = [d.geom_xpos[g] + (signs * m.geom_size[g]) @ d.geom_xmat[g].reshape(3, 3).T for g in boxes]
        if not corners:
            polygons.append(np.zeros((0, 2)))
            continue
        pts = np.concatenate(corners)
        low = pts[pts[:, 2] <= pts[:, 2].min() + SOLE_CONTACT_TOLERANCE_M]
        polygons.append(convex_hull_2d(low[:, :2]))
    return polygons


def plot_balance(robot: Robot, rec: Recording, scene: str | os.PathLike[str] | None) -> bytes:
    """Top view of the ZMP and support polygons while on feet; the ZMP margin over time (PNG bytes)."""
    fig = new_figure(11, 4.6)
    left, right = fig.subplots(1, 2, width_ratios=[1, 1.6])
    on = rec.on_feet & np.all(np.isfinite(rec.zmp), axis=1)
    idx = np.flatnonzero(on)
    if idx.size:
        picks = sorted({int(idx[0]), int(idx[idx.size // 2]), int(idx[-1])})[:POLYGON_SAMPLES]
        shades = np.linspace(0.75, 0.35, len(picks))
        for k, poly, shade in zip(picks, sole_polygons(robot, rec, scene, picks), shades):
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
    mark_trajectory_end(right, rec)
    right.set_title("ZMP margin inside the support polygon (gaps: not only on feet)", fontsize=9)
    right.set_xlabel("time [s]")
    right.set_ylabel("margin [mm] (negative: outside)")
    right.set_xlim(float(rec.t[0]), float(rec.t[-1]))
    right.legend(fontsize=7)
    return png_bytes(fig)
