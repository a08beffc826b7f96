"""The ensemble proof: a trajectory replayed unchanged on every model variant, each judged.

A proof on one model can be a fluke of its exact masses, friction, servo strength and timing.
The filter proves the nominal model within the envelope margin (``proof.py``), then replays the
same targets on each variant of ``robot_rise.sim.variants.ENSEMBLE``: proven means every variant
stands too (the standing judge, no self-collision beyond the tolerance). A variant's torque is
recorded, not bounded: under a deliberately wrong model, using the margin the nominal proof kept
free is what the margin is for. The worst margins over the ensemble (tilt, height, torque
ratio, ZMP) say how far from falling the trajectory is.

Cost: one replay per variant (about 0.12 s each for a 6 s get-up on one core); they run in a
thread pool, one ``Player`` (one ``MjModel``) per variant, built once per robot and scene.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
import numpy as np

from robot_rise.proof.config import ProofConfig
from robot_rise.proof.noise import NOISE_CHECK_KEY, noise_check, with_noise
from robot_rise.proof.verdict import Proof, VariantVerdict, prove
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.sim.player import Player, Recording
from robot_rise.sim.standing import judge
from robot_rise.sim.variants import ENSEMBLE, ModelVariant, combined_variants, random_variants, variant_start, variant_trajectory
from robot_rise.trajectory import Trajectory

__all__ = ["COMBINED_VARIANTS_KEY", "EnsembleResult", "EnsembleReplayer", "with_ensemble", "check", "replay_random_variants",
           "proven_combined_variants", "proven_noise_replays"]

COMBINED_VARIANTS_KEY = "combined_variants"  # the trajectory report's entry: combined variants its proof replayed


@dataclass(frozen=True)
class EnsembleResult:
    """Every variant's verdict, in ensemble order."""

    verdicts: tuple[VariantVerdict, ...]

    @property
    def all_stand(self) -> bool:
        return all(v.standing for v in self.verdicts)

    @property
    def standing_share(self) -> float:
        return sum(v.standing for v in self.verdicts) / max(1, len(self.verdicts))

    def failures(self) -> list[str]:
        """One line per variant that did not stand."""
        return [f"variant '{v.label}': {v.reason}" for v in self.verdicts if not v.standing]


def _verdict(variant: ModelVariant, rec: Recording, config: ProofConfig) -> VariantVerdict:
    v = judge(rec)
    # grown shapes overlap by twice the growth where the nominal ones touch: that much is the same touch
    tolerance = config.self_penetration_tolerance_m + 2.0 * max(0.0, variant.geom_grow_m)
    # and a limb that rests on the body where the robot lies (a foot against the torso) starts as
    # deep as the grown shapes and its load put it: the start's own overlap is where the robot is,
    # not what the motion does; only deeper than that (by the tolerance) counts
    if rec.self_penetration_m.size:
        tolerance = max(tolerance, float(rec.self_penetration_m[0]) + config.self_penetration_tolerance_m)
    self_collision = bool(np.max(rec.self_penetration_m, initial=0.0) > tolerance)
    standing = bool(v.standing and not self_collision)
    reason = "" if standing else (v.reason or "self-collision")
    zmp = v.min_zmp_margin_m
    return VariantVerdict(
        variant.label,
        standing,
        reason,
        math.degrees(v.final_tilt_rad),
        float(v.final_height_fraction),
        float(v.peak_envelope_ratio),
        None if not math.isfinite(zmp) else float(zmp),
    )


class EnsembleReplayer:
    """Replays trajectories of one robot in one scene on every variant (one Player each).

    Args:
        robot: the robot.
        scene: the scene.
        variants: the model variants (default: the ensemble).
        threads: replays run at once (default: the CPUs this process may use).

    A config with ``combined_variants`` adds that many combined variants
    (``robot_rise.sim.variants.combined_variants``) after ``variants``; their players are built
    on first use and kept.

    Not thread-safe itself (each Player is used by one thread at a time).
    """

    def __init__(self, robot: Robot, scene: str | os.PathLike[str] | None = "flat", *,
                 variants: Sequence[ModelVariant] = ENSEMBLE, threads: int | None = None) -> None:
        self.robot = robot
        self.scene = scene
        self.variants = tuple(variants)
        self.players = [Player(robot, scene, variant=v) for v in self.variants]
        self.threads = max(1, threads or len(os.sched_getaffinity(0)))
        self._combined: list[Player] = []

    def _variants_and_players(self, combined: int) -> tuple[tuple[ModelVariant, ...], list[Player]]:
        extra = combined_variants(combined)
        while len(self._combined) < combined:
            self._combined.append(Player(self.robot, self.scene, variant=extra[len(self._combined)]))
        return self.variants + extra, self.players + self._combined[:combined]

    def replay(self, trajectory: Trajectory, *, start: Posture | None = None,
               config: ProofConfig = ProofConfig(), only: Sequence[int] | None = None) -> tuple[EnsembleResult, list[Recording]]:
        """Replay ``trajectory`` (from ``start``, default its own) on every variant (or on the
        variants numbered ``only``, in that order); judge each."""
        start = start or trajectory.start
        variants, players = self._variants_and_players(config.combined_variants)
        ks = list(range(len(variants))) if only is None else [int(k) for k in only]

        def one(k: int) -> Recording:
            v = variants[k]
            return players[k].play(variant_trajectory(trajectory, v), variant_start(start, self.robot, v), hold_s=config.hold_s)

        threads = min(self.threads, len(ks))
        if threads <= 1:
            recs = [one(k) for k in ks]
        else:
            with ThreadPoolExecutor(threads) as pool:
                recs = list(pool.map(one, ks))
        return EnsembleResult(tuple(_verdict(variants[k], r, config) for k, r in zip(ks, recs))), recs


def proven_combined_variants(trajectory: Trajectory) -> int:
    """How many combined variants ``trajectory``'s proof replayed besides the ensemble (0 for files
    written before them, or proven without): what a replay of its proof must replay again."""
    n = trajectory.report.get(COMBINED_VARIANTS_KEY, 0)
    return n if isinstance(n, int) and not isinstance(n, bool) and n > 0 else 0


def proven_noise_replays(trajectory: Trajectory, replays: int) -> int:
    """How many noisy replays a replay of ``trajectory``'s proof runs: ``replays``, or as many as
    its proof ran where that is more (a motion may ask for more: ``Motion.noise_replays``); 0 stays 0."""
    entry = trajectory.report.get(NOISE_CHECK_KEY)
    n = entry.get("replays") if isinstance(entry, dict) else None
    return max(replays, n) if replays > 0 and isinstance(n, int) and not isinstance(n, bool) else replays


def with_ensemble(proof: Proof, result: EnsembleResult) -> Proof:
    """``proof`` with the ensemble's verdicts: proven only if it was and every variant stands."""
    failures = result.failures()
    return dataclasses.replace(proof, ensemble=result.verdicts, proven=proof.proven and not failures,
                               problems=proof.problems + tuple(failures))


def check(
    robot: Robot,
    trajectory: Trajectory,
    *,
    scene: str | os.PathLike[str] | None = None,
    config: ProofConfig = ProofConfig(),
) -> Proof:
    """Replay ``trajectory`` from its start and return its proof, on the nominal model (with its
    ``config.noise_replays`` noisy replays: ``noise.py``) and (with ``config.ensemble``) on every
    variant of the ensemble: what ``robot-rise check`` does.

    Args:
        robot: the robot.
        trajectory: the servo targets.
        scene: the scene to replay it in (default: the scene its report was proven in, else flat).
        config: the envelope margin, tolerances, the judge's hold time, the ensemble switch.
    """
    if scene is None:
        scene = str(trajectory.report.get("scene") or "flat")
    config = dataclasses.replace(config, combined_variants=proven_combined_variants(trajectory),
                                 noise_replays=proven_noise_replays(trajectory, config.noise_replays))
    player = Player(robot, scene)
    rec, _, proof = prove(robot, trajectory, scene=scene, config=config, player=player)
    if config.noise_replays > 0:
        proof = with_noise(proof, noise_check(trajectory, rec, player, config=config)[0])
    if not config.ensemble:
        return proof
    return with_ensemble(proof, EnsembleReplayer(robot, scene).replay(trajectory, config=config)[0])


def replay_random_variants(
    robot: Robot,
    trajectory: Trajectory,
    n: int,
    seed: int,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    config: ProofConfig = ProofConfig(),
) -> EnsembleResult:
    """Replay on ``n`` random variants drawn from the ensemble's ranges (``random_variants``): the
    share that stands is the trajectory's margin, measured on models it was not proven on."""
    config = dataclasses.replace(config, combined_variants=0)  # only the random draws
    return EnsembleReplayer(robot, scene, variants=random_variants(n, seed)).replay(trajectory, config=config)[0]
