"""Writing the library: each motion settled, timed, verified on the robustness grid, proven, and only then written with its index row.

A motion is written only after it stands on all five players of
:func:`robot_rise.authoring.robustness.robustness_players` within ``TORQUE_BOUND`` of the
envelope and without self collision (a turn-over's: none deeper than the proof's tolerance), and
its proof (:func:`robot_rise.filter.check` on flat
ground) says proven; its index row is added or replaced, so the index always names motions that
pass. The file's ``report`` holds the judge's verdict, the peak torque ratio (nominal and over the
corners), ZMP margin and keyframe times, and the proof's entries (``Proof.to_dict``: ``proven``,
``robot``, ``robot_digest``, ``scene``, ...), so ``execute`` accepts the motion as written; the
simulated root pose is written as ``root`` (needed by connecting-posture selection). The settled
start posture is clamped into the joint limits (a body at rest on a joint stop reads slightly
past it). Files are written atomically (a temporary file renamed over the old one), so an
interrupted run never leaves a half-written motion.

:func:`reprove_library` re-proves a library in place without re-authoring it (``robot-rise
library prove``): after the robot files or the proof change, the motions keep their rows and get
a fresh proof.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_rise.authoring.adapt import adapt_to_body, fit_to_body, reference_statics
from robot_rise.authoring.goal_lead import clamp_goal_lead
from robot_rise.authoring.keyframes import Keyframe, MotionSpec, build_trajectory
from robot_rise.authoring.lying import settle
from robot_rise.authoring.retiming import RETIME_RATIO_TARGET, Retimed, retime, speed_prescale, subdivide
from robot_rise.authoring.robustness import TORQUE_BOUND, robustness_players
from robot_rise.errors import FormatError, PostureError
from robot_rise.fileio import write_text_atomic
from robot_rise.filter import COMMAND_LIMITS_KEY, command_limits_for, conform
from robot_rise.proof import (
    PREDICTED_KEY,
    EnsembleReplayer,
    Proof,
    arrival_spread_starts,
    predicted_positions,
    prove,
    with_ensemble,
)
from robot_rise.library import LIBRARY_FORMAT, Strategy, joint_keyframes, load_library, load_strategies, robot_library_dir
from robot_rise.model import Robot, load_robot
from robot_rise.posture import LIMIT_CLAMP_TOLERANCE_RAD, clamp_to_limits, posture_from_dict, write_posture
from robot_rise.sampling import classify_lying
from robot_rise.sim.player import Player, Recording
from robot_rise.sim.standing import StandVerdict, judge
from robot_rise.validity import DEFAULT_CONTACT_TOLERANCE_M
from robot_rise.trajectory import Trajectory, trajectory_from_dict, trajectory_to_dict, write_trajectory
from robot_rise.seal import sealed

__all__ = ["author_library", "settled_start", "prove_for_library", "write_motion", "motion_specs", "PROOF_SCENE", "with_proof", "Reproof", "reprove_library"]

log = logging.getLogger(__name__)

PROOF_SCENE = "flat"  # library motions are authored on flat ground and proven there

_PROOF_KEYS = frozenset(f.name for f in dataclasses.fields(Proof))  # a report's entries that belong to its proof


def with_proof(robot: Robot, tr: Trajectory, *, scene: str = PROOF_SCENE) -> tuple[Trajectory, Proof]:
    """Conform ``tr`` to the executor's command limits, replay it from its start on the nominal
    model and every ensemble variant, and put the proof's entries into its report, with the
    command limits it was proven under and the positions the executor should see.

    The report's other entries (the author's verdict, keyframe times, ...) stay where they are;
    proof entries of an older proof are replaced, and dropped when the new proof has none.

    Returns:
        (the trajectory, conformed, with the proof in its report; the proof).
    """
    limits = command_limits_for(robot)
    tr = conform(tr, limits)  # what the executor streams unclamped is what is proven
    rec, _, proof = prove(robot, tr, scene=scene)
    replayed, recs = EnsembleReplayer(robot, scene).replay(tr)
    proof = with_ensemble(proof, replayed)
    entries = {**proof.to_dict(), COMMAND_LIMITS_KEY: limits.to_dict(), PREDICTED_KEY: predicted_positions(rec, ensemble=recs)}
    report = {k: v for k, v in tr.report.items() if k not in _PROOF_KEYS or k in entries}
    report.update(entries)
    return sealed(dataclasses.replace(tr, report=report)), proof


@dataclass(frozen=True)
class Reproof:
    """What :func:`reprove_library` did to one motion.

    Attributes:
        name: the motion.
        proof: its fresh proof.
        clamped: joints of its start posture clamped into their limits (rows past a limit are
            clamped with them).
        written: its files changed (False: they already held this proof and start).
    """

    name: str
    proof: Proof
    clamped: tuple[str, ...]
    written: bool


def reprove_library(directory: str | Path | None, robot: Robot, *, scene: str = PROOF_SCENE) -> list[Reproof]:
    """Re-prove every motion of a library in place, without re-authoring it.

    Per motion: the start posture (trajectory file and start file) and the rows up to
    ``LIMIT_CLAMP_TOLERANCE_RAD`` past a joint limit are clamped into it; the trajectory is
    replayed and its report's proof entries replaced (:func:`with_proof`); the files are
    rewritten atomically in their own JSON layout, other entries byte for byte and the rows as
    proven (conforming to the command limits may move one a micro-radian: the seal is of what
    was proven), and only when something changed. A motion that is not proven gets its failing proof written (the file
    tells the truth; ``execute`` refuses it).

    Args:
        directory: the library directory (default: the robot's shipped library).
        robot: the robot the motions are proven on.
        scene: the scene they are proven in.

    Returns:
        one :class:`Reproof` per motion, in index order.

    Raises:
        FormatError: the library or a motion file is malformed, or a row lies further than the
            tolerance past a limit.
        PostureError: a start posture lies further than the tolerance past a limit.
    """
    lib = load_library(directory if directory is not None else robot_library_dir(robot), sealed_only=False)  # re-proving seals them
    index_path = lib.directory / "index.json"
    index_text = index_path.read_text()
    index = json.loads(index_text)
    rows = index["motions"]
    out = []
    for row in rows:
        traj_path, start_path = lib.directory / str(row["trajectory"]), lib.directory / str(row["start"])
        text, start_text = traj_path.read_text(), start_path.read_text()
        obj, start_obj = json.loads(text), json.loads(start_text)
        clamped = _clamp_posture_object(obj["start"], robot, where=f"{traj_path}: start")
        clamped += tuple(j for j in _clamp_posture_object(start_obj, robot, where=str(start_path)) if j not in clamped)
        _clamp_rows(obj, trajectory_from_dict(obj, where=str(traj_path)), robot, where=str(traj_path))
        before = trajectory_from_dict(obj, where=str(traj_path))
        proven, proof = with_proof(robot, before, scene=scene)
        written = trajectory_to_dict(proven)
        obj["report"] = written["report"]
        if written["q"] != obj["q"]:  # conformed rows (a micro-radian off): the file holds what was proven, as its seal says
            obj["q"] = written["q"]
        if proven.t is not before.t:  # conformed: slower segments, same rows; the phase ends where its row went
            obj["t"] = written["t"]
            row["connect_until_s"] = round(float(np.interp(float(row["connect_until_s"]), before.t, proven.t)), 6)
            if "duration_s" in row:
                row["duration_s"] = round(proven.duration_s, 6)
        new_text, new_start_text = json.dumps(obj) + "\n", json.dumps(start_obj, indent=1) + "\n"
        if new_start_text != start_text:
            write_text_atomic(start_path, new_start_text)
        if new_text != text:
            write_text_atomic(traj_path, new_text)
        log.info("%s: %s%s", row["name"], "proven" if proof.proven else "NOT proven: " + "; ".join(proof.problems),
                 f", start clamped at {', '.join(clamped)}" if clamped else "")
        out.append(Reproof(str(row["name"]), proof, clamped, new_text != text or new_start_text != start_text))
    new_index_text = json.dumps(index, indent=1) + "\n"
    if new_index_text != index_text:
        write_text_atomic(index_path, new_index_text)
    return out


def _clamp_posture_object(obj: dict, robot: Robot, *, where: str) -> tuple[str, ...]:
    """Clamp a posture@1 JSON object's joints into the limits in place; returns the joints clamped.

    Raises:
        PostureError: a joint lies further than ``LIMIT_CLAMP_TOLERANCE_RAD`` past its limit.
    """
    inside, clamped = clamp_to_limits(posture_from_dict(obj, where=where), robot, where=where)
    for j in clamped:
        obj["joints"][j] = inside.joints[j]
    return clamped


def _clamp_rows(obj: dict, tr: Trajectory, robot: Robot, *, where: str) -> None:
    """Clamp a trajectory file's rows into the joint limits, editing ``obj`` (its JSON object) in place.

    Raises:
        FormatError: a row lies further than ``LIMIT_CLAMP_TOLERANCE_RAD`` past a limit.
    """
    cols = [robot.joint_index(j) for j in tr.joint_names]
    inside = np.clip(tr.q, robot.joint_lower[cols], robot.joint_upper[cols])
    excess = np.abs(inside - tr.q)
    if excess.max(initial=0.0) > LIMIT_CLAMP_TOLERANCE_RAD:
        r, c = np.unravel_index(int(np.argmax(excess)), excess.shape)
        raise FormatError(f"{where}: row {r} (t = {tr.t[r]:.3f} s): {tr.joint_names[c]} lies {excess[r, c] * 1e3:.2f} mrad past its limit",
                          hint=f"up to {LIMIT_CLAMP_TOLERANCE_RAD * 1e3:.2f} mrad is clamped; re-author the motion")
    for r, c in zip(*np.nonzero(excess)):
        obj["q"][r][c] = float(inside[r, c])


def motion_specs(robot: Robot, strategies: tuple[Strategy, ...] | None = None) -> tuple[MotionSpec, ...]:
    """The strategies (default: the shipped get-ups, ``configs/strategies`` but its turn-overs) as
    motions of ``robot``: role values mapped to its joints."""
    out = []
    for s in strategies if strategies is not None else tuple(s for s in load_strategies() if s.lands is None):
        lying, keyframes = joint_keyframes(s, robot)
        out.append(
            MotionSpec(
                name=s.name,
                lying=s.lying,
                strategy=s.description,
                lying_joints=lying,
                keyframes=tuple(Keyframe(t, goals) for t, goals in keyframes),
                connect_keyframe=s.connect_keyframe,
                lying_yaw_rad=s.lying_yaw_rad,
                retime=s.retime,
                clamp_lead=s.clamp_lead,
                max_stretch=s.max_stretch,
                combined_variants=s.combined_variants,
                noise_replays=s.noise_replays,
            )
        )
    return tuple(out)


def settled_start(robot: Robot, spec: MotionSpec) -> Posture:
    """The motion's lying posture dropped onto flat ground to rest, clamped into the joint limits.

    Raises:
        PostureError: a joint rests further than the clamp tolerance past its limit.
    """
    return clamp_to_limits(settle(robot, spec.lying, spec.lying_joints, yaw_rad=spec.lying_yaw_rad), robot, where=f"{spec.name}: settled start")[0]


def prove_for_library(robot: Robot, tr: Trajectory, start: Posture, players: list[Player], *, clamp_lead: bool, connect_until_s: float,
                      report: dict, touching_ok: bool = False) -> tuple[Trajectory, StandVerdict, float] | str:
    """A library motion's trial: its goals clamped into the envelope (``clamp_lead``), standing
    on every robustness player within ``TORQUE_BOUND`` without self contact (``touching_ok``:
    without self contact deeper than the proof's tolerance), then proven on the ensemble
    (:func:`with_proof`, rows rounded as the file writes them).

    Returns:
        (the trajectory with its report, the nominal verdict, the end of its lying-to-sitting
        phase [s] after conforming), or why it is not a library motion.
    """
    if clamp_lead:
        tr = clamp_goal_lead(robot, tr, players, spread_starts=arrival_spread_starts(robot, start))
    recs = [p.play(tr) for p in players]
    verdicts = [judge(r) for r in recs]
    collides = [bool(np.max(r.self_penetration_m, initial=0.0) > DEFAULT_CONTACT_TOLERANCE_M) if touching_ok else v.self_collision
                for r, v in zip(recs, verdicts)]
    bad = [f"{i}: {v.summary()}" + (_deepest_self_contact(r) if c else "")
           for i, (r, v, c) in enumerate(zip(recs, verdicts, collides)) if not v.standing or c or v.peak_envelope_ratio > TORQUE_BOUND]
    if bad:
        return f"{tr.duration_s:.2f} s motion fails on the robustness players: " + "; ".join(bad)
    rec, v = recs[0], verdicts[0]
    # simulated root pose at every row (rows at ROW_HZ, recording at 100 Hz: interpolate)
    root = np.stack([np.interp(tr.t, np.concatenate([[0.0], rec.t]), np.concatenate([[start.root_pos[i] if i < 3 else start.root_quat_wxyz[i - 3]], rec.root_pose[:, i]])) for i in range(7)], axis=-1)
    root[:, 3:] /= np.linalg.norm(root[:, 3:], axis=1, keepdims=True)
    report = {
        **report,
        "duration_s": tr.duration_s,
        "standing": v.standing,
        "verdict": v.summary(),
        "peak_envelope_ratio": v.peak_envelope_ratio,
        "peak_envelope_ratio_corners": max(x.peak_envelope_ratio for x in verdicts),
        "min_zmp_margin_m": v.min_zmp_margin_m,
        "self_collision": v.self_collision,
        "connect_until_s": connect_until_s,
        "robot_digest": robot.digest(),
    }
    as_written = trajectory_from_dict(trajectory_to_dict(Trajectory(tr.robot, tr.joint_names, tr.t, tr.q, tr.start, report, root)))
    tr, proof = with_proof(robot, as_written)  # the proof is of the file's rows (rounded as written)
    if tr.t is not as_written.t:  # conformed: slower segments, same rows; the phase ends where its row went (as reprove_library)
        connect_until_s = round(float(np.interp(connect_until_s, as_written.t, tr.t)), 6)
        tr = tr.with_report(connect_until_s=connect_until_s)
    if not proof.proven:
        return f"{tr.duration_s:.2f} s motion not proven: " + "; ".join(proof.problems)
    return tr, v, connect_until_s


def _deepest_self_contact(rec: Recording) -> str:
    """How deep and when the deepest self contact was, and (the recording keeps no per-step pairs)
    which geoms touched during the play."""
    k = int(np.argmax(rec.self_penetration_m))
    return (f" (deepest {1000 * float(rec.self_penetration_m[k]):.1f} mm at {rec.t[k]:.2f} s; touching during the play: "
            + ", ".join(f"{a}/{b}" for a, b in rec.self_contact_pairs[:3]) + ("..." if len(rec.self_contact_pairs) > 3 else "") + ")")


def write_motion(out_dir: Path, name: str, tr: Trajectory, start: Posture) -> None:
    """A motion's trajectory and start files, each complete or not there (written aside, then renamed)."""
    tmp_dir = out_dir / ".authoring"
    tmp_dir.mkdir(exist_ok=True)
    write_trajectory(tmp_dir / f"{name}.json", tr)
    write_posture(tmp_dir / f"{name}.start.json", start)
    (tmp_dir / f"{name}.start.json").replace(out_dir / f"{name}.start.json")
    (tmp_dir / f"{name}.json").replace(out_dir / f"{name}.json")
    tmp_dir.rmdir()


def author_library(
    out_dir: Path,
    robot: Robot | None = None,
    *,
    names: list[str] | None = None,
    strategies: tuple[Strategy, ...] | None = None,
    failures: dict[str, str] | None = None,
) -> list[dict]:
    """Settle, retime, play and judge motions; write the passing ones and merge them into the index.

    A motion is written (and its index row added or replaced) only if it stands, within
    ``TORQUE_BOUND`` of the envelope and without self collision, nominally and at the four
    friction/mass corners, and its ensemble proof says proven; a failing motion is logged (and
    its reason put in ``failures``) and leaves the files and the index as they were, so
    ``index.json`` always names motions that pass. Rows of motions no longer among the strategies
    are dropped when the whole library is rebuilt (``names`` None).

    Args:
        out_dir: the library directory (created if missing), e.g. ``configs/motions/op3``.
        robot: the robot (default: the embedded OP3-class robot); it needs joint roles.
        names: the motions to rebuild, their rows replaced or added and the others kept; None or
            empty: every strategy (only None drops stale rows).
        strategies: the strategies to adapt (default: the shipped ones).
        failures: filled with name -> reason for each strategy not written.

    Returns:
        the index rows of the motions written by this call, in strategy order.
    """
    robot = robot or load_robot()
    out_dir.mkdir(parents=True, exist_ok=True)
    players = robustness_players(robot)
    player = players[0]
    index_path = out_dir / "index.json"
    old_rows: dict[str, dict] = {}
    if index_path.exists():
        try:
            old_rows = {r["name"]: r for r in json.loads(index_path.read_text()).get("motions", [])}
        except (ValueError, KeyError):
            old_rows = {}
    entries = []
    every = strategies if strategies is not None else load_strategies()
    # turn-overs end lying, not standing: build_library follows each with a get-up (turn_over.author_turn_over)
    chosen = tuple(s for s in every if s.lands is None)
    specs = motion_specs(robot, chosen)
    failed = failures if failures is not None else {}

    def fail(name: str, reason: str) -> None:
        log.error("%s: not written: %s", name, reason)
        failed[name] = reason

    for s in every:
        if s.lands is not None and names and s.name in names:
            fail(s.name, "a turn-over (it ends lying): robot-rise library build follows it with a get-up where a lying kind has none")

    for spec in specs:
        if names and spec.name not in names:
            continue
        try:
            start = settled_start(robot, spec)
        except PostureError as e:
            fail(spec.name, str(e))
            continue
        kind = classify_lying(start.root_quat_wxyz)
        if kind != spec.lying:
            fail(spec.name, f"its lying posture settles {kind}, not {spec.lying}")
            continue
        adaptation = ""
        if robot.roles is not None:
            # the strategy as its own robot does it: the statics this body is fitted to (a no-op there)
            reference = load_robot()
            ref_spec = motion_specs(reference, tuple(s for s in chosen if s.name == spec.name))[0]
            ref = reference_statics(reference, ref_spec.keyframes, settle(reference, ref_spec.lying, ref_spec.lying_joints, yaw_rad=ref_spec.lying_yaw_rad))
            written = spec.keyframes
            fitted, notes = fit_to_body(robot, written, start, ref)
            if notes:
                log.info("%s: fitted to the body: %s", spec.name, "; ".join(notes))
                adaptation = f"{len(notes)} keyframes fitted to the body's statics"
                spec = dataclasses.replace(spec, keyframes=fitted)
            raw = judge(player.play(build_trajectory(robot, start, spec.keyframes)))
            if not raw.standing and ref.stands:
                # it stands on its own robot as written, not on this body: search the body-relative
                # parameters (a strategy that needs its timing found on its own robot too goes on to retiming)
                adapted = adapt_to_body(robot, written, start, players, ref, seed=zlib.crc32(spec.name.encode()))
                if adapted.keyframes is None:
                    fail(spec.name, f"does not stand as written ({raw.reason}); {adapted.note}")
                    continue
                adaptation = adapted.note
                log.info("%s: adapted to the body: %s", spec.name, adaptation)
                spec = dataclasses.replace(spec, keyframes=adapted.keyframes)
        # the fastest timing first; should it not be proven, slower ones (the retiming before its
        # coordinate descent, then the keyframes' own timing): never needed on the strategies' own robot
        attempts = ("fastest", "unrefined", "unretimed") if spec.retime else ("as written",)
        reasons: list[str] = []
        done = None
        retimed: Retimed | None = None  # both retimed attempts from one retiming (it is deterministic)
        for attempt in attempts:
            if attempt in ("fastest", "unrefined"):
                if retimed is None:
                    fine, where = subdivide(robot, start, speed_prescale(robot, start, spec.keyframes))
                    retimed = retime(robot, start, fine, players, ratio_target=RETIME_RATIO_TARGET)
                elif retimed.unrefined == retimed.fastest:  # the refinement changed nothing: the same proof would fail the same way
                    continue
                kfs = retimed.fastest if attempt == "fastest" else retimed.unrefined
                connect_until_s = kfs[where[spec.connect_keyframe]].t_s
            elif attempt == "unretimed":
                kfs = speed_prescale(robot, start, spec.keyframes)
                connect_until_s = kfs[spec.connect_keyframe].t_s
            else:
                kfs = spec.keyframes
                connect_until_s = kfs[spec.connect_keyframe].t_s
            tr = build_trajectory(robot, start, kfs)
            extra = {"strategy": spec.strategy, "lying": spec.lying, "keyframe_times_s": [k.t_s for k in kfs], **({"adaptation": adaptation} if adaptation else {})}
            got = prove_for_library(robot, tr, start, players, clamp_lead=spec.clamp_lead, connect_until_s=connect_until_s, report=extra)
            if isinstance(got, str):
                reasons.append(got)
                continue
            done = got
            break
        if done is None:
            fail(spec.name, " / slower: ".join(reasons))
            continue
        tr, v, connect_until_s = done
        write_motion(out_dir, spec.name, tr, start)
        log.info("%s: %.2f s; %s (corners: peak %.2f)", spec.name, tr.duration_s, v.summary(), tr.report["peak_envelope_ratio_corners"])
        row = {
            "name": spec.name,
            "lying": spec.lying,
            "strategy": spec.strategy,
            "trajectory": f"{spec.name}.json",
            "start": f"{spec.name}.start.json",
            "connect_until_s": connect_until_s,
            "duration_s": round(tr.duration_s, 3),
            **({"max_stretch": spec.max_stretch} if spec.max_stretch is not None else {}),
            **({"combined_variants": spec.combined_variants} if spec.combined_variants else {}),
            **({"noise_replays": spec.noise_replays} if spec.noise_replays else {}),
        }
        entries.append(row)
        old_rows[spec.name] = row
        order = [s.name for s in specs]
        keep = [n for n in order if n in old_rows] + [n for n in old_rows if n not in order]
        index = {"format": LIBRARY_FORMAT, "robot": robot.name, "motions": [old_rows[n] for n in keep]}
        write_text_atomic(index_path, json.dumps(index, indent=1) + "\n")
    if names is None:  # a full rebuild drops rows of motions no longer authored (failed ones keep their last passing files)
        order = [s.name for s in specs]
        turned = [r for n, r in old_rows.items() if n not in order and r.get("turn_over")]  # library build's, not authored here
        index = {"format": LIBRARY_FORMAT, "robot": robot.name, "motions": [old_rows[n] for n in order if n in old_rows] + turned}
        write_text_atomic(index_path, json.dumps(index, indent=1) + "\n")
    return entries
