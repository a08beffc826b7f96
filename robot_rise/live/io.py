"""The robot as the live loop sees it: the :class:`RobotIO` interface and what it returns.

Nothing in ``robot_rise.live`` talks to hardware: :class:`RobotIO` is the robot (joint angles,
IMU samples, health, execute a trajectory, go limp, hold), and ``robot_rise.cli`` wires it to
``drivers`` (``robot_rise.cli._bus_io.BusRobotIO``: a real bus, or the emulated bus moved by the
physics twin). The twin, the mock bus and a real robot plug in unchanged.

Time: every time is on the IO's clock (``RobotIO.now_s``: the bus clock, simulated with the twin).
Thinking (estimate, plan, proof) takes no simulated time by itself; its CPU time (one core's worth,
``time.process_time``) is handed to ``RobotIO.spent``, which lets that much time pass on a
simulated clock (a real clock has passed it already), so latencies include it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from robot_rise.live.fall import ImuSampleLike
from robot_rise.live.health import Health
from robot_rise.posture import Posture
from robot_rise.trajectory import Trajectory

__all__ = ["ExecutionResult", "RobotIO", "TruthSource"]


@dataclass(frozen=True)
class ExecutionResult:
    """How one trajectory ran.

    Attributes:
        completed: it ran to the end without a fault.
        first_command_s: IO clock time of the first goal sent [s] (None: nothing was sent).
        ended_s: IO clock time at the end [s].
        reason: why it stopped or was refused (empty when completed).
        interrupted: the operator stopped it (Ctrl-C).
        lagging_joints: joints whose servo it stopped for, off the proof's predicted position (a
            blocked shaft, or the body went elsewhere).
    """

    completed: bool
    first_command_s: float | None
    ended_s: float
    reason: str = ""
    interrupted: bool = False
    lagging_joints: tuple[str, ...] = ()


@runtime_checkable
class RobotIO(Protocol):
    """The robot as the get-up loop sees it (SI units; joint angles in the model's joint frame)."""

    def now_s(self) -> float:
        """The IO clock [s] (monotonic; simulated with the twin)."""
        ...

    def sleep(self, duration_s: float) -> None:
        """Let ``duration_s`` [s] pass (the loop's cycle)."""
        ...

    def spent(self, compute_s: float) -> None:
        """The loop thought for ``compute_s`` [s] of CPU: a simulated clock lets that much time
        pass (a real one already has)."""
        ...

    def read_joints(self) -> Mapping[str, float]:
        """Present joint angles by joint name [rad] (one sync read); missing servos left out."""
        ...

    def read_imu(self) -> ImuSampleLike:
        """One IMU sample (torso frame, SI; ``valid`` False when the read failed)."""
        ...

    def health(self) -> Health:
        """Temperatures, voltages, hardware errors of every servo."""
        ...

    def execute(self, trajectory: Trajectory) -> ExecutionResult:
        """Stream a proven trajectory under the executor's safety layer (holds at the end)."""
        ...

    def go_limp(self) -> None:
        """Torque off now (falling, lying, giving up); never raises (a failure is logged)."""
        ...

    def hold(self) -> str:
        """Torque on holding the present posture (no motion); returns why not ('' when holding),
        never raises."""
        ...


@runtime_checkable
class TruthSource(Protocol):
    """Where the body truly lies (the physics twin only): for the estimate's error."""

    def true_posture(self) -> Posture: ...
