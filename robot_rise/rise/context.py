"""What every rise of one robot in one scene reuses (``RiseContext``), and where a plan goes (``select_goal``)."""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field

from robot_rise.library import (Connection, FrameIndex, KMeansTree, Motion, MotionLibrary, connecting_posture, connection_candidates, load_library,
                                lying_frames, robot_library_dir)
from robot_rise.model import Robot
from robot_rise.placement import MotionRoom, motion_room
from robot_rise.planning.space import PostureSpace
from robot_rise.posture import Posture
from robot_rise.proof import (EnsembleReplayer, ProofConfig, StartProof, load_start_proof, prove, prove_start, save_start_proof, settled_start,
                              start_proof_key)
from robot_rise.rise.options import DEFAULT_CANDIDATES
from robot_rise.validity import Looseness, ValidityChecker

__all__ = ["RiseContext", "GoalSelection", "select_goal", "connection_room", "joining"]

OBSTACLES_ONLY_GROUND_DROP_M = 2.0  # the ground moved this far down: a checker that sees only obstacles [m]
KEY_IN_LIBRARY_DISTANCE = 1e-6  # a key posture this close (planner distance) to its connecting posture is that library posture


def joining(standard: ProofConfig, motion: Motion) -> ProofConfig:
    """``standard`` for a proof that joins ``motion``: the combined variants it asks for, and its
    noisy replays where it asks for more than ``standard`` (none where ``standard`` has none)."""
    noise = max(standard.noise_replays, motion.noise_replays) if standard.noise_replays > 0 else 0
    return dataclasses.replace(standard, combined_variants=motion.combined_variants, noise_replays=noise)


@dataclass
class RiseContext:
    """What every rise of one robot in one scene reuses: checker, library, frame index, K-means tree.

    Build it once (``RiseContext.build``) when rising many times; ``rise`` builds one otherwise.
    """

    robot: Robot
    scene: str | os.PathLike[str] | None
    checker: ValidityChecker
    library: MotionLibrary
    index: FrameIndex
    tree: KMeansTree
    _obstacle_checker: ValidityChecker | None = field(default=None, repr=False)
    _ensemble: EnsembleReplayer | None = field(default=None, repr=False)
    _start_proofs: dict[tuple[str, ProofConfig], StartProof | None] = field(default_factory=dict, repr=False)

    def start_proof(self, motion: Motion, standard: ProofConfig = ProofConfig()) -> StartProof | None:
        """The motion proven from rest on its first targets on every variant
        (:func:`robot_rise.proof.prove_start`), None where the nominal model does not prove it;
        read from the start proof cache (``robot_rise.proof.start_cache``) or computed on first
        use (``warm_start_proofs`` does all at once) and kept there, then reused."""
        # what a start proof rests on: the margins, noise and hold of the caller's standard, the
        # motion's combined variants (a proof's standard only: no filter's stretch bounds)
        config = joining(standard, motion)
        if (motion.name, config) not in self._start_proofs:
            key = start_proof_key(self.robot, self.scene, motion.name, motion.trajectory, motion.start, config)
            kept = load_start_proof(key)
            if kept is None:
                rec, _, nominal = prove(self.robot, settled_start(motion.trajectory), scene=self.scene, config=config, start=motion.start)
                kept = prove_start(motion.name, motion.trajectory, self.ensemble(), config, rec) if nominal.proven else None
                if kept is not None:
                    save_start_proof(key, kept)
            self._start_proofs[motion.name, config] = kept
        return self._start_proofs[motion.name, config]

    def warm_start_proofs(self, standard: ProofConfig = ProofConfig()) -> int:
        """Every library motion's start proof now (what a live get-up precomputes per robot); how many compose."""
        return sum(self.start_proof(m, standard) is not None for m in self.library.motions)

    def ensemble(self) -> EnsembleReplayer:
        """The model variants' players in this scene (built on first use, then reused)."""
        if self._ensemble is None:
            self._ensemble = EnsembleReplayer(self.robot, self.scene)
        return self._ensemble

    def obstacle_checker(self) -> ValidityChecker | None:
        """The scene's obstacles without its ground (placement.motion_room), None without obstacles."""
        if self.checker.index.obstacle_geoms.size == 0:
            return None
        if self._obstacle_checker is None:
            self._obstacle_checker = ValidityChecker(self.robot, self.scene, looseness=Looseness(ground_drop_m=OBSTACLES_ONLY_GROUND_DROP_M))
        return self._obstacle_checker

    @classmethod
    def build(cls, robot: Robot, scene: str | os.PathLike[str] | None = "flat", library: MotionLibrary | None = None) -> RiseContext:
        library = library or load_library(robot_library_dir(robot))
        index = lying_frames(FrameIndex.build(library, robot), library)
        return cls(robot, scene, ValidityChecker(robot, scene), library, index, KMeansTree(index))


@dataclass(frozen=True)
class GoalSelection:
    """Where a plan goes when the user names no goal (``select_goal``).

    Attributes:
        goal: the connecting posture, placed where the robot lies (or where the key posture is).
        key: the key posture to pass through, or None (none given, or it IS the connecting posture).
        source: ``motion@frame (candidate r)`` of the library frame, for messages and reports.
    """

    goal: Posture
    key: Posture | None
    source: str


def select_goal(ctx: RiseContext, start: Posture, key: Posture | None = None) -> GoalSelection:
    """The connecting posture a plan goes to, as ``robot-rise rise`` selects it.

    Paper 000 section 4.1: the nearest library posture (eq. 1) to the lying posture; with a key
    posture the plan passes through it, and "if a key posture is not a posture in our motion
    database, motion planning is applied again to connect the key posture to a posture in our
    motion database" (section 5.1): the connecting posture is then the one nearest the KEY
    posture, placed where the key posture is. Among the nearest frames of the
    ``DEFAULT_CANDIDATES`` nearest motions (nearest first), the first whose placement is legal is
    taken (as ``rise`` moves on to its next candidate); if none is, the nearest, so that the
    planner reports why it is invalid.

    Args:
        ctx: library, frame index, K-means tree and checker of the scene.
        start: the lying posture.
        key: optional key posture.
    """
    anchor = key if key is not None else start
    tried: list[tuple[Posture, str]] = []
    for rank, conn in enumerate(connection_candidates(ctx.library, ctx.robot, anchor, DEFAULT_CANDIDATES, index=ctx.index, tree=ctx.tree)):
        goal = connecting_posture(ctx.library, ctx.robot, conn, anchor, ctx.checker)
        tried.append((goal, f"{conn.motion}@{conn.frame} (candidate {rank})"))
        if ctx.checker.is_valid(goal):
            break
    else:  # no legal placement: the nearest, so that the planner reports why it is invalid
        goal, _ = tried[0]
    source = next(s for g, s in tried if g is goal)
    if key is not None:
        space = PostureSpace.for_robot(ctx.robot)
        if float(space.distance(space.state(key), space.state(goal))) < KEY_IN_LIBRARY_DISTANCE:
            return GoalSelection(key, None, source)  # the key posture is in the library: plan to it
    return GoalSelection(goal, key, source)


def connection_room(context: RiseContext, connection: Connection, goal: Posture) -> MotionRoom:
    """placement.motion_room for a candidate (always ok in a scene without obstacles)."""
    checker = context.obstacle_checker()
    motion = context.library.get(connection.motion)
    tr = motion.trajectory
    if checker is None or tr.root is None:
        return MotionRoom(True, connection.motion)
    cols = [tr.joint_names.index(j) for j in context.robot.joint_names]
    return motion_room(connection.motion, tr.root, tr.t, tr.q[:, cols], connection.frame, goal, checker)
