"""Joint roles: the robot-independent names motions are written in, and the one conversion to joints.

A role is a place in a humanoid's body ("left.knee", "head.pan"), not a joint name. Each joint a
robot has gets a role (or ``extra``: held where the standing posture has it), a sign and a
neutral angle, so that a role value means the same movement on every robot:

    q_joint = neutral + sign * role_value                                   [rad]

Role frame (stand frame: x forward, y left, z up; the neutral pose is every limb hanging
straight down, the head level). Left and right are mirror images, so a symmetric posture has equal
left and right role values:
- pitch roles (shoulder_pitch, hip_pitch, knee, ankle_pitch, head.tilt): positive turns about +y:
  a limb below the joint swings backward (knee: flexion; hip: extension; ankle: toes down;
  shoulder: arm back; head: nod down).
- roll roles (shoulder_roll, hip_roll, ankle_roll): positive moves the limb away from the
  midline (abduction).
- yaw roles (hip_yaw, head.pan): positive turns the toes outward (head: look left).
- elbow: positive flexes (the hand moves forward or, for a sideways elbow, inward).

Robots list their roles in ``robot.toml`` (``[roles]``: joint = {role, sign, neutral}); the
robot import infers them (:mod:`robot_rise.robot_import.roles`) and people correct them there.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["SIDES", "LIMB_ROLES", "HEAD_ROLES", "ROLES", "EXTRA", "JointRole", "RoleMap", "mirror_role_values"]

SIDES = ("left", "right")
LIMB_ROLES = (
    "shoulder_pitch", "shoulder_roll", "elbow",
    "hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll",
)  # fmt: skip
HEAD_ROLES = ("head.pan", "head.tilt")
ROLES: tuple[str, ...] = tuple(f"{side}.{r}" for side in SIDES for r in LIMB_ROLES) + HEAD_ROLES
EXTRA = "extra"  # a joint outside the vocabulary: held at its standing angle by every strategy


@dataclass(frozen=True)
class JointRole:
    """One joint's role: ``q = neutral_rad + sign * role_value``."""

    joint: str
    role: str
    sign: int
    neutral_rad: float

    def __post_init__(self) -> None:
        if self.role != EXTRA and self.role not in ROLES:
            raise ValueError(f"joint {self.joint}: unknown role {self.role!r}; roles: {', '.join(ROLES)}, {EXTRA}")
        if self.sign not in (-1, 1):
            raise ValueError(f"joint {self.joint}: sign must be 1 or -1, not {self.sign}")


@dataclass(frozen=True)
class RoleMap:
    """The roles of a robot's joints (each role at most once; ``extra`` any number of times)."""

    joints: tuple[JointRole, ...]

    def __post_init__(self) -> None:
        seen: dict[str, str] = {}
        for j in self.joints:
            if j.role != EXTRA and j.role in seen:
                raise ValueError(f"role {j.role} is given to both {seen[j.role]} and {j.joint}")
            seen[j.role] = j.joint

    def by_role(self) -> dict[str, JointRole]:
        return {j.role: j for j in self.joints if j.role != EXTRA}

    def missing_roles(self) -> tuple[str, ...]:
        """Roles of the vocabulary this robot has no joint for (e.g. no shoulder roll)."""
        have = self.by_role()
        return tuple(r for r in ROLES if r not in have)

    def joint_goals(self, role_values: Mapping[str, float]) -> dict[str, float]:
        """Joint goals [rad] for role values; roles this robot lacks are skipped."""
        have = self.by_role()
        out: dict[str, float] = {}
        for role, value in role_values.items():
            if role not in ROLES:
                raise ValueError(f"unknown role {role!r}; roles: {', '.join(ROLES)}")
            j = have.get(role)
            if j is not None:
                out[j.joint] = j.neutral_rad + j.sign * float(value)
        return out

    def role_values(self, joint_angles: Mapping[str, float]) -> dict[str, float]:
        """Role values of joint angles [rad] (joints with role ``extra`` are left out)."""
        out: dict[str, float] = {}
        for j in self.joints:
            if j.role != EXTRA and j.joint in joint_angles:
                out[j.role] = j.sign * (float(joint_angles[j.joint]) - j.neutral_rad)
        return out


def mirror_role_values(values: Mapping[str, float]) -> dict[str, float]:
    """The mirror image (left <-> right) of role values: sides swap, head pan changes sign."""
    out: dict[str, float] = {}
    for role, v in values.items():
        side, _, rest = role.partition(".")
        if side in SIDES:
            out[f"{SIDES[1 - SIDES.index(side)]}.{rest}"] = float(v)
        elif role == "head.pan":
            out[role] = -float(v)
        else:
            out[role] = float(v)
    return out
