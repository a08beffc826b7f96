"""Violations of a played motion: the windows where torque, balance or tracking broke a limit.

Torque beyond (1 - margin) of the torque-speed envelope (dissertation 003 eq. 2.2 strength
limits; for us the DC-motor envelope), the ZMP outside the support polygon while on the feet
(003 eq. 2.11-2.14), and the motion diverging from its targets (tracking error beyond the
servo's saturation for longer than ``divergence_hold_s``: a roll that does not happen, a limb
blocked). The filter reshapes the motion around these windows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_rise.proof.config import ProofConfig
from robot_rise.model import Robot
from robot_rise.sim.player import Recording
from robot_rise.sim.standing import supported_on_feet

__all__ = ["Violation", "find_violations", "saturation_rad", "true_runs"]


@dataclass(frozen=True)
class Violation:
    """One offending window of the played motion. Times on the trajectory's clock [s]."""

    kind: str  # "torque" | "balance" | "divergence" | "fall"
    t_start_s: float
    t_end_s: float
    joints: tuple[str, ...] = ()
    value: float = float("nan")

    def describe(self) -> str:
        where = f" ({', '.join(self.joints)})" if self.joints else ""
        return f"{self.kind}{where} at {self.t_start_s:.2f}-{self.t_end_s:.2f} s, value {self.value:.3f}"


def true_runs(mask: np.ndarray, t: np.ndarray, min_len_s: float = 0.0) -> list[tuple[int, int]]:
    """Index ranges [i, j] of contiguous True runs of ``mask`` lasting at least ``min_len_s`` on the clock ``t`` [s]."""
    out = []
    i = 0
    n = len(mask)
    while i < n:
        if mask[i]:
            j = i
            while j + 1 < n and mask[j + 1]:
                j += 1
            if t[j] - t[i] >= min_len_s - 1e-9:
                out.append((i, j))
            i = j + 1
        else:
            i += 1
    return out


def find_violations(rec: Recording, config: ProofConfig, *, saturation_rad: float) -> list[Violation]:
    """Violations in a recording (times on the recording's clock = the trajectory's)."""
    out: list[Violation] = []
    t = rec.t
    limit = 1.0 - config.envelope_margin
    over = rec.envelope_ratio > limit
    for i, j in true_runs(over.any(axis=1), t):
        joints = tuple(rec.joint_names[k] for k in np.flatnonzero(over[i : j + 1].any(axis=0)))
        out.append(Violation("torque", float(t[i]), float(t[j]), joints, float(rec.envelope_ratio[i : j + 1].max())))
    on = supported_on_feet(rec) & np.isfinite(rec.zmp_margin_m)
    bad = on & (np.nan_to_num(rec.zmp_margin_m, nan=1.0) < config.min_zmp_margin_m - config.balance_tolerance_m)
    for i, j in true_runs(bad, t, config.balance_hold_s):
        out.append(Violation("balance", float(t[i]), float(t[j]), (), float(np.nanmin(rec.zmp_margin_m[i : j + 1]))))
    err = np.abs(rec.q - rec.goal)
    div = err > max(config.divergence_rad, 1.5 * saturation_rad)
    for i, j in true_runs(div.any(axis=1), t, config.divergence_hold_s):
        joints = tuple(rec.joint_names[k] for k in np.flatnonzero(div[i : j + 1].any(axis=0)))
        out.append(Violation("divergence", float(t[i]), float(t[j]), joints, float(err[i : j + 1].max())))
    return out


def saturation_rad(robot: Robot) -> float:
    """The smallest saturation error of the robot's servos [rad] (the divergence floor of :func:`find_violations`)."""
    return min(sheet.saturation_error_rad() for sheet in robot.servo_datasheets())
