"""Target-noise replays: a proof must not hang on the last digits of its targets.

A trajectory file rounds its targets to 5e-7 rad and a servo is commanded in ticks, so a verdict
that changes with 1e-6 rad of noise on the targets is a coin toss, not a proof (issue 14: 3 of 300
rise outputs flipped, a landing's torque peak jumping from 0.83 to 1.00 of the envelope, in 4-6 of
10 noisy replays each). So the nominal model also replays ``ProofConfig.noise_replays`` copies of
the targets with seeded uniform noise of +-``noise_rad``, each up to ``noise_hold_s`` after the
trajectory's end, and each must:

- keep the torque within the proof's bound at every physics step, with no self-collision;
- end where the noiseless replay is at that moment: torso tilt, torso height and every joint
  within ``NOISE_SAME_*`` (then the noiseless replay's standing verdict, judged over the whole
  hold, is its verdict too; a body that lands otherwise is the knife edge itself).

Cost: about 0.1 s of CPU per replay of a 5 s get-up. The seed is fixed, so a proof is repeatable.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from robot_rise.proof.config import ProofConfig
from robot_rise.proof.verdict import Proof
from robot_rise.posture import Posture
from robot_rise.sim.player import Player, Recording
from robot_rise.trajectory import Trajectory

__all__ = ["NOISE_CHECK_KEY", "NoiseReplay", "NoiseCheck", "noisy_trajectory", "noise_check", "with_noise"]

NOISE_CHECK_KEY = "noise_check"  # the trajectory report's entry: the noisy replays its proof passed (or not)
# "Ends where the noiseless replay does" (ours): the composed proof's arrival tolerances
# (robot_rise.proof.composed) halved; seen between the noisy and noiseless replays of 60 rise
# outputs (2026-12-03): < 0.01 deg of tilt, < 0.02 deg per joint (the root up to 9 mm elsewhere
# on the floor, which standing does not care about).
NOISE_SAME_TILT_RAD = math.radians(0.5)
NOISE_SAME_HEIGHT_M = 0.0015
NOISE_SAME_JOINT_RAD = math.radians(2.0)


@dataclass(frozen=True)
class NoiseReplay:
    """One noisy replay against the noiseless one.

    Attributes:
        peak_torque_ratio: its largest torque / envelope ratio over every physics step.
        self_collision: a self contact deeper than the tolerance.
        tilt_gap_rad: torso tilt at its end minus the noiseless replay's then, absolute [rad].
        height_gap_m: the same for the torso height [m].
        joint_gap_rad: the largest joint angle difference then [rad].
        problems: why it does not hold (empty when it does).
    """

    peak_torque_ratio: float
    self_collision: bool
    tilt_gap_rad: float
    height_gap_m: float
    joint_gap_rad: float
    problems: tuple[str, ...]

    @property
    def holds(self) -> bool:
        return not self.problems


@dataclass(frozen=True)
class NoiseCheck:
    """The noisy replays of one trajectory: its verdict holds if each of them does."""

    noise_rad: float
    replays: tuple[NoiseReplay, ...]

    @property
    def holds(self) -> bool:
        return all(r.holds for r in self.replays)

    def failures(self) -> list[str]:
        """One line per noisy replay that does not hold."""
        return [f"target noise +-{self.noise_rad:g} rad, replay {k + 1}: {'; '.join(r.problems)}"
                for k, r in enumerate(self.replays) if not r.holds]

    def to_dict(self) -> dict[str, Any]:
        """The report's ``noise_check`` entry."""
        return {
            "noise_rad": self.noise_rad,
            "replays": len(self.replays),
            "holding": sum(r.holds for r in self.replays),
            "worst_torque_ratio": max((r.peak_torque_ratio for r in self.replays), default=None),
            "worst_tilt_gap_deg": max((math.degrees(r.tilt_gap_rad) for r in self.replays), default=None),
            "worst_joint_gap_deg": max((math.degrees(r.joint_gap_rad) for r in self.replays), default=None),
        }


def noisy_trajectory(trajectory: Trajectory, rng: np.random.Generator, noise_rad: float) -> Trajectory:
    """``trajectory`` with uniform noise of +-``noise_rad`` on every target."""
    return dataclasses.replace(trajectory, q=trajectory.q + rng.uniform(-noise_rad, noise_rad, trajectory.q.shape))


def _replay_against(rec: Recording, nominal: Recording, config: ProofConfig) -> NoiseReplay:
    limit = 1.0 - config.envelope_margin
    k = len(rec.t) - 1
    kn = min(k, len(nominal.t) - 1)  # the same sample of the noiseless replay (same rate, same start)
    tilt_gap = abs(float(rec.tilt_rad[k] - nominal.tilt_rad[kn]))
    height_gap = abs(float(rec.torso_height_m[k] - nominal.torso_height_m[kn]))
    joint_gap = float(np.max(np.abs(rec.q[k] - nominal.q[kn]), initial=0.0))
    self_collision = bool(np.max(rec.self_penetration_m, initial=0.0) > config.self_penetration_tolerance_m)
    problems = []
    if abs(float(rec.t[k] - nominal.t[kn])) > 1e-9:  # a noiseless replay held shorter than the noisy ones
        problems.append(f"the noiseless replay ends at {nominal.t[kn]:.2f} s, before this one ({rec.t[k]:.2f} s)")
    if rec.peak_envelope_ratio > limit + 1e-9:
        worst = rec.joint_names[int(np.argmax(rec.envelope_ratio.max(axis=0)))]
        problems.append(f"torque {rec.peak_envelope_ratio:.2f} of the envelope (limit {limit:.2f}) at {worst}")
    if self_collision:
        problems.append(f"self-collision {1000 * float(np.max(rec.self_penetration_m)):.1f} mm deep")
    own = 2.0 * config.noise_rad  # where the noise itself leaves the last targets (nothing at 1e-6 rad)
    if tilt_gap > NOISE_SAME_TILT_RAD + own or height_gap > NOISE_SAME_HEIGHT_M or joint_gap > NOISE_SAME_JOINT_RAD + own:
        problems.append(f"ends elsewhere at {rec.t[k]:.2f} s (tilt {math.degrees(tilt_gap):.2f} deg, height "
                        f"{1000 * height_gap:.1f} mm, a joint {math.degrees(joint_gap):.1f} deg from the noiseless replay)")
    return NoiseReplay(float(rec.peak_envelope_ratio), self_collision, tilt_gap, height_gap, joint_gap, tuple(problems))


def noise_check(
    trajectory: Trajectory,
    nominal: Recording,
    player: Player,
    *,
    start: Posture | None = None,
    config: ProofConfig = ProofConfig(),
) -> tuple[NoiseCheck, list[Recording]]:
    """Replay ``config.noise_replays`` noisy copies of ``trajectory`` on ``player`` (the nominal
    model) from ``start`` (default: its own) and hold each against ``nominal``, the noiseless
    replay on the same player. Returns the check and the noisy recordings (in order)."""
    rng = np.random.default_rng(config.noise_seed)
    start = start or trajectory.start
    recs = [player.play(noisy_trajectory(trajectory, rng, config.noise_rad), start, hold_s=config.noise_hold_s)
            for _ in range(config.noise_replays)]
    return NoiseCheck(config.noise_rad, tuple(_replay_against(r, nominal, config) for r in recs)), recs


def with_noise(proof: Proof, checked: NoiseCheck) -> Proof:
    """``proof`` with the noisy replays' verdict: proven only if it was and each of them holds."""
    failures = checked.failures()
    return dataclasses.replace(proof, proven=proof.proven and not failures, problems=proof.problems + tuple(failures))
