"""Adapting a strategy to a body: the strategy's statics matched, then, if it still does not stand, a small search.

A strategy's keyframes are written for one body, the embedded robot (``load_robot()``, the OP3):
the strategies are its motions. On another body the same role values put the centre of mass
elsewhere, flex a knee into its own thigh, or leave the hands short of the ground (paper 000
section 5.3: the dynamics filter adapts the motion to the body; here before timing). Two steps,
both measured against what the strategy does on its own robot (:func:`reference_statics`: played
there as written, the body parts on the ground at each keyframe, the final run of keyframes on
the feet alone -- the *standing phase* -- and the centre of mass of each of them relative to the
feet):

1. :func:`fit_to_body` -- statics, no simulation: each standing-phase keyframe is leaned about
   the ankles (hip pitch -t, ankle pitch +t: the soles stay flat) until its centre of mass lies
   where it lies on the strategy's robot, as a fraction of the foot length (a keyframe within
   ``BALANCE_TOLERANCE_M`` is left alone); a keyframe that makes this body touch itself (a
   collision mesh thicker than the strategy's robot's) is opened toward standing, only the
   joints between the touching bodies (:func:`collision_free`). On the strategy's own robot
   every quantity matches itself: a no-op.
2. :func:`adapt_to_body` -- only when the fitted strategy does not stand on the nominal player: a
   deterministic, bounded search (``ADAPT_MAX_PLAYS`` plays) over body-relative parameters
   (:class:`BodyAdaptation`: the time scale, shoulder pitch / hip / ankle / knee offsets of the
   push keyframes -- the last one before the standing phase and its first, where the body goes
   from its hands onto its feet -- and a lean of the standing phase), scored in MuJoCo. A
   candidate is accepted when it stands without self collision within ``RETIME_RATIO_TARGET`` of
   the torque envelope on the nominal player and the four robustness corners, so that retiming
   starts from a feasible timing.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import brentq

from robot_rise.authoring.keyframes import Keyframe, build_trajectory
from robot_rise.authoring.retiming import RETIME_RATIO_TARGET
from robot_rise.model import Robot, compose, model_index
from robot_rise.placement import place_on_soles
from robot_rise.posture import Posture
from robot_rise.sim.player import Player
from robot_rise.sim.standing import StandVerdict, judge

__all__ = [
    "ADAPT_BOX",
    "ADAPT_MAX_PLAYS",
    "ADAPT_TIME_SCALES",
    "FEET_ONLY_CLEARANCE_M",
    "BALANCE_TOLERANCE_M",
    "MAX_LEAN_RAD",
    "AdaptResult",
    "BodyAdaptation",
    "adapt_to_body",
    "apply_adaptation",
    "balance_on_feet",
    "body_parts",
    "collision_free",
    "fit_to_body",
    "Reference",
    "Statics",
    "reference_statics",
    "standing_phase",
    "support_phases",
]

FEET_ONLY_CLEARANCE_M = 0.02  # a keyframe is "on its feet alone" when nothing else is this close to the ground
MAX_LEAN_RAD = 0.5  # the lean correction is searched within +-this
BALANCE_TOLERANCE_M = 0.003  # a keyframe whose centre of mass is this close to where it is wanted is left alone


class Statics:
    """Robot-alone kinematics: a posture placed with its soles flat on z = 0."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.m = compose(robot, None, with_actuators=False)
        self.d = mujoco.MjData(self.m)
        self.idx = model_index(self.m, robot)
        self.soles = [mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_SITE, s) for s in robot.sole_sites]
        # a foot is everything from the ankle pitch joint down (the link between the ankle joints too)
        self.feet = {int(self.m.site_bodyid[s]) for s in self.soles}
        if robot.roles is not None:
            for side in ("left", "right"):
                ankle = robot.roles.by_role().get(f"{side}.ankle_pitch")
                if ankle is not None:
                    self.feet.add(int(self.m.jnt_bodyid[mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_JOINT, ankle.joint)]))
        root = self.idx.root_body
        self.foot_geoms = np.array([g for g in range(self.m.ngeom) if self._in_feet(int(self.m.geom_bodyid[g]))], dtype=int)
        self.other_geoms = np.array([g for g in range(self.m.ngeom) if g not in set(self.foot_geoms.tolist()) and self.m.geom_bodyid[g] != 0], dtype=int)
        self.root = root
        # "flat" is the sole site's frame aligned with the root's: a sole site is the stand frame
        # where its sole lies flat (robot import places it so at the neutral pose; for robots whose
        # soles are flat at the zero pose, as the OP3's, that is the zero pose's orientation)
        self.sole_zero = np.eye(3)

    def _in_feet(self, body: int) -> bool:
        while body > 0:
            if body in self.feet:
                return True
            body = int(self.m.body_parentid[body])
        return False

    def place(self, q: np.ndarray) -> None:
        """Joint angles ``q`` [rad], shape (n_joints,), with the soles flat on z = 0: the root turned
        so the first sole is as at the zero pose (a keyframe's joints may tilt the soles)."""
        self.d.qpos[self.idx.qpos_joints] = q
        place_on_soles(self.m, self.d, self.idx.qpos_root, self.soles, flat_sole_xmat=self.sole_zero)

    def points(self, g: int) -> np.ndarray:
        """World points bounding geom ``g``: a mesh's vertices, else the corners of its oriented bounding box."""
        d, m = self.d, self.m
        R = d.geom_xmat[g].reshape(3, 3)
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH and m.geom_dataid[g] >= 0:
            a, n = int(m.mesh_vertadr[m.geom_dataid[g]]), int(m.mesh_vertnum[m.geom_dataid[g]])
            local = m.mesh_vert[a : a + n].astype(float)
        else:
            c, h = m.geom_aabb[g, :3], m.geom_aabb[g, 3:]
            local = c + h * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
        return d.geom_xpos[g] + local @ R.T

    def lowest(self, geoms: np.ndarray) -> float:
        """Lowest point of the geoms [m] (see :meth:`points`)."""
        return float(min((self.points(int(g))[:, 2].min() for g in geoms), default=np.inf))

    def foot_length(self) -> float:
        """Length of the feet along x where they touch the ground [m] (call after :meth:`place` with the soles flat)."""
        pts = np.concatenate([self.points(int(g)) for g in self.foot_geoms])
        low = pts[pts[:, 2] < pts[:, 2].min() + 0.01]
        return float(low[:, 0].max() - low[:, 0].min())

    def self_contacts(self, q: np.ndarray) -> list[tuple[int, int]]:
        """Body pairs of the robot touching each other in posture ``q`` (robot alone)."""
        d, m = self.d, self.m
        d.qpos[self.idx.qpos_root] = [0, 0, 0, 1, 0, 0, 0]
        d.qpos[self.idx.qpos_joints] = q
        mujoco.mj_forward(m, d)
        return sorted({(int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])) for c in d.contact[: d.ncon]})

    def path_joints(self, a: int, b: int) -> list[int]:
        """Joint indices (into the robot's joint list) that move body ``a`` relative to body ``b``."""
        m = self.m

        def chain(x: int) -> list[int]:
            out = []
            while x > 0:
                out.append(x)
                x = int(m.body_parentid[x])
            return out

        ca, cb = chain(a), chain(b)
        common = set(ca) & set(cb)
        bodies = [x for x in ca + cb if x not in common]
        jnt_body = m.jnt_bodyid[[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in self.robot.joint_names]]
        return [i for i, jb in enumerate(jnt_body) if int(jb) in bodies]

    def com_offset_x(self) -> float:
        """CoM x minus the middle of the sole sites [m]."""
        mid = np.mean([self.d.site_xpos[s] for s in self.soles], axis=0)
        return float(self.d.subtree_com[self.root][0] - mid[0])


def balance_on_feet(
    robot: Robot,
    keyframes: tuple[tuple[float, Mapping[str, float]], ...],
    start: Mapping[str, float],
    *,
    from_keyframe: int = 0,
    targets: Sequence[float | None] | None = None,
) -> tuple[tuple[tuple[float, dict[str, float]], ...], list[str]]:
    """Lean each on-its-feet keyframe so the centre of mass is over the feet (see the module docstring).

    Args:
        keyframes: (time, joint goals) as a strategy maps onto the robot; goals not named hold.
        start: the joint angles before the first keyframe.
        from_keyframe: keyframes before this one are left alone (the lying-to-sitting phase, where
            soles flat on the ground would be a posture the robot is not in).
        targets: per keyframe, where the centre of mass is to be (ahead of the middle of the
            feet [m], soles flat), or None to leave it alone; a keyframe within
            ``BALANCE_TOLERANCE_M`` of its target is left alone. Default: over the middle of the
            feet for every keyframe from ``from_keyframe`` on that is on its feet alone.

    Returns:
        the keyframes with leaned hip and ankle pitch goals, and a note per changed keyframe.
    """
    roles = robot.roles
    if roles is None:
        return tuple((t, dict(g)) for t, g in keyframes), []
    by_role = roles.by_role()
    pitch = {side: (by_role.get(f"{side}.hip_pitch"), by_role.get(f"{side}.ankle_pitch")) for side in ("left", "right")}
    if any(h is None or a is None for h, a in pitch.values()):
        return tuple((t, dict(g)) for t, g in keyframes), ["no hip or ankle pitch: keyframes not balanced"]
    st = Statics(robot)
    names = robot.joint_names
    current = np.array([start.get(j, 0.0) for j in names])
    out, notes = [], []
    for i, (t, goals) in enumerate(keyframes):
        q = current.copy()
        for j, v in goals.items():
            q[names.index(j)] = v
        q = np.clip(q, robot.joint_lower, robot.joint_upper)
        st.place(q)
        new_goals = dict(goals)
        target = (0.0 if st.lowest(st.other_geoms) > FEET_ONLY_CLEARANCE_M else None) if targets is None else targets[i]
        if i >= from_keyframe and target is not None and abs(st.com_offset_x() - target) > BALANCE_TOLERANCE_M:

            def leaned(lean: float, q: np.ndarray = q) -> np.ndarray:
                ql = q.copy()
                for hip, ankle in pitch.values():
                    ql[names.index(hip.joint)] += -lean * hip.sign  # hip pitch role -lean: the torso forward
                    ql[names.index(ankle.joint)] += lean * ankle.sign
                return np.clip(ql, robot.joint_lower, robot.joint_upper)

            def offset(lean: float, target: float = target) -> float:
                st.place(leaned(lean))
                return st.com_offset_x() - target

            before = offset(0.0) + target
            try:
                lean = brentq(offset, -MAX_LEAN_RAD, MAX_LEAN_RAD, xtol=1e-3)
            except ValueError:
                lean = 0.0
            if abs(lean) > 1e-3:
                q = leaned(lean)
                for hip, ankle in pitch.values():
                    new_goals[hip.joint] = float(q[names.index(hip.joint)])
                    new_goals[ankle.joint] = float(q[names.index(ankle.joint)])
                notes.append(f"keyframe {i} (t {t:.2f} s) on its feet: CoM {1000 * before:+.0f} mm from the feet (wanted {1000 * target:+.0f}), leaned {np.degrees(lean):+.1f} deg")
        out.append((t, new_goals))
        current = q
    return tuple(out), notes


# --- the body adaptation: a small search over body-relative parameters, scored in MuJoCo -------------

ADAPT_MAX_PLAYS = 160  # nominal plays the search may spend per strategy (each ~0.1-0.5 s)
ADAPT_TIME_SCALES = (1.0, 1.5, 2.0, 3.0)  # the keyframe times are stretched by one of these (retiming then finds the timing)
# search box of the role offsets [rad]: (arm push: shoulder pitch, hip pitch, ankle pitch, knee) on the
# push keyframes, and the lean of the standing phase
ADAPT_BOX = {"arm": (-0.6, 1.2), "hip": (-0.8, 0.5), "ankle": (-0.8, 0.6), "knee": (-0.6, 0.3), "lean": (-0.15, 0.15)}
PARTS = ("foot", "hand", "other")


def _subtree_bodies(m: mujoco.MjModel, body: int) -> set[int]:
    out = {body}
    for b in range(m.nbody):
        p = b
        while p > 0 and p not in out:
            p = int(m.body_parentid[p])
        if p in out:
            out.add(b)
    return out


def body_parts(robot: Robot, m: mujoco.MjModel, geoms: np.ndarray) -> np.ndarray:
    """Per geom of ``geoms``: 0 foot (the ankle pitch joint's body and below, the sole sites' bodies),
    1 hand (the elbow's body and below; the shoulder pitch's where there is no elbow), 2 anything else."""
    by_role = robot.roles.by_role() if robot.roles is not None else {}

    def joint_body(role: str) -> int | None:
        j = by_role.get(role)
        return None if j is None else int(m.jnt_bodyid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j.joint)])

    feet: set[int] = {int(m.site_bodyid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s)]) for s in robot.sole_sites}
    hands: set[int] = set()
    for side in ("left", "right"):
        b = joint_body(f"{side}.ankle_pitch")
        if b is not None:
            feet.add(b)
        h = joint_body(f"{side}.elbow")
        if h is None:
            h = joint_body(f"{side}.shoulder_pitch")
        if h is not None:
            hands |= _subtree_bodies(m, h)
    feet = set().union(*(_subtree_bodies(m, b) for b in feet))
    out = np.full(len(geoms), 2, dtype=int)
    for i, g in enumerate(geoms):
        b = int(m.geom_bodyid[g])
        out[i] = 0 if b in feet else 1 if b in hands else 2
    return out


def support_phases(player: Player, start: Posture, keyframes: tuple[Keyframe, ...]) -> list[frozenset[str]]:
    """Which body parts (``foot``, ``hand``, ``other``) rest on the ground at each keyframe's time when
    ``keyframes`` are played as written on ``player``."""
    rec = player.play(build_trajectory(player.robot, start, keyframes))
    parts = body_parts(player.robot, player.model, player.index.robot_geoms)
    out = []
    for k in keyframes:
        i = min(int(np.searchsorted(rec.t, k.t_s)), len(rec.t) - 1)
        out.append(frozenset(PARTS[p] for p in parts[np.flatnonzero(rec.ground_contact[i])]))
    return out


def standing_phase(phases: list[frozenset[str]]) -> int | None:
    """Index of the first keyframe of the final run of keyframes supported on the feet alone (None: none is)."""
    i = len(phases)
    while i > 0 and phases[i - 1] == frozenset({"foot"}):
        i -= 1
    return i if i < len(phases) else None


@dataclass(frozen=True)
class Reference:
    """What the strategy does on the robot it was written for (the embedded robot, ``load_robot()``),
    the measure the adaptation matches on another body.

    Attributes:
        phases: per keyframe, the body parts on the ground when played as written (:func:`support_phases`).
        stand_from: first keyframe of the final run on the feet alone (None: never on its feet alone).
        com_ratio: per keyframe of that run, the centre of mass ahead of the middle of the feet
            with the soles flat, over the foot length (None elsewhere).
        self_contact: per keyframe, whether the posture touches itself.
        stands: the strategy stands there as written.
    """

    phases: tuple[frozenset[str], ...]
    stand_from: int | None
    com_ratio: tuple[float | None, ...]
    self_contact: tuple[bool, ...]
    stands: bool


def _postures(robot: Robot, keyframes: tuple[Keyframe, ...], start: Posture) -> list[np.ndarray]:
    names = robot.joint_names
    q = np.array([start.joints.get(j, 0.0) for j in names])
    out = []
    for k in keyframes:
        q = q.copy()
        for j, v in k.joints.items():
            q[names.index(j)] = v
        q = np.clip(q, robot.joint_lower, robot.joint_upper)
        out.append(q)
    return out


def _foot_length(st: Statics) -> float:
    st.place(np.asarray(st.robot.stand_qpos[7:], dtype=float))
    return st.foot_length()


def reference_statics(reference: Robot, keyframes: tuple[Keyframe, ...], start: Posture) -> Reference:
    """:class:`Reference` of a strategy on its own robot (``keyframes``, ``start``: the strategy on it, settled)."""
    player = Player(reference, "flat")
    stands = judge(player.play(build_trajectory(reference, start, keyframes))).standing
    phases = tuple(support_phases(player, start, keyframes))
    stand_from = standing_phase(list(phases)) if stands else None
    st = Statics(reference)
    foot = _foot_length(st)
    ratio: list[float | None] = []
    contact = []
    for i, q in enumerate(_postures(reference, keyframes, start)):
        contact.append(bool(st.self_contacts(q)))
        if stand_from is not None and i >= stand_from:
            st.place(q)
            ratio.append(st.com_offset_x() / foot)
        else:
            ratio.append(None)
    return Reference(phases, stand_from, tuple(ratio), tuple(contact), stands)


def fit_to_body(robot: Robot, keyframes: tuple[Keyframe, ...], start: Posture, ref: Reference, *, lean: float = 0.0) -> tuple[tuple[Keyframe, ...], list[str]]:
    """The statics part of the adaptation, a no-op on the strategy's own robot: each keyframe of the
    standing phase leaned so its centre of mass lies where it lies on the strategy's robot
    (relative to the foot length, within ``BALANCE_TOLERANCE_M``), then ``lean`` more (hip pitch
    -lean, ankle pitch +lean), and keyframes that make this body touch itself (where the strategy's
    robot does not) opened toward standing (:func:`collision_free`)."""
    st = Statics(robot)
    foot = _foot_length(st)
    targets = [None if r is None else r * foot for r in ref.com_ratio]
    raw = tuple((k.t_s, k.joints) for k in keyframes)
    balanced, notes = balance_on_feet(robot, raw, dict(start.joints), targets=targets)
    out = []
    current = dict(start.joints)
    for i, (t, goals) in enumerate(balanced):
        g = dict(goals)
        if ref.stand_from is not None and i >= ref.stand_from and lean != 0.0:
            g = _offset(robot, g, current, {"hip_pitch": -lean, "ankle_pitch": lean})
        current.update(g)
        out.append(Keyframe(t, g))
    free, more = collision_free(robot, tuple(out), start, st=st, keep=ref.self_contact)
    return free, notes + more


@dataclass(frozen=True)
class BodyAdaptation:
    """Body-relative changes to a strategy: its keyframe times stretched, role offsets [rad] on the push
    keyframes (the one before the standing phase and its first: where the body goes from its
    hands or knees onto its feet), a lean of the standing phase (hip pitch -lean, ankle pitch
    +lean: the hips back with the soles flat), and every standing-phase keyframe balanced over the feet."""

    time_scale: float = 1.0
    arm: float = 0.0
    hip: float = 0.0
    ankle: float = 0.0
    knee: float = 0.0
    lean: float = 0.0

    def describe(self) -> str:
        return (f"times x{self.time_scale:.2f}; push: shoulder pitch {self.arm:+.2f}, hip pitch {self.hip:+.2f}, "
                f"ankle pitch {self.ankle:+.2f}, knee {self.knee:+.2f} rad; standing lean {self.lean:+.2f} rad")


def _offset(robot: Robot, goals: Mapping[str, float], current: Mapping[str, float], offsets: Mapping[str, float]) -> dict[str, float]:
    by_role = robot.roles.by_role()
    out = dict(goals)
    for side in ("left", "right"):
        for role, d in offsets.items():
            j = by_role.get(f"{side}.{role}")
            if j is None or d == 0.0:
                continue
            out[j.joint] = float(out.get(j.joint, current[j.joint])) + j.sign * d
    return out


def apply_adaptation(robot: Robot, keyframes: tuple[Keyframe, ...], start: Posture, ref: Reference, a: BodyAdaptation) -> tuple[tuple[Keyframe, ...], list[str]]:
    """The keyframes with ``a`` applied: times stretched, the push offsets, then :func:`fit_to_body` with its lean."""
    stand_from = ref.stand_from if ref.stand_from is not None else len(keyframes)
    push = {max(stand_from - 1, 0), stand_from}
    current = dict(start.joints)
    raw: list[Keyframe] = []
    for i, k in enumerate(keyframes):
        goals = dict(k.joints)
        if i in push:
            goals = _offset(robot, goals, current, {"shoulder_pitch": a.arm, "hip_pitch": a.hip, "ankle_pitch": a.ankle, "knee": a.knee})
        current.update(goals)
        raw.append(Keyframe(round(k.t_s * a.time_scale, 3), goals))
    return fit_to_body(robot, tuple(raw), start, ref, lean=a.lean)


def collision_free(
    robot: Robot, keyframes: tuple[Keyframe, ...], start: Posture, *, st: Statics | None = None, keep: Sequence[bool] | None = None
) -> tuple[tuple[Keyframe, ...], list[str]]:
    """Keyframes whose postures make the robot touch itself, moved back toward the standing posture
    until they do not: for each touching pair of bodies, only the joints between them (a knee
    flexed so far that the shin meets the thigh opens; the hip and ankle of that leg with it), by
    the smallest blend found by bisection. A body's own stops are its joint limits; this finds the
    stops its shape adds (a collision mesh thicker than the strategy's robot's). Keyframes marked in
    ``keep`` are left as they are (the strategy's own robot touches itself there too: meant)."""
    st = st or Statics(robot)
    names = robot.joint_names
    stand = np.asarray(robot.stand_qpos[7:], dtype=float)
    current = np.array([start.joints.get(j, 0.0) for j in names])
    out, notes = [], []
    for i, k in enumerate(keyframes):
        q = current.copy()
        for j, v in k.joints.items():
            q[names.index(j)] = v
        q = np.clip(q, robot.joint_lower, robot.joint_upper)
        goals = dict(k.joints)
        for _ in range(0 if keep is not None and keep[i] else 4):
            pairs = st.self_contacts(q)
            if not pairs:
                break
            cols = sorted({c for a, b in pairs for c in st.path_joints(a, b)})
            if not cols:
                break
            lo_a, hi_a = 0.0, 1.0
            for _ in range(10):
                mid = 0.5 * (lo_a + hi_a)
                qt = q.copy()
                qt[cols] += mid * (stand[cols] - q[cols])
                if any(p in pairs for p in st.self_contacts(qt)):
                    lo_a = mid
                else:
                    hi_a = mid
            q[cols] += hi_a * (stand[cols] - q[cols])
            for c in cols:
                goals[names[c]] = float(q[c])
            notes.append(f"keyframe {i} (t {k.t_s:.2f} s): self contact, {', '.join(names[c] for c in cols)} {100 * hi_a:.0f} % toward standing")
        out.append(Keyframe(k.t_s, goals))
        current = q
    return tuple(out), notes


def _failure(v: StandVerdict, ratio_target: float = np.inf) -> str:
    """Why a play does not pass (empty: it does): not standing, self collision, torque over ``ratio_target``."""
    if not v.standing:
        return v.reason
    if v.self_collision:
        return "self collision"
    if v.peak_envelope_ratio > ratio_target:
        return f"peak torque/envelope {v.peak_envelope_ratio:.2f}"
    return ""


@dataclass(frozen=True)
class AdaptResult:
    """What :func:`adapt_to_body` found: the keyframes to time (None: nothing stood), the adaptation, plays spent, and why."""

    keyframes: tuple[Keyframe, ...] | None
    adaptation: BodyAdaptation | None
    plays: int
    note: str


def adapt_to_body(
    robot: Robot,
    keyframes: tuple[Keyframe, ...],
    start: Posture,
    players: Sequence[Player],
    ref: Reference,
    *,
    seed: int = 0,
    max_plays: int = ADAPT_MAX_PLAYS,
    ratio_target: float = RETIME_RATIO_TARGET,
) -> AdaptResult:
    """Adapt a strategy's keyframes to this body: the search of :class:`BodyAdaptation` parameters.

    Deterministic for a seed and bounded by ``max_plays`` nominal plays. The candidates are tried
    in this order: no offsets at each time scale of ``ADAPT_TIME_SCALES``, then random samples of
    the box ``ADAPT_BOX`` (half of them, once a candidate has got onto its feet, near the best one
    so far). A candidate is accepted when it stands without self collision within
    ``ratio_target`` of the torque envelope on the nominal player, then on every other player.

    Args:
        keyframes: the strategy on this robot (joint goals).
        start: the settled lying posture.
        players: nominal first, then the robustness corners.
        ref: the strategy on the robot it was written for (:func:`reference_statics`): its
            standing phase and push keyframes, where its centre of mass is.
    """
    stand_from = ref.stand_from
    if stand_from is None:
        return AdaptResult(None, None, 0, "the strategy never stands on its feet alone on the robot it was written for")
    rng = np.random.default_rng(seed)
    nominal = players[0]
    scales = ADAPT_TIME_SCALES
    names = ("arm", "hip", "ankle", "knee", "lean")
    lo = np.array([ADAPT_BOX[n][0] for n in names])
    hi = np.array([ADAPT_BOX[n][1] for n in names])
    tried = [BodyAdaptation(time_scale=s) for s in scales]
    best: tuple[float, BodyAdaptation] | None = None
    last = ""
    plays = 0
    while plays < max_plays:
        if tried:
            a = tried.pop(0)
        else:
            if best is not None and best[0] > 0.0 and rng.random() < 0.5:
                x0 = np.array([getattr(best[1], n) for n in names])
                x = np.clip(x0 + rng.normal(0.0, 0.12, len(names)) * (hi - lo) / 2, lo, hi)
                s = best[1].time_scale if rng.random() < 0.7 else float(rng.choice(scales))
            else:
                x = rng.uniform(lo, hi)
                s = float(rng.choice(scales))
            a = BodyAdaptation(s, *(round(float(v), 3) for v in x))
        kfs, _ = apply_adaptation(robot, keyframes, start, ref, a)
        tr = build_trajectory(robot, start, kfs)
        rec = nominal.play(tr)
        plays += 1
        v = judge(rec)
        if v.standing and not v.self_collision:
            if v.peak_envelope_ratio > ratio_target:
                score = 5.0 - v.peak_envelope_ratio
                last = f"{a.describe()}: stands, peak torque/envelope {v.peak_envelope_ratio:.2f}"
            else:
                others = [judge(p.play(tr)) for p in players[1:]]
                bad = [f"{i + 1}: {_failure(o, ratio_target)}" for i, o in enumerate(others) if _failure(o, ratio_target)]
                if not bad:
                    return AdaptResult(kfs, a, plays, f"{a.describe()} ({plays} plays)")
                last = f"{a.describe()}: stands nominally, not on corners " + "; ".join(bad)
                score = 10.0 - len(bad)
        else:
            # how far it got: the best torso height (fraction of stand) on its feet alone after the push
            after = rec.t > kfs[stand_from].t_s - 1e-9
            on = rec.on_feet & after
            score = float(np.max(np.where(on, rec.torso_height_m / rec.stand_height_m, 0.0), initial=0.0)) - 0.5 * v.self_collision
            last = last or v.reason or "self collision"
        if best is None or score > best[0]:
            best = (score, a)
    why = f"best: {best[1].describe()}" if best is not None else ""
    return AdaptResult(None, None, plays, f"no adaptation stood within {max_plays} plays ({last}; {why})")
