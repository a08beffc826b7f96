"""A get-up's ensemble proof composed of a library motion's start proof and an arrival proven online.

The ensemble proof replays the whole get-up (approach, library motion, the judge's hold) on
every model variant: 2.5-4 s of CPU, most of a fallen robot's wait for its first command
(issue 16: <= 2 s at the 95th percentile on one core). Most of it is the library motion, the
same every time. So, once per robot and motion (``prove_start``, a :class:`StartProof`): the
motion is replayed on every variant after ``ARRIVAL_SETTLE_S`` on its first targets, from its
start posture; each variant's verdict and the pose it rests in before the motion plays are kept.
Online, for a get-up that joins the motion at its start (``prove_composed``):

- the approach ends on the motion's first targets and holds them ``ARRIVAL_SETTLE_S``, then the
  motion plays its rows unchanged;
- the nominal model replays the whole of it (the filter, as always: envelope, standing, self
  contact): the nominal proof is never composed;
- each variant replays the approach and the settle only, and must end at rest in that variant's
  rest pose of the start proof (gravity direction in the torso, root height, joints within
  ``ARRIVAL_*``). On flat ground a lying body at rest holding the same targets is in the same
  state wherever it lies and whichever way it faces, so from there the start proof's verdict on
  that variant holds;
- a variant stands if it arrives and the start proof says it stands; a variant that does not
  arrive (slower to come to rest, a joint left further off: a weak P gain does both) is replayed
  whole, as the uncomposed proof would, and stands if that replay does.

What it is not: "the same state" is within our tolerances (gear friction leaves a loaded joint a
few degrees from where another approach would), not a theorem. ``robot-rise check`` replays the
whole trajectory on every variant (the uncomposed proof); BENCHMARKS.md reports how often the
two agree. ``rise(..., composed=True)`` (the guard) composes where it applies and proves whole
where it does not (another scene than the library's, a library part the nominal filter had to
reshape, a motion whose start proof is not ``composable``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from robot_rise.proof.config import ProofConfig
from robot_rise.proof.ensemble import EnsembleReplayer
from robot_rise.proof.noise import noise_check
from robot_rise.proof.prediction import PREDICTED_KEY, PredictedPositions, predicted_positions
from robot_rise.proof.verdict import Proof, VariantVerdict, prove
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.sim.player import Player, Recording
from robot_rise.sim.variants import ModelVariant, combined_variants, variant_start
from robot_rise.trajectory import Trajectory

__all__ = [
    "ARRIVAL_SETTLE_S",
    "ARRIVAL_SPREAD_STARTS",
    "arrival_spread_starts",
    "MAX_WHOLE_REPLAYS",
    "TAIL_MAX_STRETCH",
    "COMPOSED_KEY",
    "Arrival",
    "ComposedProof",
    "gravity_angle_rad",
    "RestPose",
    "StartProof",
    "settled_start",
    "prove_start",
    "prove_composed",
]

COMPOSED_KEY = "composed_proof"  # the trajectory report's entry saying the ensemble was composed (and of what)
ARRIVAL_SETTLE_S = 0.5  # [s] the motion's first targets held before it plays: the lying body comes to rest (ours)
# "At rest in the motion's start pose" (ours): the library proof's own start variant spreads the
# joints by 0.5 deg; a body that lies 2 deg otherwise, 5 mm higher or a joint 2 deg off is not
# the start that proof replayed.
ARRIVAL_MAX_TILT_RAD = math.radians(1.0)  # gravity direction in the torso against the rest pose's
ARRIVAL_MAX_HEIGHT_M = 0.003  # root height against the rest pose's
ARRIVAL_MAX_JOINT_RAD = math.radians(4.0)  # every joint against the rest pose's (gear friction leaves a loaded joint where it stopped: 2.2 deg seen on a hip roll, 3.4 deg with the P gain 20 % low)
ARRIVAL_REST_JOINT_SPEED_RAD_S = 0.05  # every joint slower than this
ARRIVAL_REST_ROOT_SPEED_M_S = 0.01  # root slower than this
# The library part as its proof played it, but for what conforming the file's rounded rows to the
# executor's limits changes: a few microseconds of time, a micro-radian of target (its proof
# already stands under 1e-6 rad of target noise: issue 14's flips)
TAIL_TIME_TOLERANCE_S = 1e-4
TAIL_TARGET_TOLERANCE_RAD = 1e-5
TAIL_MAX_STRETCH = 1.0 + 1e-4  # FilterConfig.motion_max_stretch of the nominal filter: the library part not slowed
ARRIVAL_SPREAD_STARTS = 4  # arrival_spread_starts: rest states a start proof also proves the nominal model from (ours)
# Variants that arrive elsewhere are replayed whole, up to this many (ours: one or two whole
# replays, ~0.15 s each, instead of the next candidate's plan and proof; more than that and the
# approach is not the one the start proof had in mind)
MAX_WHOLE_REPLAYS = 3


@dataclass(frozen=True)
class RestPose:
    """Where a lying body rests: root orientation (wxyz), root height [m], joints [rad] (the player's order)."""

    root_quat_wxyz: np.ndarray
    root_z_m: float
    joints_rad: np.ndarray


@dataclass(frozen=True)
class StartProof:
    """A library motion proven from rest on its first targets (precomputed once per robot and motion).

    The library file's proof starts from the settled start posture, where the servos then pull
    toward the first targets (a few degrees under the body's weight). This one holds the first
    targets ``ARRIVAL_SETTLE_S`` from that posture, then plays the motion, on every variant: the
    rest pose each variant reaches is what an arrival must match, its verdict what it inherits.

    Attributes:
        motion: the motion's name.
        verdicts: each variant's verdict on settle + motion (ensemble order).
        rest: each variant's rest pose at the end of the settle.
        tolerance_rad: per joint, the variants' spread over the motion [rad] (the executor's band).
        tilt_tolerance_rad: the same for the torso's tilt [rad].
        spread_proven: the nominal model's ``noise_check`` of the motion after the settle holds,
            and the nominal model proves it (stands, within the torque bound) from every
            :func:`arrival_spread_starts` too. Where it does not, an arrival within the tolerances
            is not as good as the motion's own start (a landing impact's torque is that sensitive:
            the sit-up peaks at 1.00 from one of them), and the motion is not joined by
            composition (``composable``). A get-up joining it by composition is not noise-checked
            online: noise before the settle is forgotten at rest, and the noisy and spread
            replays from there stand for it.
    """

    motion: str
    verdicts: tuple[VariantVerdict, ...]
    rest: tuple[RestPose, ...]
    tolerance_rad: np.ndarray
    tilt_tolerance_rad: float
    spread_proven: bool = True

    @property
    def all_stand(self) -> bool:
        return all(v.standing for v in self.verdicts)

    @property
    def composable(self) -> bool:
        """A get-up may join the motion by a composed proof: every variant stands from the rest
        pose and the nominal model proves the motion from every arrival-spread start."""
        return self.all_stand and self.spread_proven

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON values (``robot_rise.proof.start_cache`` writes them)."""
        return {
            "motion": self.motion,
            "verdicts": [v.to_dict() for v in self.verdicts],
            "rest": [{"root_quat_wxyz": r.root_quat_wxyz.tolist(), "root_z_m": r.root_z_m, "joints_rad": r.joints_rad.tolist()}
                     for r in self.rest],
            "tolerance_rad": self.tolerance_rad.tolist(),
            "tilt_tolerance_rad": self.tilt_tolerance_rad,
            "spread_proven": self.spread_proven,
        }

    @classmethod
    def from_dict(cls, obj: Any) -> StartProof:
        """The inverse of :meth:`to_dict`.

        Raises:
            KeyError, TypeError, ValueError: not what ``to_dict`` writes.
        """
        rest = tuple(RestPose(np.asarray(r["root_quat_wxyz"], dtype=float), float(r["root_z_m"]), np.asarray(r["joints_rad"], dtype=float))
                     for r in obj["rest"])
        return cls(str(obj["motion"]), tuple(VariantVerdict.from_dict(v) for v in obj["verdicts"]), rest,
                   np.asarray(obj["tolerance_rad"], dtype=float), float(obj["tilt_tolerance_rad"]), bool(obj["spread_proven"]))


@dataclass(frozen=True)
class Arrival:
    """One variant's arrival at the motion's start.

    Attributes:
        label: the variant.
        arrived: at rest in the variant's rest pose of the motion's start.
        reason: why not (empty when arrived).
        peak_torque_ratio: largest torque / envelope during the arrival.
    """

    label: str
    arrived: bool
    reason: str
    peak_torque_ratio: float


@dataclass(frozen=True)
class ComposedProof:
    """What :func:`prove_composed` found.

    Attributes:
        proof: the nominal proof with the composed ensemble verdicts (proven only if the nominal
            one was and every variant arrives and stands in the start proof).
        arrivals: each variant's arrival.
        report: the trajectory report's entries to replace (the proof's, ``predicted``, ``COMPOSED_KEY``).
    """

    proof: Proof
    arrivals: tuple[Arrival, ...]
    report: dict[str, Any]


def arrival_spread_starts(robot: Robot, start: Posture, n: int = ARRIVAL_SPREAD_STARTS) -> tuple[Posture, ...]:
    """``n`` seeded copies of a motion's start posture with every joint off by up to
    ``ARRIVAL_MAX_JOINT_RAD``: where an approach that a composed proof accepts may leave the body
    (gear friction leaves a loaded joint degrees from where the motion's own start rests, and a
    momentum motion's saturated first pull then costs torque)."""
    return tuple(variant_start(start, robot, ModelVariant(f"arrival spread {k}", seed=k, start_spread_rad=ARRIVAL_MAX_JOINT_RAD))
                 for k in range(1, n + 1))


def gravity_angle_rad(qa: np.ndarray, qb: np.ndarray) -> float:
    """Angle between the world's vertical seen from two root orientations (wxyz) [rad]: how
    differently two bodies lie, whatever their heading."""
    def down(q: np.ndarray) -> np.ndarray:
        w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
        return np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])  # R^T e_z
    return float(np.arccos(np.clip(down(qa) @ down(qb), -1.0, 1.0)))


def settled_start(motion_trajectory: Trajectory, settle_s: float = ARRIVAL_SETTLE_S) -> Trajectory:
    """The motion after ``settle_s`` on its first targets (from its start posture)."""
    t = np.concatenate([[0.0], motion_trajectory.t + settle_s])
    q = np.vstack([motion_trajectory.q[:1], motion_trajectory.q])
    root = None if motion_trajectory.root is None else np.vstack([motion_trajectory.root[:1], motion_trajectory.root])
    return dataclasses.replace(motion_trajectory, t=t, q=q, root=root)


def _rest_at(rec: Recording, t_s: float) -> RestPose:
    k = min(int(np.searchsorted(rec.t, t_s - 1e-9)), len(rec.t) - 1)
    return RestPose(rec.root_pose[k, 3:].copy(), float(rec.root_pose[k, 2]), rec.q[k].copy())


def prove_start(name: str, motion_trajectory: Trajectory, replayer: EnsembleReplayer, config: ProofConfig,
                nominal: Recording) -> StartProof:
    """:class:`StartProof` of a library motion: settle + motion replayed on every variant.

    Args:
        name: the motion's name.
        motion_trajectory: the library motion (from its start posture).
        replayer: the ensemble's players.
        config: tolerances, the judge's hold and the motion's ``combined_variants`` (replayed too).
        nominal: the nominal replay of ``settled_start(motion_trajectory)`` (the executor's band
            is the variants' spread around it).
    """
    settled = settled_start(motion_trajectory)
    result, recs = replayer.replay(settled, config=config)
    band = PredictedPositions.from_dict(predicted_positions(nominal, ensemble=recs))
    player = Player(replayer.robot, replayer.scene)
    # the noisy replays from its own start; the spread starts are four larger perturbations
    spread_proven = (noise_check(settled, nominal, player, start=motion_trajectory.start, config=config)[0].holds
                     and all(prove(replayer.robot, settled, scene=replayer.scene, config=config, player=player, start=s)[2].proven
                             for s in arrival_spread_starts(replayer.robot, motion_trajectory.start)))
    return StartProof(name, result.verdicts, tuple(_rest_at(r, ARRIVAL_SETTLE_S) for r in recs),
                      band.tolerance_rad, float(band.tilt_tolerance_rad or 0.0), spread_proven)


def _arrival(label: str, rec: Recording, rest: RestPose, config: ProofConfig) -> Arrival:
    peak = float(np.max(rec.envelope_ratio, initial=0.0))
    problems = []
    if float(np.max(np.abs(rec.qd[-1]), initial=0.0)) > ARRIVAL_REST_JOINT_SPEED_RAD_S or float(np.linalg.norm(rec.root_vel[-1, :3])) > ARRIVAL_REST_ROOT_SPEED_M_S:
        problems.append("not at rest")
    tilt = gravity_angle_rad(rec.root_pose[-1, 3:], rest.root_quat_wxyz)
    if tilt > ARRIVAL_MAX_TILT_RAD:
        problems.append(f"lies {math.degrees(tilt):.1f} deg otherwise than at the motion's start")
    height = abs(float(rec.root_pose[-1, 2]) - rest.root_z_m)
    if height > ARRIVAL_MAX_HEIGHT_M:
        problems.append(f"{1000 * height:.1f} mm higher or lower than at the motion's start")
    joints = np.abs(rec.q[-1] - rest.joints_rad)
    if float(np.max(joints)) > ARRIVAL_MAX_JOINT_RAD:
        problems.append(f"{rec.joint_names[int(np.argmax(joints))]} {math.degrees(float(np.max(joints))):.1f} deg off the motion's start")
    start_overlap = float(rec.self_penetration_m[0]) if rec.self_penetration_m.size else 0.0
    if float(np.max(rec.self_penetration_m, initial=0.0)) > max(config.self_penetration_tolerance_m, start_overlap + config.self_penetration_tolerance_m):
        problems.append("self-collision")
    return Arrival(label, not problems, "; ".join(problems), peak)


def prove_composed(
    nominal: Proof,
    nominal_recording: Recording,
    trajectory: Trajectory,
    *,
    join_row: int,
    motion_trajectory: Trajectory,
    start_proof: StartProof,
    start: Posture,
    replayer: EnsembleReplayer,
    config: ProofConfig,
) -> ComposedProof | None:
    """The composed ensemble proof of ``trajectory`` (see the module docstring), or None where it
    does not apply (the caller then replays the whole ensemble).

    Args:
        nominal: the nominal proof of the whole ``trajectory`` (the filter's).
        nominal_recording: its replay.
        trajectory: approach, settle, then the library motion's rows from its first on, from ``join_row``.
        join_row: the row of ``trajectory`` where the library motion's first row is.
        motion_trajectory: the library motion.
        start_proof: the motion's :class:`StartProof` on ``replayer``'s variants.
        start: where the robot lies.
        replayer: the ensemble's players.
        config: tolerances, the motion's ``combined_variants`` (the start proof's own).
    """
    labels = tuple(v.label for v in replayer.variants + combined_variants(config.combined_variants))
    if tuple(v.label for v in start_proof.verdicts) != labels or not 0 < join_row < len(trajectory.t):
        return None
    if motion_trajectory.report.get("scene_digest") not in (None, nominal.scene_digest):
        return None  # the motion was made for another scene (a slope, obstacles): no translation symmetry to lean on
    tail_q = trajectory.q[join_row:]
    lib_q = motion_trajectory.q[:, [motion_trajectory.joint_names.index(j) for j in trajectory.joint_names]]
    if tail_q.shape != lib_q.shape or not np.allclose(tail_q, lib_q, rtol=0.0, atol=TAIL_TARGET_TOLERANCE_RAD) or not np.allclose(
            trajectory.t[join_row:] - trajectory.t[join_row], motion_trajectory.t, rtol=0.0, atol=TAIL_TIME_TOLERANCE_S):
        return None  # the filter reshaped the library part: not what the start proof played
    if trajectory.t[join_row] - trajectory.t[join_row - 1] < ARRIVAL_SETTLE_S - TAIL_TIME_TOLERANCE_S or not np.allclose(
            trajectory.q[join_row - 1], tail_q[0], rtol=0.0, atol=TAIL_TARGET_TOLERANCE_RAD):
        return None  # no settle on the motion's first targets before it plays
    arrival = dataclasses.replace(trajectory, t=trajectory.t[:join_row + 1], q=trajectory.q[:join_row + 1],
                                  root=None if trajectory.root is None else trajectory.root[:join_row + 1])
    _, recs = replayer.replay(arrival, start=start, config=dataclasses.replace(config, hold_s=0.0))
    arrivals = tuple(_arrival(label, rec, rest, config) for label, rec, rest in zip(labels, recs, start_proof.rest))
    elsewhere = [k for k, a in enumerate(arrivals) if not a.arrived]
    whole: dict[int, VariantVerdict] = {}
    if elsewhere and len(elsewhere) <= MAX_WHOLE_REPLAYS:  # those few replayed whole: their own proof, not the start proof's
        result, _ = replayer.replay(trajectory, start=start, config=config, only=elsewhere)
        whole = dict(zip(elsewhere, result.verdicts))
    verdicts = []
    for k, (a, v) in enumerate(zip(arrivals, start_proof.verdicts)):
        if k in whole:
            w = whole[k]
            verdicts.append(dataclasses.replace(w, reason=w.reason and f"replayed whole (arrival: {a.reason}): {w.reason}"))
            continue
        reason = f"arrival: {a.reason}" if not a.arrived else v.reason
        verdicts.append(VariantVerdict(v.label, a.arrived and v.standing, "" if a.arrived and v.standing else reason,
                                       v.final_tilt_deg, v.final_height_fraction, max(a.peak_torque_ratio, v.peak_torque_ratio),
                                       v.min_zmp_margin_m))
    failures = [f"variant '{v.label}': {v.reason}" for v in verdicts if not v.standing]
    proof = dataclasses.replace(nominal, ensemble=tuple(verdicts), proven=nominal.proven and not failures,
                                problems=nominal.problems + tuple(failures))
    report = {
        **proof.to_dict(),
        PREDICTED_KEY: _predicted(nominal_recording, recs, start_proof),
        COMPOSED_KEY: {"arrival_until_s": round(float(trajectory.t[join_row]), 4), "settle_s": ARRIVAL_SETTLE_S,
                       "start_proof": start_proof.motion, "replayed_whole": [labels[k] for k in sorted(whole)]},
    }
    return ComposedProof(proof, arrivals, report)


def _predicted(nominal: Recording, arrivals: list[Recording], start_proof: StartProof) -> dict[str, Any]:
    """The nominal replay's positions; each joint's tolerance the larger of the arrivals' spread
    and the start proof's (its variants' spread over the motion)."""
    entry = PredictedPositions.from_dict(predicted_positions(nominal, ensemble=arrivals))
    tolerance = np.maximum(entry.tolerance_rad, start_proof.tolerance_rad)
    tilt_tol = None if entry.tilt_tolerance_rad is None else max(entry.tilt_tolerance_rad, start_proof.tilt_tolerance_rad)
    return dataclasses.replace(entry, tolerance_rad=tolerance, tilt_tolerance_rad=tilt_tol).to_dict()
