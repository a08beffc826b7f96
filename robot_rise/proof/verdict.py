"""The proof of a trajectory: replayed from its start posture, judged, and kept as a frozen ``Proof``.

A trajectory is proven when, replayed through the servo model, the robot ends standing by the
judge, torque stays within (1 - margin) of the torque-speed envelope at every physics step, and
no self-collision occurs. The ``Proof`` says so, with the margins and what it was proven on (the
robot's and the scene's digests); it is written into the trajectory file's ``report`` beside the
entries of the planner, the filter and ``rise`` (``to_dict`` / ``from_dict``, the file's keys).

The rule built on it, "may this trajectory run on this robot?", is :func:`execution_permit`: a
refusal is a ``Permit`` with its reason, not an exception.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from robot_rise.errors import FormatError
from robot_rise.proof.config import ProofConfig
from robot_rise.proof.fall import describe_fall
from robot_rise.proof.timeline import segment_at
from robot_rise.proof.violations import Violation, find_violations, saturation_rad
from robot_rise.model import Robot
from robot_rise.paths import scene_path
from robot_rise.posture import Posture
from robot_rise.sim.player import Player, Recording
from robot_rise.sim.standing import StandVerdict, judge, supported_on_feet
from robot_rise.trajectory import Trajectory
from robot_rise.seal import seal_problem

__all__ = ["Proof", "VariantVerdict", "Permit", "prove", "prove_with_violations", "execution_permit", "scene_digest"]


@dataclass(frozen=True)
class VariantVerdict:
    """How one variant fared.

    Attributes:
        label: the variant's label.
        standing: the judge's verdict, and no self-collision beyond the tolerance.
        reason: why not (empty when standing).
        final_tilt_deg: torso tilt at the end [deg].
        final_height_fraction: torso height at the end / the stand keyframe's.
        peak_torque_ratio: largest torque / envelope ratio (the variant's own envelope).
        min_zmp_margin_m: smallest ZMP margin while on the feet [m]; None if never on the feet.
    """

    label: str
    standing: bool
    reason: str
    final_tilt_deg: float
    final_height_fraction: float
    peak_torque_ratio: float
    min_zmp_margin_m: float | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "label": self.label,
            "standing": self.standing,
            "reason": self.reason,
            "final_tilt_deg": self.final_tilt_deg,
            "final_height_fraction": self.final_height_fraction,
            "peak_torque_ratio": self.peak_torque_ratio,
            "min_zmp_margin_m": self.min_zmp_margin_m,
        }

    @classmethod
    def from_dict(cls, obj: Mapping[str, Any]) -> VariantVerdict:
        zmp = obj.get("min_zmp_margin_m")
        return cls(
            str(obj["label"]),
            bool(obj["standing"]),
            str(obj.get("reason", "")),
            float(obj["final_tilt_deg"]),
            float(obj["final_height_fraction"]),
            float(obj["peak_torque_ratio"]),
            None if zmp is None else float(zmp),
        )


@dataclass(frozen=True)
class Proof:
    """The verdict of a replay, its margins, and what it was proven on.

    Attributes:
        proven: the robot ends standing by the judge, within (1 - margin) of the envelope, with
            no self-collision.
        problems: why not, one line each (empty when proven).
        robot: name of the robot it was proven on.
        robot_digest: SHA-256 of the robot's files (``Robot.digest()``).
        scene: the scene (name or MJCF path) it was proven in, None for none.
        scene_digest: SHA-256 of the scene file ('' for no scene).
        standing: the judge's verdict.
        judge: the judge's verdict in one line (``StandVerdict.summary()``: tilt, height, peaks).
        duration_s: duration of the proven trajectory, without the judge's hold [s].
        peak_torque_ratio: largest torque / envelope ratio over every physics step.
        envelope_limit: the ratio allowed, 1 - margin.
        peak_torque_ratio_per_joint: joint name -> its largest torque / envelope ratio.
        min_zmp_margin_m: smallest ZMP margin inside the support polygon while on the feet [m];
            None if never on the feet.
        time_on_feet_s: time on the feet [s].
        ground_contacts: the robot's geoms that touched the ground.
        self_collision: a self contact deeper than the tolerance (touching is not colliding).
        self_touch: any self contact (the judge's flag).
        max_self_penetration_m: deepest self contact [m].
        stood_from_s: start of the final standing stretch [s]; None if it never stood.
        diagnosis: why it did not stand (:func:`describe_fall`); '' when standing.
        ensemble: each model variant's verdict (``robot_rise.proof.ensemble``), empty when the
            ensemble was not replayed; ``proven`` then also means every variant stands.
    """

    proven: bool
    problems: tuple[str, ...]
    robot: str
    robot_digest: str
    scene: str | None
    scene_digest: str
    standing: bool
    judge: str
    duration_s: float
    peak_torque_ratio: float
    envelope_limit: float
    peak_torque_ratio_per_joint: dict[str, float]
    min_zmp_margin_m: float | None
    time_on_feet_s: float
    ground_contacts: tuple[str, ...]
    self_collision: bool
    self_touch: bool
    max_self_penetration_m: float
    stood_from_s: float | None
    diagnosis: str = ""
    ensemble: tuple[VariantVerdict, ...] = ()

    @property
    def worst_tilt_deg(self) -> float | None:
        """Largest final torso tilt over the ensemble [deg] (None without one)."""
        return max((v.final_tilt_deg for v in self.ensemble), default=None)

    @property
    def worst_height_fraction(self) -> float | None:
        """Smallest final torso height fraction over the ensemble (None without one)."""
        return min((v.final_height_fraction for v in self.ensemble), default=None)

    @property
    def worst_torque_ratio(self) -> float | None:
        """Largest peak torque / envelope over the ensemble (None without one)."""
        return max((v.peak_torque_ratio for v in self.ensemble), default=None)

    @property
    def worst_zmp_margin_m(self) -> float | None:
        """Smallest ZMP margin on the feet over the ensemble [m] (None without one, or never on the feet)."""
        return min((v.min_zmp_margin_m for v in self.ensemble if v.min_zmp_margin_m is not None), default=None)

    @property
    def ensemble_standing(self) -> int:
        """How many variants stand."""
        return sum(v.standing for v in self.ensemble)

    def to_dict(self) -> dict[str, Any]:
        """The proof's entries of a trajectory's ``report``, in the file's key order."""
        return {
            "proven": self.proven,
            "problems": list(self.problems),
            "robot": self.robot,
            "robot_digest": self.robot_digest,
            "scene": self.scene,
            "scene_digest": self.scene_digest,
            "standing": self.standing,
            "judge": self.judge,
            "duration_s": self.duration_s,
            "peak_torque_ratio": self.peak_torque_ratio,
            "envelope_limit": self.envelope_limit,
            "peak_torque_ratio_per_joint": dict(self.peak_torque_ratio_per_joint),
            "min_zmp_margin_m": self.min_zmp_margin_m,
            "time_on_feet_s": self.time_on_feet_s,
            "ground_contacts": list(self.ground_contacts),
            "self_collision": self.self_collision,
            "self_touch": self.self_touch,
            "max_self_penetration_m": self.max_self_penetration_m,
            "stood_from_s": self.stood_from_s,
            **({"diagnosis": self.diagnosis} if self.diagnosis else {}),
            **({"ensemble": self._ensemble_dict()} if self.ensemble else {}),
        }

    def _ensemble_dict(self) -> dict[str, Any]:
        return {
            "standing": self.ensemble_standing,
            "size": len(self.ensemble),
            "worst_tilt_deg": self.worst_tilt_deg,
            "worst_height_fraction": self.worst_height_fraction,
            "worst_torque_ratio": self.worst_torque_ratio,
            "worst_zmp_margin_m": self.worst_zmp_margin_m,
            "variants": [v.to_dict() for v in self.ensemble],
        }

    @classmethod
    def from_dict(cls, report: Mapping[str, Any], *, where: str = "report") -> Proof:
        """Read the proof's entries out of a trajectory's ``report`` (its other entries are ignored).

        A number the file holds as null (the trajectory writer's spelling of NaN) reads as NaN.

        Raises:
            FormatError: naming the missing or mistyped entry.
        """
        if not isinstance(report, Mapping):
            raise FormatError(f"{where}: expected an object, got {_short(report)}")
        values: dict[str, Any] = {}
        for key, (read, what) in _READERS.items():
            if key not in report:
                if key in _OPTIONAL:
                    continue
                raise FormatError(f"{where}: proof entry {key!r} missing")
            try:
                values[key] = read(report[key])
            except (TypeError, ValueError):
                raise FormatError(f"{where}: proof entry {key!r} must be {what}, got {_short(report[key])}") from None
        return cls(**values)


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _bool(v: Any) -> bool:
    if not isinstance(v, bool):
        raise TypeError
    return v


def _str(v: Any) -> str:
    if not isinstance(v, str):
        raise TypeError
    return v


def _optional_str(v: Any) -> str | None:
    return None if v is None else _str(v)


def _number(v: Any) -> float:
    if v is None:
        return math.nan  # the trajectory writer turns NaN into null
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise TypeError
    return float(v)


def _optional_number(v: Any) -> float | None:
    return None if v is None else _number(v)


def _strings(v: Any) -> tuple[str, ...]:
    if not isinstance(v, (list, tuple)):
        raise TypeError
    return tuple(_str(x) for x in v)


def _numbers_by_name(v: Any) -> dict[str, float]:
    if not isinstance(v, Mapping):
        raise TypeError
    return {_str(k): _number(x) for k, x in v.items()}


# Each entry of a Proof in the report: its reader and, for the error message, what it must be.
def _ensemble(v: Any) -> tuple[VariantVerdict, ...]:
    if not isinstance(v, Mapping) or not isinstance(v.get("variants"), list):
        raise TypeError
    try:
        return tuple(VariantVerdict.from_dict(x) for x in v["variants"])
    except (KeyError, AttributeError) as e:
        raise TypeError from e


_OPTIONAL = ("diagnosis", "ensemble")  # absent in files written before them
_READERS: dict[str, tuple[Callable[[Any], Any], str]] = {
    "proven": (_bool, "true or false"),
    "problems": (_strings, "a list of strings"),
    "robot": (_str, "a string"),
    "robot_digest": (_str, "a string"),
    "scene": (_optional_str, "a string or null"),
    "scene_digest": (_str, "a string"),
    "standing": (_bool, "true or false"),
    "judge": (_str, "a string"),
    "duration_s": (_number, "a number"),
    "peak_torque_ratio": (_number, "a number"),
    "envelope_limit": (_number, "a number"),
    "peak_torque_ratio_per_joint": (_numbers_by_name, "an object of numbers by joint name"),
    "min_zmp_margin_m": (_optional_number, "a number or null"),
    "time_on_feet_s": (_number, "a number"),
    "ground_contacts": (_strings, "a list of strings"),
    "self_collision": (_bool, "true or false"),
    "self_touch": (_bool, "true or false"),
    "max_self_penetration_m": (_number, "a number"),
    "stood_from_s": (_optional_number, "a number or null"),
    "diagnosis": (_str, "a string"),
    "ensemble": (_ensemble, "an object with a list of variant verdicts"),
}


@dataclass(frozen=True)
class Permit:
    """Whether a trajectory may run on a robot (:func:`execution_permit`).

    Attributes:
        allowed: its report proves it for this robot.
        reason: why not, one line naming the report entry (empty when allowed).
    """

    allowed: bool
    reason: str = ""


def execution_permit(report_or_proof: Proof | Mapping[str, Any], robot: Robot, trajectory: Trajectory | None = None) -> Permit:
    """May this trajectory run on ``robot``? Only if its proof says proven, on this robot's files,
    and (given the ``trajectory``) of exactly these targets: its seal holds (:mod:`robot_rise.seal`).

    Entries read: ``proven`` (true only if the judge passed within limits), ``robot`` (name),
    ``robot_digest`` (SHA-256 of the robot files, checked when present: an older proof may lack
    it). A trajectory's whole ``report`` may be passed; a partial one is judged on what it has.

    Args:
        report_or_proof: the trajectory's report (as read from its file) or its Proof.
        robot: the robot it is to run on (its digest is computed only when the report has one).
        trajectory: the trajectory itself: its seal is checked (what runs is what was proven).
    """
    report = report_or_proof.to_dict() if isinstance(report_or_proof, Proof) else report_or_proof
    if report.get("proven") is not True:
        return Permit(False, "the trajectory's report does not say it was proven (report.proven is not true)")
    name = report.get("robot")
    if name is None:
        return Permit(False, "the trajectory's report does not name the robot it was proven on (report.robot missing)")
    if name != robot.name:
        return Permit(False, f"the trajectory was proven on robot {name!r}, not {robot.name!r}")
    digest = report.get("robot_digest")
    if digest is not None:
        ours = robot.digest()
        if digest != ours:
            return Permit(False, (f"the trajectory was proven on another version of robot {name!r}: the robot files "
                                  f"changed since (report.robot_digest {str(digest)[:12]}..., loaded robot {ours[:12]}...)"))
    if trajectory is not None:
        problem = seal_problem(trajectory)
        if problem:
            return Permit(False, f"the trajectory is not what was proven: {problem}")
    return Permit(True)


def scene_digest(scene: str | os.PathLike[str] | None) -> str:
    """SHA-256 of the scene file ('' for no scene)."""
    if scene is None:
        return ""
    return hashlib.sha256(scene_path(scene).read_bytes()).hexdigest()


def prove(
    robot: Robot,
    trajectory: Trajectory,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    config: ProofConfig = ProofConfig(),
    player: Player | None = None,
    start: Posture | None = None,
) -> tuple[Recording, StandVerdict, Proof]:
    """Replay a trajectory from its start posture and judge it.

    Args:
        robot: the robot.
        trajectory: the servo targets.
        scene: the scene it is replayed in.
        config: the envelope margin, tolerances and the judge's hold time.
        player: a player of ``robot`` in ``scene`` to reuse (e.g. a model variant's).
        start: the posture the robot lies in (default: the trajectory's start).

    Returns:
        (recording, verdict, proof); ``proof.proven`` only if the robot stands by the judge,
        torque stays within (1 - margin) of the envelope at every physics step, and no
        self-collision occurred.
    """
    rec, verdict, proof, _ = prove_with_violations(
        robot, trajectory, scene=scene, config=config, player=player or Player(robot, scene), start=start,
        saturation_rad=saturation_rad(robot), want_violations=False,
    )
    return rec, verdict, proof


def prove_with_violations(
    robot: Robot,
    trajectory: Trajectory,
    *,
    scene: str | os.PathLike[str] | None,
    config: ProofConfig,
    player: Player,
    start: Posture | None,
    saturation_rad: float,
    want_violations: bool = True,
    stop_at_s: float | None = None,
) -> tuple[Recording, StandVerdict, Proof, list[Violation]]:
    """:func:`prove`, also returning the recording's violations (:func:`find_violations`, all of
    them; found only for a fall's diagnosis unless ``want_violations``: the filter reshapes them).
    With ``stop_at_s`` the replay stops there if the torque margin was exceeded by then (not
    proven; the violations are those until then)."""
    limit = 1.0 - config.envelope_margin
    rec = player.play(trajectory, start, hold_s=config.hold_s, stop_over=None if stop_at_s is None else (stop_at_s, limit + 1e-9))
    verdict = judge(rec)
    peak_per_joint = rec.envelope_ratio.max(axis=0)
    on = supported_on_feet(rec) & np.isfinite(rec.zmp_margin_m)
    ground_geoms = [rec.robot_geom_names[g] for g in np.flatnonzero(rec.ground_contact.any(axis=0))]
    within = verdict.peak_envelope_ratio <= limit + 1e-9
    # Touching is not colliding: a limb resting on another (as a lying robot's often does from
    # the start) interpenetrates less than the validity checker's contact tolerance.
    self_collision = bool(np.max(rec.self_penetration_m, initial=0.0) > config.self_penetration_tolerance_m)
    proven = bool(verdict.standing and within and not self_collision and rec.stopped_s is None)
    problems = []
    diagnosis = ""
    violations = (find_violations(rec, config, saturation_rad=saturation_rad)
                  if want_violations or not verdict.standing else [])
    if rec.stopped_s is not None:
        problems.append(f"replay stopped at {rec.stopped_s:.2f} s, over the torque margin by then")
    elif not verdict.standing:
        diagnosis = describe_fall(rec, trajectory, violations)
        problems.append(f"not standing: {verdict.reason} ({diagnosis})")
    if not within:
        worst = rec.joint_names[int(np.argmax(peak_per_joint))]
        problems.append(f"torque {verdict.peak_envelope_ratio:.2f} of the envelope (limit {limit:.2f}) at {worst}")
    if self_collision:
        k_self = int(np.argmax(rec.self_penetration_m))
        problems.append(
            f"self-collision {1000 * float(np.max(rec.self_penetration_m)):.1f} mm deep {segment_at(trajectory, float(rec.t[k_self]))}: "
            + ", ".join(f"{a}/{b}" for a, b in rec.self_contact_pairs[:3])
        )
    proof = Proof(
        proven=proven,
        problems=tuple(problems),
        robot=robot.name,
        robot_digest=robot.digest(),
        scene=str(scene) if scene is not None else None,
        scene_digest=scene_digest(scene),
        standing=verdict.standing,
        judge=verdict.summary(),
        duration_s=float(trajectory.duration_s),
        peak_torque_ratio=float(verdict.peak_envelope_ratio),
        envelope_limit=limit,
        peak_torque_ratio_per_joint={j: float(r) for j, r in zip(rec.joint_names, peak_per_joint)},
        min_zmp_margin_m=float(np.min(rec.zmp_margin_m[on])) if on.any() else None,
        time_on_feet_s=float(on.sum() * (rec.t[1] - rec.t[0])) if len(rec.t) > 1 else 0.0,
        ground_contacts=tuple(ground_geoms),
        self_collision=self_collision,
        self_touch=bool(verdict.self_collision),
        max_self_penetration_m=float(np.max(rec.self_penetration_m, initial=0.0)),
        stood_from_s=float(verdict.stood_from_s) if np.isfinite(verdict.stood_from_s) else None,
        diagnosis=diagnosis,
    )
    return rec, verdict, proof, violations
