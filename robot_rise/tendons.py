"""A robot's tendons (and the tendon couplings naming them) carried across its attachment to a scene.

A scene is composed by attaching the robot's root body under a prefix that is then stripped; a
tendon wrap's target cannot be renamed once attached, so the robot's tendons are taken out
before and made again after, by name (``robot_rise.model.compose``).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

__all__ = ["detach_tendons", "attach_tendons"]


@dataclass(frozen=True)
class _Tendon:
    """A tendon of the robot file, kept by name across composition (a wrap's target cannot be
    renamed once attached, so tendons are taken out before and made again after)."""

    name: str
    wraps: tuple[tuple[str, str, float, str], ...]  # (kind, target name, coef or divisor, side site)
    settings: dict[str, object]


_TENDON_SETTINGS = ("stiffness", "damping", "frictionloss", "armature", "margin", "width", "springlength", "range", "limited", "rgba", "group")


def detach_tendons(spec: mujoco.MjSpec) -> tuple[list[_Tendon], list[dict[str, object]]]:
    """Take the tendons out of the robot's spec, and the tendon couplings that name them."""
    couplings = []
    for eq in list(spec.equalities):
        if eq.type == mujoco.mjtEq.mjEQ_TENDON:
            couplings.append({k: getattr(eq, k) for k in ("name", "name1", "name2", "data", "solref", "solimp", "active")})
            spec.delete(eq)
    out = []
    for t in list(spec.tendons):
        wraps = []
        for k in range(len(t.path)):
            w = t.path[k]
            target = w.target
            kind = {mujoco.mjtWrap.mjWRAP_JOINT: "joint", mujoco.mjtWrap.mjWRAP_SITE: "site", mujoco.mjtWrap.mjWRAP_PULLEY: "pulley"}.get(
                w.type, "geom"
            )
            weight = float(w.coef) if kind == "joint" else float(w.divisor) if kind == "pulley" else 0.0
            wraps.append((kind, target.name if target is not None else "", weight, w.sidesite.name if getattr(w, "sidesite", None) is not None else ""))
        settings = {k: getattr(t, k) for k in _TENDON_SETTINGS if hasattr(t, k)}
        out.append(_Tendon(t.name, tuple(wraps), settings))
        spec.delete(t)
    return out, couplings


def attach_tendons(spec: mujoco.MjSpec, detached: tuple[list[_Tendon], list[dict[str, object]]]) -> None:
    tendons, couplings = detached
    for tendon in tendons:
        t = spec.add_tendon()
        t.name = tendon.name
        for k, v in tendon.settings.items():
            setattr(t, k, v)
        for kind, target, weight, side in tendon.wraps:
            if kind == "joint":
                t.wrap_joint(target, weight)
            elif kind == "site":
                t.wrap_site(target)
            elif kind == "pulley":
                t.wrap_pulley(weight)
            else:
                t.wrap_geom(target, side)
    for coupling in couplings:
        eq = spec.add_equality()
        eq.type = mujoco.mjtEq.mjEQ_TENDON
        eq.objtype = mujoco.mjtObj.mjOBJ_TENDON
        for k, v in coupling.items():
            setattr(eq, k, v)
