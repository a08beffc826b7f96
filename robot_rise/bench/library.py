"""Benchmarks of the motion library: per-motion play figures and tree vs brute-force selection.

Run with ``robot-rise library bench`` (prints a Markdown section for BENCHMARKS.md).
"""

from __future__ import annotations

import logging
import math
import platform
import time
from collections import Counter
from dataclasses import dataclass

import numpy as np

from robot_rise.sim.standing import judge
from robot_rise.library import FrameIndex, KMeansTree, MotionLibrary
from robot_rise.model import Robot
from robot_rise.posture import quat_multiply

__all__ = ["MotionFigures", "SelectionBench", "LibraryBench", "random_lying_postures", "bench_motions", "bench_selection"]

log = logging.getLogger(__name__)

LYING_TILT_NOISE_RAD = math.radians(20.0)  # random lying postures: roll/pitch noise about the lying orientation (ours)


@dataclass(frozen=True)
class MotionFigures:
    """Figures of one motion played nominally on flat ground (and the corner peak).

    Attributes:
        duration_s: the trajectory's duration (its last goal row) [s].
        stood_from_s: when the final stretch of standing (the judge's) begins, nominal [s].
        peak_envelope_ratio: peak torque / envelope, nominal.
        peak_envelope_ratio_corners: the worst peak over the four friction/mass corners of issue 4.
        min_zmp_margin_m: smallest ZMP margin while only the feet touch the ground [m].
        play_wall_s: wall time of the nominal play [s].
    """

    name: str
    duration_s: float
    standing: bool
    peak_envelope_ratio: float
    min_zmp_margin_m: float
    play_wall_s: float
    stood_from_s: float = float("nan")
    peak_envelope_ratio_corners: float = float("nan")


@dataclass(frozen=True)
class SelectionBench:
    """Tree vs brute-force connecting-posture selection over random lying postures."""

    n_queries: int
    n_frames: int
    branching: int
    leaf_size: int
    depth: int
    agreement: float
    worst_distance_ratio: float
    brute_us_per_query: float
    tree_us_per_query: float
    mean_evaluations: float
    build_s: float
    nearest_motion_counts: tuple[tuple[str, int], ...] = ()  # (motion, how many queries' brute-force nearest frame is in it), most first


@dataclass(frozen=True)
class LibraryBench:
    motions: tuple[MotionFigures, ...]
    selection: SelectionBench | None

    @property
    def agreement(self) -> float:
        return self.selection.agreement if self.selection else float("nan")

    def markdown(self) -> str:
        out = [f"Machine: {platform.machine()}, Python {platform.python_version()}, single thread.", ""]
        if self.motions:
            out += [
                "| motion | duration [s] | standing from [s] | stands | peak torque / envelope | worst corner peak | min ZMP margin on feet [mm] | play time [s] |",
                "| --- | ---: | ---: | :---: | ---: | ---: | ---: | ---: |",
            ]
            for m in self.motions:
                out.append(
                    f"| {m.name} | {m.duration_s:.2f} | {m.stood_from_s:.2f} | {'yes' if m.standing else 'NO'} | {m.peak_envelope_ratio:.2f} | "
                    f"{m.peak_envelope_ratio_corners:.2f} | {1000 * m.min_zmp_margin_m:.1f} | {m.play_wall_s:.2f} |"
                )
            out.append("")
        s = self.selection
        if s:
            out += [
                f"Connecting-posture selection over {s.n_frames} indexed frames, {s.n_queries} random lying postures:",
                "",
                "| method | time per query [us] | agreement with brute force | worst distance ratio | mean distance evaluations |",
                "| --- | ---: | ---: | ---: | ---: |",
                f"| brute force (vectorised) | {s.brute_us_per_query:.1f} | 100 % | 1.000 | {s.n_frames} |",
                f"| K-means tree (N={s.branching}, leaf <= {s.leaf_size}, depth {s.depth}) | {s.tree_us_per_query:.1f} | "
                f"{100 * s.agreement:.1f} % | {s.worst_distance_ratio:.3f} | {s.mean_evaluations:.0f} |",
                "",
                f"Tree build: {s.build_s * 1000:.0f} ms.",
            ]
            if s.nearest_motion_counts:
                out += ["", "Nearest motion (brute force) of the random lying postures: " + ", ".join(f"{m} {k}" for m, k in s.nearest_motion_counts) + "."]
        return "\n".join(out)


def random_lying_postures(robot: Robot, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Random lying postures for selection benchmarks (not physically settled).

    Orientation: supine, prone, left or right side with a uniform yaw and up to 20 deg of roll and
    pitch noise; joints uniform within the middle 80 % of each range.

    Returns:
        (quats (n, 4) w x y z, joints (n, n_joints) [rad]).
    """
    from robot_rise.authoring import quat_lying

    rng = np.random.default_rng(seed)
    kinds = ("supine", "prone", "left", "right")
    quats = np.zeros((n, 4))
    for i in range(n):
        base = quat_lying(kinds[rng.integers(4)], float(rng.uniform(-math.pi, math.pi)))
        axis = np.array([*rng.normal(size=2), 0.0])
        axis /= np.linalg.norm(axis)
        ang = rng.uniform(0, LYING_TILT_NOISE_RAD)
        noise = np.array([math.cos(ang / 2), *(math.sin(ang / 2) * axis)])
        quats[i] = quat_multiply(noise, base)
    lo, hi = robot.joint_lower, robot.joint_upper
    mid, half = (lo + hi) / 2, (hi - lo) / 2 * 0.8
    joints = rng.uniform(mid - half, mid + half, size=(n, robot.n_joints))
    return quats, joints


def bench_motions(robot: Robot, library: MotionLibrary) -> tuple[MotionFigures, ...]:
    """Play every motion nominally on flat ground (and at the four friction/mass corners, for the
    worst peak) and collect its figures."""
    from robot_rise.authoring import robustness_players

    player, *corners = robustness_players(robot)
    out = []
    for m in library.motions:
        rec = player.play(m.trajectory, m.start)
        v = judge(rec)
        corner_peak = max(judge(c.play(m.trajectory, m.start)).peak_envelope_ratio for c in corners)
        out.append(
            MotionFigures(
                m.name, m.duration_s, v.standing, v.peak_envelope_ratio, v.min_zmp_margin_m, rec.wall_time_s,
                stood_from_s=v.stood_from_s, peak_envelope_ratio_corners=corner_peak,
            )
        )
    return tuple(out)


def _selection(robot: Robot, library: MotionLibrary, n: int, seed: int) -> SelectionBench:
    index = FrameIndex.build(library, robot)
    tree = KMeansTree(index, seed=seed)
    quats, joints = random_lying_postures(robot, n, seed)
    t0 = time.perf_counter()
    brute = [index.brute_force(q, j) for q, j in zip(quats, joints)]
    t_brute = time.perf_counter() - t0
    t0 = time.perf_counter()
    fast = [tree.query(q, j) for q, j in zip(quats, joints)]
    t_tree = time.perf_counter() - t0
    same = sum(1 for a, b in zip(brute, fast) if (a.motion, a.frame) == (b.motion, b.frame) or abs(a.distance - b.distance) <= 1e-12)
    ratio = max(b.distance / a.distance for a, b in zip(brute, fast))
    return SelectionBench(
        n_queries=n,
        n_frames=index.size,
        branching=tree.branching,
        leaf_size=tree.leaf_size,
        depth=tree.depth(),
        agreement=same / n,
        worst_distance_ratio=float(ratio),
        brute_us_per_query=1e6 * t_brute / n,
        tree_us_per_query=1e6 * t_tree / n,
        mean_evaluations=float(np.mean([c.evaluations for c in fast])),
        build_s=tree.build_time_s,
        nearest_motion_counts=tuple(Counter(a.motion for a in brute).most_common()),
    )


def bench_selection(robot: Robot, library: MotionLibrary, *, n: int = 1000, seed: int = 0, motions: bool = True) -> LibraryBench:
    """Both benchmarks (motions optional)."""
    figs = bench_motions(robot, library) if motions else ()
    return LibraryBench(figs, _selection(robot, library, n, seed))
