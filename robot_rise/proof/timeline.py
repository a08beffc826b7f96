"""When things happen in a rise: the segment a time falls in, and the stretches on the feet alone.

A rise trajectory is a planned path, a blend, then the library motion (``report["plan_rows"]``
rows of plan, the plan's rows before an overlapped join's motion; ``motion`` and
``connecting_frame`` name the rest), then the judge's final hold.
"On its feet" is the judge's condition: only the feet touch the world.
"""

from __future__ import annotations

from robot_rise.proof.violations import true_runs
from robot_rise.sim.player import Recording
from robot_rise.sim.standing import supported_on_feet
from robot_rise.trajectory import Trajectory

__all__ = ["ON_FEET_MIN_S", "segment_at", "feet_stretches", "feet_from"]

ON_FEET_MIN_S = 0.2  # "on its feet": only the feet touch the ground for at least this long [s] (ours)


def segment_at(trajectory: Trajectory, t_s: float) -> str:
    """Which part of a rise trajectory ``t_s`` falls in: the planned path or the library motion."""
    rep = trajectory.report
    rows = rep.get("plan_rows")
    if not isinstance(rows, int) or not 0 < rows < len(trajectory.t):
        return f"at {t_s:.2f} s"
    join = float(trajectory.t[rows])
    if t_s < float(trajectory.t[rows - 1]):
        return f"at {t_s:.2f} s, in the planned path (ends {trajectory.t[rows - 1]:.2f} s)"
    if t_s < join:
        return f"at {t_s:.2f} s, in the blend into {rep.get('motion', 'the library motion')}"
    if t_s > trajectory.duration_s:
        return f"at {t_s:.2f} s, in the final hold"
    return f"at {t_s:.2f} s, {t_s - join:.2f} s into {rep.get('motion', 'the library motion')} (from frame {rep.get('connecting_frame', '?')})"


def feet_stretches(rec: Recording) -> list[tuple[int, int]]:
    """Sample ranges [i, j] "on its feet": only the feet touch the world for at least ON_FEET_MIN_S."""
    if len(rec.t) < 2:
        return []
    need = max(1, int(round(ON_FEET_MIN_S / float(rec.t[1] - rec.t[0]))))
    return [(i, j) for i, j in true_runs(supported_on_feet(rec), rec.t) if j - i + 1 >= need]


def feet_from(rec: Recording, until_s: float) -> int | None:
    """First sample (at most ``until_s``) from which the robot is on its feet (:func:`feet_stretches`)."""
    stretches = feet_stretches(rec)
    return stretches[0][0] if stretches and rec.t[stretches[0][0]] <= until_s else None
