"""What a rise returns: every candidate tried (``RiseAttempt``) and the outcome (``RiseResult``)."""

from __future__ import annotations

from dataclasses import dataclass, field

from robot_rise.filter import FilterResult
from robot_rise.proof import Proof
from robot_rise.trajectory import Trajectory

__all__ = ["RiseAttempt", "RiseResult"]


@dataclass(frozen=True)
class RiseAttempt:
    """One candidate tried: which motion and frame, and what became of it."""

    motion: str
    frame: int
    distance: float
    planned: bool
    plan_reason: str = ""
    proven: bool = False
    filter_reason: str = ""
    seconds: dict[str, float] = field(default_factory=dict)
    robust: bool = False
    blocked: str = ""  # why the motion has no room where it would go (placement.motion_room); nothing was planned
    skipped: str = ""  # why this pass does not try the motion (the composed pass: not composable); nothing was planned
    more_iterations: int = 0  # the candidate filtered again with this many more iterations (MORE_ITERATIONS)
    cautious: str = ""  # the fast approach went off plan, so the same path was filtered again cautiously timed: "proven" or why not

    def describe(self) -> str:
        if self.skipped:
            return f"{self.motion}@{self.frame}: skipped ({self.skipped})"
        if self.blocked:
            return f"{self.motion}@{self.frame}: {self.blocked}"
        if not self.planned:
            return f"{self.motion}@{self.frame}: no path ({self.plan_reason})"
        again = f" with {self.more_iterations} more filter iterations" if self.more_iterations else ""
        again += f" (off plan; cautiously timed: {self.cautious})" if self.cautious else ""
        if not self.proven:
            return f"{self.motion}@{self.frame}{again}: not proven ({self.filter_reason})"
        return f"{self.motion}@{self.frame}{again}: proven" + ("" if self.robust else ", not robust to model errors")


@dataclass(frozen=True)
class RiseResult:
    """Outcome of :func:`rise`. ``trajectory`` is set whenever a motion was filtered (even unproven).

    Attributes:
        proven: the trajectory stands, proven by the filter's replay (its ``proof``).
        trajectory: the servo targets from the start posture (None when nothing was filtered).
        attempts: every candidate tried, in order, with what became of it.
        reason: why not proven (empty when proven).
        filter_result: the filter's evidence for the returned trajectory.
    """

    proven: bool
    trajectory: Trajectory | None
    attempts: tuple[RiseAttempt, ...]
    reason: str = ""
    filter_result: FilterResult | None = None

    @property
    def proof(self) -> Proof | None:
        """The proof written in the trajectory's report (None when nothing was filtered)."""
        if self.trajectory is None or "proven" not in self.trajectory.report:
            return None
        return Proof.from_dict(self.trajectory.report)
