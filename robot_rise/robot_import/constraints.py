"""Closed linkages and coupled joints of an imported model: which hinges the servos drive, which the constraints move.

A model closes loops with equality constraints (``connect`` / ``weld`` between two bodies: a
four-bar knee, a parallel neck), couples joints (``joint`` with ``polycoef``, a URDF ``mimic``)
and routes tendons (a waist differential with a ``tendon`` equality). The servo map names the
joints the servos drive; every other hinge must be one the constraints move (passive), and is
kept out of the servo model and the roles. Without a servo map (a template), the driven joints
are those the file actuates, else every constrained hinge but a coupling's follower and the
loop joints off the limbs' main chains.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import mujoco

from robot_rise.errors import ConfigError

__all__ = ["Constrained", "constrained_joints", "passive_joints"]


@dataclass(frozen=True)
class Constrained:
    """The hinges a model's constraints involve (joint ids), by how."""

    loop: frozenset[int]  # on the tree path between the two bodies of a connect or weld
    follower: frozenset[int]  # joint1 of a joint coupling (it follows joint2), the joints of a coupling's tendon1
    coupled: frozenset[int]  # joint2 of a coupling, the joints of its tendon2

    @property
    def all(self) -> frozenset[int]:
        return self.loop | self.follower | self.coupled


def _path_joints(m: mujoco.MjModel, a: int, b: int) -> set[int]:
    """Hinges on the tree path between bodies ``a`` and ``b`` (through their common ancestor)."""

    def chain(body: int) -> list[int]:
        out = [body]
        while body != 0:
            body = int(m.body_parentid[body])
            out.append(body)
        return out

    ca, cb = chain(a), chain(b)
    common = next(x for x in ca if x in cb)
    bodies = ca[: ca.index(common)] + cb[: cb.index(common)]
    return {
        j for body in bodies for j in range(m.body_jntadr[body], m.body_jntadr[body] + m.body_jntnum[body])
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    }  # fmt: skip


def constrained_joints(m: mujoco.MjModel) -> Constrained:
    """The hinges each kind of equality constraint involves."""
    loop: set[int] = set()
    follower: set[int] = set()
    coupled: set[int] = set()
    for e in range(m.neq):
        kind, a, b = int(m.eq_type[e]), int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
        if kind in (mujoco.mjtEq.mjEQ_CONNECT, mujoco.mjtEq.mjEQ_WELD):
            if int(m.eq_objtype[e]) == mujoco.mjtObj.mjOBJ_SITE:
                a, b = int(m.site_bodyid[a]), int(m.site_bodyid[b])
            loop |= _path_joints(m, a, max(b, 0))
        elif kind == mujoco.mjtEq.mjEQ_JOINT:
            follower.add(a)
            if b >= 0:
                coupled.add(b)
        elif kind == mujoco.mjtEq.mjEQ_TENDON:  # tendon1's joints follow tendon2's
            for t, group in ((a, follower), (b, coupled)):
                if t < 0:
                    continue
                for w in range(m.tendon_adr[t], m.tendon_adr[t] + m.tendon_num[t]):
                    if m.wrap_type[w] == mujoco.mjtWrap.mjWRAP_JOINT:
                        group.add(int(m.wrap_objid[w]))
    hinge = {j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE}
    return Constrained(frozenset(loop & hinge), frozenset(follower & hinge), frozenset(coupled & hinge))


def passive_joints(
    m: mujoco.MjModel, servo_joints: Iterable[str] | None, actuated: Iterable[str], main_chains: Iterable[int], source: str
) -> tuple[tuple[str, ...], list[str]]:
    """The hinges the constraints move (names, model order) and a note on each decision.

    Args:
        m: the model.
        servo_joints: the joints the user's servo map drives (None for a template servo map).
        actuated: joints the file itself puts actuators on.
        main_chains: joint ids on the limbs' main chains (from the trunk to each limb's tip).
        source: the file, for messages.

    Raises:
        ConfigError: a hinge has no servo and no constraint moves it.
    """
    hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    cons = constrained_joints(m)
    if servo_joints is not None:
        driven = set(servo_joints)
        passive = [j for j in hinges if m.joint(j).name not in driven]
        free = [m.joint(j).name for j in passive if j not in cons.all]
        if free:
            raise ConfigError(
                f"{source}: joints with no servo in the servo map that no constraint moves: {', '.join(free)}",
                hint="give them a servo, or close their linkage with an equality constraint in the model",
            )
        how = "the servo map drives the others"
    elif not cons.all:
        return (), []
    else:
        acted = set(actuated)
        if acted:
            passive = [j for j in cons.all if m.joint(j).name not in acted]
            how = "the file actuates the others"
        else:
            chains = set(main_chains)
            passive = [j for j in cons.all if j in cons.follower or (j in cons.loop and j not in chains)]
            how = "couplings' followers and loop joints off the limbs' main chains; the others driven"
    names = tuple(m.joint(j).name for j in sorted(set(passive)))
    if not names:
        return (), []
    kinds = []
    for label, group in (("closed loops", cons.loop), ("joint couplings", cons.follower | cons.coupled)):
        hit = [m.joint(j).name for j in sorted(set(passive) & group)]
        if hit:
            kinds.append(f"{label}: {', '.join(hit)}")
    return names, [f"passive joints (moved by the model's constraints, no servo; {how}): {'; '.join(kinds) or ', '.join(names)}"]
