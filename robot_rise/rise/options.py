"""What a rise may be asked: one frozen ``RiseOptions`` (scene, key posture, budget, candidates, retries, proof)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from robot_rise.filter import FilterConfig
from robot_rise.library import MotionLibrary
from robot_rise.posture import Posture
from robot_rise.sim.variants import ModelVariant

__all__ = ["DEFAULT_CANDIDATES", "DEFAULT_RETRIES", "DEFAULT_CANDIDATE_RANK", "RiseOptions"]

DEFAULT_CANDIDATES = 3  # library motions tried: the quickest, then the two nearest; one more after a motion with a timing window (connection_candidates)
DEFAULT_RETRIES = 1  # new rises from where a failed attempt left the robot lying
DEFAULT_CANDIDATE_RANK = "duration"  # the quickest expected get-up first, the nearest next (issue 17; connection_candidates)


@dataclass(frozen=True)
class RiseOptions:
    """How :func:`robot_rise.rise.rise` selects, plans, filters and proves.

    Attributes:
        scene: the scene the robot lies in.
        key: optional key posture to pass through (paper 000 section 4.2.3, key postures).
        seed: planner seed (deterministic for a seed).
        budget_s: planning budget per candidate [s].
        library: motion library (default: the robot's shipped library).
        candidates: how many library motions to try.
        candidate_rank: ``"duration"`` tries first the motion with the shortest expected get-up
            (approach + rest of the motion), ``"distance"`` the nearest (paper 000);
            :func:`robot_rise.library.connection_candidates`.
        retries: when every candidate fails (the more-iterations pass included) but the robot
            ends lying at rest, rise again from there, up to this many falls deep (the combined
            motion is proven from the original start; a failed attempt over the torque bound is
            cut short before it).
        composed: prove the ensemble by composition where it applies
            (:mod:`robot_rise.proof.composed`: the approach arrives at rest at the library
            motion's start, the variants replay only that, the motion's own proof does the rest):
            the live get-up's first command sooner, for ``ARRIVAL_SETTLE_S`` more robot time.
            Every candidate is tried composed first (cheap: the nominal replay and the variants'
            arrivals; its approach smoothed once, ``QUICK_SMOOTHING``); when none is proven so,
            the candidates are proven whole, as without it.
        robustness: extra model variants every proven candidate is replayed under (default none:
            the filter's ensemble proof already replays every variant); the first candidate
            that still stands under all of them is returned, else the first proven one (its
            report's ``robustness`` says which check it failed).
        filter_config: the dynamics filter's tuning and the proof's standard (``filter_config.proof``).
    """

    scene: str | os.PathLike[str] | None = "flat"
    key: Posture | None = None
    seed: int = 0
    budget_s: float = 30.0
    library: MotionLibrary | None = field(default=None, compare=False)
    candidates: int = DEFAULT_CANDIDATES
    candidate_rank: str = DEFAULT_CANDIDATE_RANK
    retries: int = DEFAULT_RETRIES
    composed: bool = False
    robustness: tuple[ModelVariant, ...] = ()
    filter_config: FilterConfig = field(default_factory=FilterConfig)
