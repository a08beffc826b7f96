"""robot_rise: get a Dynamixel-servo humanoid up from any lying posture, proven in MuJoCo.

The public face. A robot directory (MJCF + ``robot.toml`` + ``servos.toml``) loads into a
:class:`Robot`; a lying :class:`Posture` rises into a :class:`Trajectory` of servo targets whose
:class:`Proof` says whether, and how well, it stands. SI units and radians throughout::

    import robot_rise as rr

    robot = rr.load_robot()                      # the embedded OP3-class robot
    lying = rr.sample_lying_postures(robot, "supine", 1, seed=0)[0]
    result = rr.rise(robot, lying)               # select, plan, filter, prove
    print(result.proven, result.proof.duration_s)
    rr.write_trajectory("getup.json", result.trajectory)
    assert rr.check(robot, rr.read_trajectory("getup.json")).proven

Streaming a trajectory to servos lives in the sibling package ``drivers`` (``DynamixelBus``,
``Executor``); the ``robot-rise`` command wires the two.
"""

from robot_rise.errors import RobotRiseError
from robot_rise.proof import Proof, ProofConfig, check
from robot_rise.model import Robot, load_robot
from robot_rise.posture import Posture, read_posture, write_posture
from robot_rise.rise import RiseOptions, RiseResult, rise
from robot_rise.sampling import sample_lying_postures
from robot_rise.trajectory import Trajectory, read_trajectory, write_trajectory

__all__ = [
    "Robot",
    "load_robot",
    "Posture",
    "read_posture",
    "write_posture",
    "sample_lying_postures",
    "rise",
    "RiseOptions",
    "RiseResult",
    "check",
    "Proof",
    "ProofConfig",
    "Trajectory",
    "read_trajectory",
    "write_trajectory",
    "RobotRiseError",
]
