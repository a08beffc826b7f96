"""Every name a module exports in __all__ must exist (mink's __all__ once named missing functions)."""

from __future__ import annotations

import importlib
import pkgutil

import pytest

import drivers
import robot_files
import robot_rise


def _modules():
    for pkg in (robot_rise, drivers, robot_files):
        for info in pkgutil.walk_packages(pkg.__path__, prefix=f"{pkg.__name__}."):
            if not info.name.endswith("__main__"):
                yield info.name


@pytest.mark.parametrize("name", sorted(_modules()))
def test_every_name_in_all_resolves(name):
    module = importlib.import_module(name)
    for exported in getattr(module, "__all__", []):
        assert hasattr(module, exported), f"{name}.__all__ names missing {exported}"


# Rooms above the core: they may import drivers and the core; the core imports none of them.
ABOVE_THE_CORE = ("cli", "bench", "authoring")


def _imported_modules(path):
    import ast

    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module


def _room(path, package_root):
    parts = path.relative_to(package_root).parts
    if parts == ("__main__.py",):
        return "cli"  # `python -m robot_rise` is the CLI
    return parts[0] if len(parts) > 1 else ""


def test_core_never_imports_drivers_and_drivers_never_import_core():
    from pathlib import Path

    root = Path(robot_rise.__file__).parent.parent
    for pkg, forbidden in (("robot_rise", "drivers"), ("drivers", "robot_rise")):
        for path in (root / pkg).rglob("*.py"):
            if pkg == "robot_rise" and _room(path, root / pkg) in ABOVE_THE_CORE:
                continue  # the CLI wires both; benchmarks measure both
            for n in _imported_modules(path):
                assert not (n == forbidden or n.startswith(forbidden + ".")), f"{path} imports {forbidden}"


def test_the_files_both_sides_read_import_neither_side():
    """robot_files (the servo map, the servo catalog, TOML) is where core and drivers meet: it imports neither."""
    from pathlib import Path

    root = Path(robot_files.__file__).parent
    for path in root.rglob("*.py"):
        for n in _imported_modules(path):
            assert n.split(".")[0] not in ("robot_rise", "drivers"), f"{path} imports {n}"


def test_the_core_never_imports_the_rooms_above_it():
    from pathlib import Path

    pkg_root = Path(robot_rise.__file__).parent
    above = tuple(f"robot_rise.{room}" for room in ABOVE_THE_CORE)
    for path in pkg_root.rglob("*.py"):
        room = _room(path, pkg_root)
        if room in ABOVE_THE_CORE:
            continue
        for n in _imported_modules(path):
            bad = [a for a in above if n == a or n.startswith(a + ".")]
            assert not bad, f"{path.relative_to(pkg_root.parent)} imports {n}: only the CLI and tests import {', '.join(ABOVE_THE_CORE)}"


def test_the_bench_rooms_import_no_cli():
    from pathlib import Path

    pkg_root = Path(robot_rise.__file__).parent
    for room in ("bench", "authoring"):
        for path in (pkg_root / room).rglob("*.py"):
            for n in _imported_modules(path):
                assert not n.startswith("robot_rise.cli"), f"{path} imports the CLI ({n})"


def test_the_public_face_names_the_documented_api():
    for name in ("load_robot", "sample_lying_postures", "rise", "check", "Posture", "Trajectory", "Proof", "Robot", "RiseResult"):
        assert name in robot_rise.__all__, name
    for name in ("DynamixelBus", "Executor", "ExecutorConfig", "load_servo_map"):
        assert name in drivers.__all__, name


def test_the_readme_example_runs_and_its_trajectory_is_proven(tmp_path, monkeypatch):
    """The ten-line example in README.md, run as written (in a temporary directory)."""
    import re
    from pathlib import Path

    readme = (Path(robot_rise.__file__).parent.parent / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, flags=re.S)
    example = next(b for b in blocks if "import robot_rise" in b)
    assert len(example.strip().splitlines()) <= 12
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(example, "README.md", "exec"), namespace)
    result = namespace["result"]
    assert result.proven and result.proof is not None and result.proof.proven
    assert (tmp_path / "getup.json").exists()


def test_the_developer_layout_names_every_module_and_nothing_that_is_gone():
    """DEVELOPERS.md's layout section matches the tree: every module and folder is named, each named one exists."""
    import re
    from pathlib import Path

    root = Path(robot_rise.__file__).parent.parent
    readme = (root / "DEVELOPERS.md").read_text()
    layout = readme[readme.index("## Layout"): readme.index("Data flows one way")]
    named = set(re.findall(r"`([\w/]+(?:\.py)?/?)`", layout))
    for pkg in ("robot_rise", "drivers", "robot_files"):
        for path in (root / pkg).rglob("*.py"):
            if path.name in ("__init__.py", "__main__.py") or "cli" in path.parts or "__pycache__" in path.parts:
                continue
            rel = path.relative_to(root / pkg)
            # a module is named by its file name; a module inside a sub-sub-package by its folder
            assert path.name in named or (len(rel.parts) > 2 and f"{rel.parts[-2]}/" in named), f"DEVELOPERS.md layout misses {pkg}/{rel}"
    for name in named:
        if name.endswith(".py"):
            assert list(root.glob(f"*/**/{name}")), f"DEVELOPERS.md layout names {name}, which does not exist"


def test_tests_import_public_names_only():
    """A test that needs a private name tests an implementation detail: make the name public or test through it."""
    import ast
    from pathlib import Path

    root = Path(robot_rise.__file__).parent.parent
    for folder in ("sim_tests", "hil_tests"):
        for path in (root / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in ("robot_rise", "drivers", "robot_files"):
                    private = [a.name for a in node.names if a.name.startswith("_")]
                    assert not private, f"{path.relative_to(root)} imports private {private} from {node.module}"
