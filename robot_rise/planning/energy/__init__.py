"""Energy-driven planning between two distant postures (paper 004, Wang, Ho & Komura 2015).

One idea per module, each from the paper section named beside it:

- ``config``: ``EnergyConfig`` (the energy, Algorithms 1-2 and the steps after them) and
  ``SecondStageConfig`` (section 6.2); every default in robot_rise/constants.py.
- ``tangent``: the chart: MuJoCo's tangent space with the root translation scaled
  (``tangent_difference``, ``tangent_step``, ``tangent_scale``, ``resample_path``).
- ``capsules``: the robot's links and the scene as capsules, boxes and half-spaces, and the
  exact segment distances between them (section 4.1's shortest distances between links).
- ``repulsive``: ``RepulsiveEnergy``, E = E_int + E_ext (section 4.1, eq. 1-2) over the robot's
  links as capsules, with its analytic gradient.
- ``gli``: the Gauss linking integral between the five linkages of Fig. 8 (section 5.2.2,
  eq. 7-8), the measure of the safe zone.
- ``constraints``: constrained steps by null-space projection (section 6.1, Algorithm 2,
  eq. 9-13: joint limits and positional constraints such as a hand kept on the ground), the
  touched ground as automatic positional constraints.
- ``window``: ``EnergyWindow``, the local-minimum detector of section 8.
- ``interpolate``: ``energy_interpolate``, energy-descent bidirectional interpolation
  (section 5.1, Algorithm 1) with the safe zone of the Gauss linking integral (section 5.2.2,
  eq. 7-8).
- ``keyframes``: ``safe_zone_keyframes``, the output of each leg reduced to its key postures,
  consecutive ones in one safe subspace (section 5.2: eq. 8 below the threshold and a legal
  straight motion), instead of every alpha step (Algorithm 1's direct and projected steps
  zig-zag at the step scale).
- ``straighten``: ``straighten_limbs``, the root and each linkage of Fig. 8 that the key postures
  move and bring back without need (section 5.1's "unnecessary expansion") put on its straight
  motion where that is legal (ours).
- ``projection``: ``second_stage``, the section 6.2 projection of the motion (eq. 14, 19-20 with
  M = I).
- ``dense``: ``dense_output``, the second stage's motion written out densely for the shared timing.
- ``deadline``: the refinement steps' wall-clock deadline.
- ``planner``: ``plan_energy`` and ``EnergyPlanner``, the planner behind the shared interface.

Every segment (straight motion between two postures) is checked by the shared segment checker,
robot_rise.planning.motion_validator, at ``EnergyConfig.verify_resolution_m``.
"""

from robot_rise.constants import FALLOFF_RETRY_SCHEDULE, GROUND_CONTACT_ZONE_M
from robot_rise.planning.energy.config import EnergyConfig, SecondStageConfig
from robot_rise.planning.energy.constraints import PositionalConstraint
from robot_rise.planning.energy.dense import dense_output
from robot_rise.planning.energy.interpolate import InterpolationOutcome, energy_interpolate
from robot_rise.planning.energy.keyframes import safe_zone_keyframes
from robot_rise.planning.energy.planner import EnergyPlanner, plan_energy
from robot_rise.planning.energy.projection import second_stage, trajectory_laplacian_energy
from robot_rise.planning.energy.repulsive import EnergyValue, RepulsiveEnergy
from robot_rise.planning.energy.straighten import straighten_limbs
from robot_rise.planning.energy.tangent import resample_path, tangent_difference, tangent_scale, tangent_step
from robot_rise.planning.energy.window import EnergyWindow

__all__ = [
    "EnergyConfig",
    "SecondStageConfig",
    "EnergyValue",
    "RepulsiveEnergy",
    "PositionalConstraint",
    "EnergyWindow",
    "InterpolationOutcome",
    "energy_interpolate",
    "plan_energy",
    "EnergyPlanner",
    "FALLOFF_RETRY_SCHEDULE",
    "GROUND_CONTACT_ZONE_M",
    "safe_zone_keyframes",
    "straighten_limbs",
    "tangent_difference",
    "tangent_step",
    "tangent_scale",
    "second_stage",
    "resample_path",
    "trajectory_laplacian_energy",
    "dense_output",
]
