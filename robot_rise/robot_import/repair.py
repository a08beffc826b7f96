"""Physics a CAD export gets wrong, fixed the way MuJoCo's own messages suggest, each fix reported.

- An inertia that breaks the triangle inequality (A + B >= C for the principal moments): MuJoCo's
  ``balanceinertia`` (the three moments set to their mean, the trace kept).
- A mesh whose volume is too small for MuJoCo to compute its inertia (a visual shell, a flat
  plate): shell inertia for that mesh, as MuJoCo's message asks.
- A moving link with no mass (a servo horn frame, a dummy wrist link that carries a joint): a mass
  floor of ``MASS_FLOOR_KG`` with the inertia of a small sphere.

The fixes are found both ways: before compiling, from what the spec declares (so that each
names its body), then from MuJoCo's compile errors until the model compiles. The total mass
before and after is reported so the user sees what the fixes cost (the import issue's bar: 1 %).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_rise.errors import ConfigError, mujoco_reason

__all__ = ["PhysicsRepair", "repair_physics", "MASS_FLOOR_KG", "MASS_KEPT_TOLERANCE"]

MASS_FLOOR_KG = 1e-3  # a moving link lighter than 1 g gets 1 g: a servo horn, a bracket at most weighs that
_FLOOR_INERTIA_KG_M2 = 0.4 * MASS_FLOOR_KG * 0.01**2  # a 1 g sphere of 1 cm radius: 2/5 m r^2
MASS_KEPT_TOLERANCE = 0.01  # the import issue: the body's mass within 1 % of what the file declares
_MAX_ROUNDS = 200  # compile-and-fix rounds (one fix per round): more than any model has meshes


@dataclass(frozen=True)
class PhysicsRepair:
    """What was fixed: one note per fix (naming the body or mesh), and the mass it cost.

    Attributes:
        notes: one line per fix.
        declared_mass_kg: the links' masses as the file declares them (explicit inertials), or the
            model's mass before any fix where it compiles as it is.
        mass_kg: the mass of the fixed model.
    """

    notes: tuple[str, ...]
    declared_mass_kg: float
    mass_kg: float

    @property
    def mass_change(self) -> float:
        """Relative change of the total mass (0.004 for +0.4 %)."""
        return (self.mass_kg - self.declared_mass_kg) / self.declared_mass_kg if self.declared_mass_kg > 0 else 0.0


def _principal_moments(body: mujoco.MjsBody) -> np.ndarray | None:
    full = np.asarray(body.fullinertia, dtype=float)
    if np.all(np.isfinite(full)) and np.any(full[:3] != 0):
        xx, yy, zz, xy, xz, yz = full
        return np.linalg.eigvalsh(np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]))
    diag = np.asarray(body.inertia, dtype=float)
    return np.sort(diag) if np.all(np.isfinite(diag)) else None


def _is_moving(body: mujoco.MjsBody) -> bool:
    return len(body.joints) > 0 or any(j.type == mujoco.mjtJoint.mjJNT_FREE for j in body.joints)


def _welded_mass(body: mujoco.MjsBody) -> float:
    """The body's declared mass and its jointless descendants' (MuJoCo moves them as one)."""
    total = float(body.mass) if np.isfinite(body.mass) else 0.0
    for child in body.bodies:
        if not child.joints:
            total += _welded_mass(child)
    return total


def _floor_mass(body: mujoco.MjsBody) -> None:
    body.mass = MASS_FLOOR_KG
    body.fullinertia = [np.nan] * 6
    body.inertia = [_FLOOR_INERTIA_KG_M2] * 3
    body.explicitinertial = True


def _label(el: mujoco.MjsBody | mujoco.MjsMesh, index: int) -> str:
    return repr(el.name) if el.name else f"#{index} (unnamed)"


def _declared_mass(spec: mujoco.MjSpec) -> float:
    try:
        return float(spec.copy().compile().body_mass.sum())
    except Exception:  # noqa: BLE001 (it may not compile before the fixes: sum what the file declares)
        return float(sum(b.mass for b in spec.bodies if b.explicitinertial and np.isfinite(b.mass)))


def repair_physics(spec: mujoco.MjSpec, source: str) -> tuple[mujoco.MjModel, PhysicsRepair]:
    """Fix the spec in place until it compiles; the compiled model and what was fixed.

    Args:
        spec: the robot (its floating base already given).
        source: the file, for messages.

    Raises:
        ConfigError: it still does not compile (one line: MuJoCo's reason, the file, the element).
    """
    declared = _declared_mass(spec)
    notes: list[str] = []
    bodies = list(spec.bodies)
    unbalanced = []
    for i, body in enumerate(bodies):
        if not body.explicitinertial:
            continue
        moments = _principal_moments(body)
        if moments is not None and moments[0] + moments[1] < moments[2] * (1.0 - 1e-9) and moments[2] > 0:
            unbalanced.append(f"{_label(body, i)} ({', '.join(f'{v:.3g}' for v in moments)} kg m^2)")
    if unbalanced:
        spec.compiler.balanceinertia = True
        notes.append(f"inertia breaks the triangle inequality, balanced (MuJoCo's balanceinertia): {'; '.join(unbalanced)}")
    for i, body in enumerate(bodies[1:], start=1):
        if _is_moving(body) and _welded_mass(body) < MASS_FLOOR_KG * 1e-3 and body.explicitinertial:
            _floor_mass(body)
            notes.append(f"body {_label(body, i)} moves on a joint with no mass: mass floor {MASS_FLOOR_KG * 1e3:g} g")
    for _ in range(_MAX_ROUNDS):
        try:
            model = spec.compile()
            break
        except Exception as e:  # mujoco raises ValueError with its message
            reason = mujoco_reason(e)
            if not _fix_from_error(spec, str(e), notes):
                raise ConfigError(f"{source}: does not compile: {reason}") from e
    else:  # pragma: no cover (more rounds than meshes and bodies)
        raise ConfigError(f"{source}: does not compile after {_MAX_ROUNDS} fixes")
    return model, PhysicsRepair(tuple(notes), declared, float(model.body_mass.sum()))


def _element(message: str) -> tuple[str, int]:
    m = re.search(r"Element name '([^']*)', id (\d+)", message)
    return (m.group(1), int(m.group(2))) if m else ("", -1)


def _fix_from_error(spec: mujoco.MjSpec, message: str, notes: list[str]) -> bool:
    """Apply the fix MuJoCo's message asks for; False if it asks for none we know."""
    name, index = _element(message)
    if "mesh volume is too small" in message or "Try setting inertia to shell" in message:
        meshes = list(spec.meshes)
        mesh = next((me for me in meshes if name and me.name == name), meshes[index] if 0 <= index < len(meshes) else None)
        if mesh is None or mesh.inertia == mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL:
            return False
        mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
        notes.append(f"mesh {_label(mesh, index)}: volume too small for a solid's inertia, shell inertia (as MuJoCo suggests)")
        return True
    if "balanceinertia" in message:
        if spec.compiler.balanceinertia:
            return False
        spec.compiler.balanceinertia = True
        notes.append(f"inertia of body {name or '#' + str(index)} breaks the triangle inequality, balanced (MuJoCo's balanceinertia)")
        return True
    if "mass and inertia of moving bodies" in message:
        bodies = list(spec.bodies)
        body = next((b for b in bodies if name and b.name == name), bodies[index] if 0 <= index < len(bodies) else None)
        if body is None:
            return False
        if body.explicitinertial and np.isfinite(body.mass) and body.mass >= MASS_FLOOR_KG:
            moments = _principal_moments(body)
            if moments is not None and moments[0] >= _FLOOR_INERTIA_KG_M2:
                return False
            mass = float(body.mass)  # its mass kept, its inertia floored
            _floor_mass(body)
            body.mass = mass
            notes.append(f"body {_label(body, index)} has a mass but no inertia: inertia floor {_FLOOR_INERTIA_KG_M2:.1e} kg m^2")
            return True
        _floor_mass(body)
        notes.append(f"body {_label(body, index)} moves with no mass or inertia: mass floor {MASS_FLOOR_KG * 1e3:g} g")
        return True
    return False
