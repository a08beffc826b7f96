"""Robot import: a robot directory from a model file as its team published it (MJCF, URDF or xacro).

- :mod:`~robot_rise.robot_import.source` -- ``read_model``: the file into a spec, every file it
  names found (ROS packages, xacro, case), MuJoCo's reason in one line.
- :mod:`~robot_rise.robot_import.repair` -- ``repair_physics``: what a CAD export gets wrong.
- :mod:`~robot_rise.robot_import.limits` -- ``joint_ranges``: the model's and the servo map's, reconciled.
- :mod:`~robot_rise.robot_import.roles` -- limbs through fixed links, joint roles, signs and
  neutral angles from the joint axes (``infer_roles``).
- :mod:`~robot_rise.robot_import.stand` -- the standing posture search (``stand_candidates``).
- :mod:`~robot_rise.robot_import.importer` -- ``import_robot``: the steps in order, the
  directory written atomically.
"""

from robot_rise.robot_import.importer import ImportResult, import_robot
from robot_rise.robot_import.roles import InferredRoles, infer_roles
from robot_rise.robot_import.source import ModelSource, read_model
from robot_rise.robot_import.stand import stand_candidates

__all__ = ["ImportResult", "InferredRoles", "ModelSource", "import_robot", "infer_roles", "read_model", "stand_candidates"]
