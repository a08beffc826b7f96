"""Shared fixtures: the embedded robot, loaded once per session."""

from __future__ import annotations

import pytest

from robot_rise.model import Robot, load_robot


@pytest.fixture(scope="session")
def robot() -> Robot:
    return load_robot()
