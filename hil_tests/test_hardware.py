"""The same checks on a real bus (ROBOT_RISE_PORT unset: skipped with the reason printed).

Read-only on purpose: nothing here enables torque or moves a servo.
"""

from __future__ import annotations

import pytest

from drivers.servo_map import ServoMap
from drivers.session import connect
from drivers.startup import preflight

pytestmark = pytest.mark.hardware


def test_that_every_mapped_servo_answers_with_its_model(hardware_port: str, servo_map: ServoMap) -> None:
    with connect(servo_map, hardware_port) as conn:
        report = preflight(conn.group, configure=False)
        assert sorted(report.found) == sorted(servo_map.ids)


def test_that_feedback_of_every_servo_is_read_in_one_cycle(hardware_port: str, servo_map: ServoMap) -> None:
    with connect(servo_map, hardware_port) as conn:
        preflight(conn.group, configure=False)
        conn.group.use_indirect = False
        fb = conn.group.read_feedback()
        assert fb.valid.all() and (fb.voltage_v > 9).all()
