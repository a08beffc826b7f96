"""Shared fixtures: the embedded robot, and the published humanoids imported, each once per session."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import pytest

from robot_rise.proof import CACHE_ENV
from robot_rise.model import Robot, load_robot
from robot_rise.robot_import import ImportResult, import_robot

_SHARED_ROBOTS = Path(__file__).resolve().parents[2] / "shared" / "robots"
# name: (model file under ../shared/robots, the servo model every joint gets)
_PUBLISHED = {"wolfgang": ("wolfgang/wolfgang.xml", "MX-106"), "bez1": ("bez1/bez1.xml", "MX-28")}


class Imported(NamedTuple):
    """A published robot as imported: what the import said, and the robot it wrote."""

    result: ImportResult
    robot: Robot


@pytest.fixture(scope="session", autouse=True)
def _start_proof_cache(tmp_path_factory: pytest.TempPathFactory):
    """Start proofs kept for this session only: never the user's cache, a clean one each run."""
    patch = pytest.MonkeyPatch()
    patch.setenv(CACHE_ENV, str(tmp_path_factory.mktemp("cache")))
    yield
    patch.undo()


@pytest.fixture(scope="session")
def robot() -> Robot:
    return load_robot()


@pytest.fixture(scope="session")
def published_models() -> dict[str, tuple[Path, str]]:
    """The humanoids as their teams published them (../shared/robots beside the repository):
    name -> (model file, servo model of every joint), only those present (none where the folder is absent)."""
    models = {name: (_SHARED_ROBOTS / path, servo) for name, (path, servo) in _PUBLISHED.items()}
    return {name: model for name, model in models.items() if model[0].is_file()}


@pytest.fixture(scope="session")
def shared_robots(published_models: dict[str, tuple[Path, str]]) -> dict[str, tuple[Path, str]]:
    """:func:`published_models`, the test skipped unless every one is there."""
    if len(published_models) < len(_PUBLISHED):
        pytest.skip("../shared/robots not beside the repository")
    return published_models


@pytest.fixture(scope="session")
def imported(shared_robots: dict[str, tuple[Path, str]], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Imported]:
    """Each published robot imported once per session into a temporary directory (tests read it,
    never change it: a test that needs to change a robot imports its own)."""
    out = {}
    for name, (path, servo) in shared_robots.items():
        directory = tmp_path_factory.mktemp("robots") / name
        out[name] = Imported(import_robot(path, directory, servo_models={"*": servo}), load_robot(directory))
    return out
