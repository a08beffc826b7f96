"""Robot import: a robot directory from a model file as its team published it (MJCF, URDF or xacro).

- :mod:`~robot_rise.robot_import.roles` -- limbs from the kinematic tree, joint roles, signs and
  neutral angles from the joint axes (``infer_roles``).
- :mod:`~robot_rise.robot_import.stand` -- the standing posture search (``stand_candidates``).
- :mod:`~robot_rise.robot_import.mjcf` -- ``import_robot``: strip, fill ranges, add sites, find
  the stand, write the directory atomically.
"""

from robot_rise.robot_import.mjcf import ImportResult, import_robot
from robot_rise.robot_import.roles import InferredRoles, infer_roles
from robot_rise.robot_import.stand import stand_candidates

__all__ = ["ImportResult", "InferredRoles", "import_robot", "infer_roles", "stand_candidates"]
