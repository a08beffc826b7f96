"""Every file an MJCF loads besides itself (included XML, meshes, skins, height fields, textures): what a robot's digest covers and a store copies."""

from __future__ import annotations

import os
from pathlib import Path
from xml.etree import ElementTree

import mujoco

from robot_rise.errors import ConfigError, mujoco_reason

__all__ = ["model_files"]


def model_files(xml_path: str | os.PathLike[str]) -> tuple[Path, ...]:
    """Every file an MJCF loads besides itself, sorted: included XML, meshes, skins, height fields, textures.

    Paths resolve as MuJoCo resolves them: an ``<include>`` relative to the main file's directory
    (else to the including file's), assets relative to the compiler's ``meshdir`` (meshes, skins,
    height fields) or ``texturedir`` (textures), themselves relative to the main file's directory.

    Raises:
        ConfigError: the MJCF cannot be read, or a file it loads is missing.
    """
    main = Path(xml_path).resolve()
    files: set[Path] = set()
    pending = [main]
    while pending:  # <include> elements, recursively (MjSpec inlines them without a trace)
        current = pending.pop()
        try:
            tree = ElementTree.parse(current)
        except (OSError, ElementTree.ParseError) as e:
            raise ConfigError(f"{current}: cannot read MJCF: {e}") from e
        for el in tree.iter("include"):
            name = el.get("file", "")
            path = next((p for p in (main.parent / name, current.parent / name) if p.is_file()), main.parent / name)
            if path not in files:
                files.add(path)
                pending.append(path)
    try:
        spec = mujoco.MjSpec.from_file(str(main))
    except Exception as e:  # mujoco raises ValueError with the parser message
        raise ConfigError(f"{main}: cannot load MJCF: {mujoco_reason(e)}") from e

    def asset(directory: str, name: str) -> Path:
        if spec.strippath:
            name = Path(name).name
        return (main.parent / directory / name).resolve()

    for element in (*spec.meshes, *spec.skins, *spec.hfields):
        if element.file:
            files.add(asset(spec.meshdir, element.file))
    for texture in spec.textures:
        for name in (texture.file, *texture.cubefiles):
            if name:
                files.add(asset(spec.texturedir, name))
    missing = sorted(str(p) for p in files if not p.is_file())
    if missing:
        raise ConfigError(f"{main}: loads files that do not exist: {', '.join(missing)}")
    return tuple(sorted(files))
