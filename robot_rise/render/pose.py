"""The robot posed at one recording sample: the model's rest qpos with that sample's root pose and joint angles.

Nothing here simulates: with a scene of static geoms, the root pose and joint angles of a
:class:`~robot_rise.sim.Recording` sample are the whole qpos. Callers run the kinematics they
need afterwards (``mj_kinematics`` for frames and geometry, ``mj_forward`` for the viewer).
"""

from __future__ import annotations

import mujoco

from robot_rise.model import ModelIndex
from robot_rise.sim.player import Recording

__all__ = ["pose_sample"]


def pose_sample(m: mujoco.MjModel, d: mujoco.MjData, index: ModelIndex, rec: Recording, k: int) -> None:
    """Set ``d.qpos`` to sample ``k`` of ``rec`` in model ``m`` (indexed by ``index``); kinematics not run.

    Every other qpos entry is reset to ``m.qpos0``, so the pose depends on ``k`` alone.
    """
    d.qpos[:] = m.qpos0
    d.qpos[index.qpos_root] = rec.root_pose[k]
    d.qpos[index.qpos_joints] = rec.q[k]
