"""Every name a module exports in __all__ must exist (mink's __all__ once named missing functions)."""

from __future__ import annotations

import importlib
import pkgutil

import pytest

import drivers
import robot_rise


def _modules():
    for pkg in (robot_rise, drivers):
        for info in pkgutil.walk_packages(pkg.__path__, prefix=f"{pkg.__name__}."):
            if not info.name.endswith("__main__"):
                yield info.name


@pytest.mark.parametrize("name", sorted(_modules()))
def test_every_name_in_all_resolves(name):
    module = importlib.import_module(name)
    for exported in getattr(module, "__all__", []):
        assert hasattr(module, exported), f"{name}.__all__ names missing {exported}"


def test_core_never_imports_drivers_and_drivers_never_import_core():
    import ast
    from pathlib import Path

    root = Path(robot_rise.__file__).parent.parent
    for pkg, forbidden in (("robot_rise", "drivers"), ("drivers", "robot_rise")):
        for path in (root / pkg).rglob("*.py"):
            if pkg == "robot_rise" and "cli" in path.parts:
                continue  # the CLI is the one room that wires both
            tree = ast.parse(path.read_text())
            for node in ast.walk(tree):
                names = []
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.module:
                    names = [node.module]
                assert not any(n == forbidden or n.startswith(forbidden + ".") for n in names), f"{path} imports {forbidden}"
