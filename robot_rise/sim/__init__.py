"""Simulation: play a trajectory through the servo model, judge the recording, the physics twin.

- :mod:`~robot_rise.sim.player`: ``Player``/``play`` and the ``Recording`` they make.
- :mod:`~robot_rise.sim.balance`: ZMP and support polygon (pure geometry).
- :mod:`~robot_rise.sim.standing`: the standing verdict of a recording.
- :mod:`~robot_rise.sim.twin`: the MuJoCo twin that moves emulated servos (the mock bus's plant).
"""

from robot_rise.sim.standing import StandVerdict, judge
from robot_rise.sim.player import DEFAULT_HOLD_S, DEFAULT_RECORD_HZ, Player, Recording, play
from robot_rise.sim.twin import MujocoTwin, TwinState

__all__ = ["Player", "Recording", "play", "DEFAULT_HOLD_S", "DEFAULT_RECORD_HZ", "StandVerdict", "judge", "MujocoTwin", "TwinState"]
