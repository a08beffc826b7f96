"""The local-minimum detector of paper 004 section 8: an energy window the two ends must leave."""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["EnergyWindow"]


@dataclass
class EnergyWindow:
    """Local-minimum detector of paper 004 section 8 (mutable state of one planning run).

    The window starts below the higher of the two initial energies; each iteration, if the lower
    energy of the two ends falls out of the window, the window slides down to contain it. When
    the ends stay in one window for ``patience`` iterations, it is a local minimum. Ours: an
    iteration in which the two ends come closer than ever before by at least a tenth of a step
    also counts as progress (linear safe-zone steps move without changing the energy much).
    """

    top: float
    fraction: float
    patience: int
    best_gap: float = math.inf
    stuck: int = 0

    def update(self, e_low: float, gap: float, min_progress: float) -> bool:
        """Feed one iteration; True when a local minimum is detected."""
        bottom = self.top * (1.0 - self.fraction)
        progressed = False
        if e_low < bottom:
            self.top = e_low
            progressed = True
        if gap < self.best_gap - min_progress:
            self.best_gap = gap
            progressed = True
        self.stuck = 0 if progressed else self.stuck + 1
        return self.stuck >= self.patience
