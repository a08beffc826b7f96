"""How far from falling a proven trajectory is: random model variants and target noise (issue 14).

Two measures per trajectory, both on the proof standard (the nominal model within the envelope
margin, every ensemble variant standing: ``robot_rise.filter.check``):

- the share of ``n`` random model variants (``robot_rise.sim.variants.random_variants``, every
  difference drawn at once from the ensemble's ranges, not the ensemble's own) that stand;
- whether the verdict flips when every target gets uniform noise of +-``noise_rad`` (1e-6 rad:
  the rounding of a trajectory file), over ``noise_trials`` seeded draws. Each trial is a whole
  ``check``, so it replays the proof's own noisy replays of the noisy targets too
  (``ProofConfig.noise_replays``): a knife edge flips a trial if any of them finds it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from robot_rise.constants import TARGET_NOISE_RAD
from robot_rise.proof import ProofConfig, check, noisy_trajectory, replay_random_variants
from robot_rise.model import Robot
from robot_rise.trajectory import Trajectory

__all__ = ["Margins", "NOISE_RAD", "margins_of"]

NOISE_RAD = TARGET_NOISE_RAD  # target noise of the knife-edge test (robot_rise.constants) [rad]


@dataclass(frozen=True)
class Margins:
    """What a trajectory withstood.

    Attributes:
        proven: its verdict on the proof standard, without noise.
        variants: random variants replayed.
        variants_standing: how many of them stood.
        noise_trials: noisy replays of the proof standard.
        noise_flips: how many gave another verdict than ``proven``.
        failures: why variants fell (one line each, at most five).
        flip_reasons: for each flip, what the verdict that differed from ``proven`` rests on (the
            noisy replay's problems, or the noiseless one's when noise made it pass).
    """

    proven: bool
    variants: int
    variants_standing: int
    noise_trials: int
    noise_flips: int
    failures: tuple[str, ...]
    flip_reasons: tuple[str, ...] = ()

    @property
    def variant_share(self) -> float:
        return self.variants_standing / self.variants if self.variants else float("nan")


def margins_of(
    robot: Robot,
    trajectory: Trajectory,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    variants: int = 50,
    seed: int = 1,
    noise_trials: int = 3,
    noise_rad: float = NOISE_RAD,
    config: ProofConfig = ProofConfig(),
) -> Margins:
    """Random-variant share and noise flips of ``trajectory`` (see the module docstring)."""
    nominal = check(robot, trajectory, scene=scene, config=config)
    proven = nominal.proven
    randoms = replay_random_variants(robot, trajectory, variants, seed, scene=scene, config=config) if variants else None
    flips = 0
    reasons: list[str] = []
    rng = np.random.default_rng(seed)
    for _ in range(noise_trials):
        noisy = noisy_trajectory(trajectory, rng, noise_rad)
        replay = check(robot, noisy, scene=scene, config=config)
        if replay.proven != proven:
            flips += 1
            failed = nominal if replay.proven else replay
            reasons.append("; ".join(failed.problems[:3]) or "not proven")
    return Margins(
        proven,
        variants,
        sum(v.standing for v in randoms.verdicts) if randoms else 0,
        noise_trials,
        flips,
        tuple(randoms.failures()[:5]) if randoms else (),
        tuple(reasons),
    )
