"""The built distributions work outside the checkout: configs/ ships as robot_rise/configs.

Builds an sdist from a copy of the source tree and a wheel from that sdist (as pip does for a
release), checks their file lists, then imports the unpacked wheel from a directory outside the
repo and loads the robot, the scenes and the motion library from the shipped package data.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tarfile
import textwrap
import tomllib
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
CODE_PACKAGES = ("robot_rise", "drivers", "robot_files")
REQUIRED = (
    "robot_rise/configs/robots/op3/robot.xml",
    "robot_rise/configs/robots/op3/robot.toml",
    "robot_rise/configs/robots/op3/servos.toml",
    "robot_rise/configs/scenes/flat.xml",
    "robot_rise/configs/motions/op3/index.json",
    "robot_rise/configs/bench/planning_problems.json",
    "robot_rise/py.typed",
    "robot_rise/cli/__init__.py",
    "drivers/__init__.py",
    "drivers/py.typed",
    "drivers/mockbus/__init__.py",
    "robot_files/__init__.py",
    "robot_files/py.typed",
)


def _setuptools_version() -> tuple[int, ...]:
    import setuptools

    return tuple(int(p) for p in setuptools.__version__.split(".")[:2] if p.isdigit())


def _source_files(sub: str, suffix: str = "") -> set[str]:
    """Files of the source tree under ``sub`` (POSIX, relative to the repo), caches left out."""
    out = set()
    for p in (REPO / sub).rglob(f"*{suffix}"):
        rel = p.relative_to(REPO)
        if p.is_file() and "__pycache__" not in rel.parts and not any(s.startswith(".") for s in rel.parts):
            out.add(rel.as_posix())
    return out


@pytest.fixture(scope="module")
def dists(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    # The build hooks run in this venv (no network); pyproject asks for setuptools>=77 (PEP 639).
    if _setuptools_version() < (77,):
        pytest.skip("setuptools>=77 is needed in the venv to build offline (pip install 'setuptools>=77')")
    tmp = tmp_path_factory.mktemp("dists")
    # Build from a copy: setuptools writes build/ and *.egg-info into the tree, and a stale
    # build/lib (modules since moved away) would leak into the wheel.
    src = tmp / "src"
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(
        ".git", ".venv", "build", "dist", "out", "*.egg-info", "__pycache__", ".hypothesis", ".pytest_cache"))
    out = tmp / "dist"
    out.mkdir()
    run = dict(capture_output=True, text=True, timeout=300)
    r = subprocess.run([sys.executable, "-c", "import sys; from setuptools import build_meta as b; print(b.build_sdist(sys.argv[1]))",
                        str(out)], cwd=src, **run)
    assert r.returncode == 0, r.stdout + r.stderr
    sdist = out / r.stdout.strip().splitlines()[-1]
    # The wheel from the sdist, not the tree: proves the sdist is complete. No cache: pip would key
    # a cached wheel on the sdist's path alone.
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-cache-dir",
                        "--no-index", "-q", "-w", str(out), str(sdist)], cwd=tmp, **run)
    assert r.returncode == 0, r.stdout + r.stderr
    (wheel,) = out.glob("robot_rise-*.whl")
    return sdist, wheel


def test_package_list_covers_the_source_tree() -> None:
    """pyproject lists packages by hand (find cannot map configs/): a new subpackage must be added."""
    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    on_disk = {
        p.parent.relative_to(REPO).as_posix().replace("/", ".")
        for top in CODE_PACKAGES
        for p in (REPO / top).rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    assert on_disk - listed == set(), "add these to [tool.setuptools] packages in pyproject.toml"
    assert listed - on_disk == {"robot_rise.configs"}, "packages listed in pyproject.toml but not in the tree"


def test_sdist_has_the_sources_and_configs(dists: tuple[Path, Path]) -> None:
    sdist, _ = dists
    with tarfile.open(sdist) as tf:
        top = sdist.name.removesuffix(".tar.gz")
        names = {n.removeprefix(top + "/") for n in tf.getnames()}
    expected = _source_files("configs") | {"pyproject.toml"}
    for top_pkg in CODE_PACKAGES:
        expected |= _source_files(top_pkg, ".py")
    assert expected - names == set()


def test_wheel_file_list(dists: tuple[Path, Path]) -> None:
    _, wheel = dists
    names = set(zipfile.ZipFile(wheel).namelist())
    assert set(REQUIRED) - names == set()
    shipped_configs = {"robot_rise/" + n for n in _source_files("configs")}
    assert shipped_configs - names == set(), "config files left out: widen [tool.setuptools.package-data]"
    code = set().union(*(_source_files(p, ".py") for p in CODE_PACKAGES))
    assert code - names == set()
    # Nothing at the top level but the three packages and the metadata: no tests, no bare configs/.
    dist_info = "-".join(wheel.name.split("-")[:2]) + ".dist-info"
    assert {n.split("/")[0] for n in names} == {"robot_rise", "drivers", "robot_files", dist_info}
    assert "robot-rise = robot_rise.cli:main" in zipfile.ZipFile(wheel).read(f"{dist_info}/entry_points.txt").decode()


_PROBE = textwrap.dedent("""
    import json, sys
    import drivers, robot_files, robot_rise
    from robot_files.servo_catalog import product_catalog_path
    from robot_rise.library import load_library
    from robot_rise.model import compose, load_robot
    from robot_rise.paths import configs_dir

    r = load_robot()
    scenes = sorted(p.stem for p in (configs_dir() / "scenes").glob("*.xml"))
    for s in scenes:
        compose(r, s)
    print(json.dumps({
        "robot_rise": robot_rise.__file__, "drivers": drivers.__file__, "robot_files": robot_files.__file__,
        "configs": str(configs_dir()), "catalog": str(product_catalog_path()),
        "robot": r.name, "n_joints": r.n_joints, "scenes": scenes, "motions": len(load_library().motions),
    }))
""")


def test_unpacked_wheel_runs_outside_the_checkout(dists: tuple[Path, Path], tmp_path: Path) -> None:
    _, wheel = dists
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    cwd = tmp_path / "elsewhere"
    cwd.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("ROBOT_RISE_CONFIGS", "PYTHONPATH")}
    # PYTHONPATH comes before site-packages and the editable install's finder (appended to
    # sys.meta_path), so the unpacked copy is the one imported; asserted below.
    env["PYTHONPATH"] = str(site)
    r = subprocess.run([sys.executable, "-c", _PROBE], cwd=cwd, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    site = site.resolve()
    for key in ("robot_rise", "drivers", "robot_files", "configs"):
        assert Path(got[key]).resolve().is_relative_to(site), (key, got[key])
    assert Path(got["configs"]).resolve() == site / "robot_rise" / "configs"
    assert Path(got["catalog"]).resolve() == site / "robot_rise" / "configs" / "servos" / "catalog.toml"  # what drivers reads
    assert got["robot"] == "op3" and got["n_joints"] > 0
    assert got["scenes"] == sorted(Path(n).stem for n in _source_files("configs/scenes", ".xml"))
    assert got["motions"] > 0
