"""A model file as its team published it, read into an ``MjSpec`` with every file it names found.

The one reader of robot description files (MJCF, URDF, xacro; the suffix in any case: ``.URDF``
is a URDF). URDF and expanded xacro are read from their text, so MuJoCo never sees a ``file://``
or ``package://`` URI (it reads neither): every mesh, texture and height field is resolved here
(:func:`resolve_asset`) and set as an absolute path, each inference a note for the user.

How a ``package://NAME/REST`` URI resolves, first hit wins:
1. an ancestor directory of the model file named ``NAME`` (the package the file lives in);
2. a child ``NAME`` of an ancestor (a package beside ours in a workspace, or a package root
   whose exporter dropped the package's name: ``package://meshes/x.stl`` from ``PKG/robots/``);
3. each ``--package-path DIR`` (``DIR`` is the package, or holds it), then ``ROS_PACKAGE_PATH``.
``package:///REST`` (no name) is relative to the nearest ancestor holding a ``package.xml`` or
``manifest.xml``, else the model's directory. A file whose name differs only in case from the one
on disk is taken (SolidWorks writes ``.STL`` for ``.stl``) and reported.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import mujoco

from robot_rise.errors import ConfigError, mujoco_reason

__all__ = ["ModelSource", "read_model", "resolve_asset", "model_kind", "PACKAGE_PATH_ENV"]

PACKAGE_PATH_ENV = "ROS_PACKAGE_PATH"
_PACKAGE_MARKERS = ("package.xml", "manifest.xml")
_PACKAGE_URI = re.compile(r"^package://([^/]*)/(.*)$")
_FILE_URI = "file://"


@dataclass(frozen=True)
class ModelSource:
    """A model file read: its spec (assets at absolute paths), kind and what reading it inferred.

    Attributes:
        spec: the model, every asset file an absolute path that exists.
        kind: ``"mjcf"``, ``"urdf"`` or ``"xacro"``.
        path: the file read.
        notes: one line per inference (a resolved URI, a case-insensitive match).
        urdf_text: the URDF (a xacro file's expansion) for what MuJoCo's parser drops (``<limit>``).
    """

    spec: mujoco.MjSpec
    kind: str
    path: Path
    notes: tuple[str, ...]
    urdf_text: str = ""


def model_kind(path: Path) -> str:
    """``mjcf``, ``urdf`` or ``xacro`` from the suffix (any case), else from the root element."""
    suffixes = [s.lower() for s in path.suffixes]
    if suffixes and suffixes[-1] == ".xacro":
        return "xacro"
    if suffixes and suffixes[-1] == ".urdf":
        return "urdf"
    try:
        root = next(ElementTree.iterparse(path, events=("start",)))[1].tag
    except (OSError, ElementTree.ParseError, StopIteration) as e:
        raise ConfigError(f"{path}: not an XML model file ({e})") from e
    return {"robot": "urdf", "mujoco": "mjcf"}.get(root.split("}")[-1], "mjcf")


def _package_roots(start: Path) -> list[Path]:
    return [d for d in (start, *start.parents) if any((d / marker).is_file() for marker in _PACKAGE_MARKERS)]


def _case_insensitive(path: Path) -> Path | None:
    """``path`` with each component matched on disk ignoring case, or None."""
    if path.exists():
        return path
    current = Path(path.anchor) if path.is_absolute() else Path(".")
    for part in path.relative_to(path.anchor).parts if path.is_absolute() else path.parts:
        exact = current / part
        if exact.exists():
            current = exact
            continue
        if not current.is_dir():
            return None
        match = [c for c in current.iterdir() if c.name.lower() == part.lower()]
        if len(match) != 1:
            return None
        current = match[0]
    return current


def resolve_asset(
    uri: str, model_dir: Path, package_paths: Sequence[Path] = (), base: Path | None = None
) -> tuple[Path, str]:
    """The file an asset name means, and a note ('' when it is where it says).

    Args:
        uri: the name as written (``package://``, ``file://``, absolute or relative).
        model_dir: the directory of the model file (ancestors are searched for packages).
        package_paths: ``--package-path`` directories, searched before ``ROS_PACKAGE_PATH``.
        base: where a relative name is relative to (the model's mesh directory), default ``model_dir``.

    Raises:
        ConfigError: no such file; the message names the URI and every place looked.
    """
    base = base or model_dir
    candidates: list[Path] = []
    match = _PACKAGE_URI.match(uri)
    if match:
        name, rest = match.groups()
        if not name:
            roots = _package_roots(model_dir)
            candidates.append((roots[0] if roots else model_dir) / rest)
        else:
            ancestors = [model_dir, *model_dir.parents]
            candidates += [a / rest for a in ancestors if a.name == name]
            candidates += [a / name / rest for a in ancestors]
            env = [Path(p) for p in os.environ.get(PACKAGE_PATH_ENV, "").split(os.pathsep) if p]
            for d in [*package_paths, *env]:
                candidates += [d / rest] if d.name == name else [d / name / rest]
    elif uri.startswith(_FILE_URI):
        candidates.append(Path(uri[len(_FILE_URI) :]))
    else:
        candidates.append(Path(uri) if Path(uri).is_absolute() else base / uri)
    for c in candidates:
        if c.is_file():
            return c.resolve(), (f"{uri} -> {c.resolve()}" if match else "")
    for c in candidates:
        found = _case_insensitive(c)
        if found is not None and found.is_file():
            return found.resolve(), f"{uri}: no such file; took {found.resolve()} (the name differs in case)"
    looked = ", ".join(dict.fromkeys(str(c) for c in candidates)) or "nowhere"
    hint = " (give the package's directory with --package-path DIR or ROS_PACKAGE_PATH)" if match else ""
    raise ConfigError(f"cannot find {uri}: looked in {looked}{hint}")


def _expand_xacro(path: Path, package_paths: Sequence[Path]) -> str:
    """The URDF a xacro file expands to (``$(find NAME)`` through the same package search)."""
    from xacrodoc import XacroDoc, packages  # noqa: PLC0415 (xacrodoc loads rospkg: only for xacro files)

    packages.reset()  # xacrodoc's package finder is global: no directory of a previous import
    env = [Path(p) for p in os.environ.get(PACKAGE_PATH_ENV, "").split(os.pathsep) if p]
    dirs = [str(d) for d in [*package_paths, *env] if d.is_dir()]
    if dirs:
        packages.look_in(dirs + [str(d.parent) for d in map(Path, dirs)])
    packages.walk_up_from(path)
    # the ancestors' children, as for package:// (a workspace's src/ holding the packages)
    packages.update_package_cache(
        {c.name: c for a in (path.parent, *path.parent.parents) if a != a.parent and os.access(a, os.R_OK) for c in _dirs_with_marker(a)}
    )
    try:
        return XacroDoc.from_file(str(path), walk_up=True).to_urdf_string(use_protocols=True)
    except packages.PackageNotFoundError as e:
        raise ConfigError(f"{path}: cannot expand xacro: {e} (give its directory with --package-path DIR or ROS_PACKAGE_PATH)") from e
    except Exception as e:  # xacro raises many kinds, each with its message
        raise ConfigError(f"{path}: cannot expand xacro: {str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__}") from e


def _dirs_with_marker(directory: Path) -> list[Path]:
    try:
        return [c for c in directory.iterdir() if c.is_dir() and any((c / m).is_file() for m in _PACKAGE_MARKERS)]
    except OSError:
        return []


def read_model(path: str | os.PathLike[str], package_paths: Sequence[str | os.PathLike[str]] = ()) -> ModelSource:
    """Read a model file into a spec whose asset files are absolute paths that exist.

    Raises:
        ConfigError: the file is missing or unreadable, an asset cannot be found (one line each).
    """
    src = Path(path)
    if not src.is_file():
        raise ConfigError(f"{src}: no such model file")
    pkg_dirs = [Path(p) for p in package_paths]
    missing = [str(p) for p in pkg_dirs if not p.is_dir()]
    if missing:
        raise ConfigError(f"--package-path {', '.join(missing)}: no such directory")
    kind = model_kind(src)
    urdf_text = ""
    try:
        if kind == "xacro":
            urdf_text = _expand_xacro(src, pkg_dirs)
            spec = mujoco.MjSpec.from_string(urdf_text)
        elif kind == "urdf":
            urdf_text = src.read_text(encoding="utf-8", errors="replace")
            spec = mujoco.MjSpec.from_string(urdf_text)
        else:
            spec = mujoco.MjSpec.from_file(str(src))
    except ConfigError:
        raise
    except Exception as e:  # mujoco's parser raises ValueError with its message
        raise ConfigError(f"{src}: cannot load the model: {mujoco_reason(e)}") from e
    notes: list[str] = []
    model_dir = src.resolve().parent
    strip = bool(getattr(spec, "strippath", False))
    for elements, directory in (
        ([*spec.meshes, *spec.skins, *spec.hfields], spec.meshdir),
        ([*spec.textures], spec.texturedir),
    ):
        base = model_dir / directory if directory else model_dir
        for el in elements:
            names = [el.file] + (list(el.cubefiles) if hasattr(el, "cubefiles") else [])
            for i, name in enumerate(names):
                if not name:
                    continue
                name = Path(name).name if strip and not name.startswith(("package:", _FILE_URI)) else name
                try:
                    found, note = resolve_asset(name, model_dir, pkg_dirs, base)
                except ConfigError as e:
                    raise ConfigError(f"{src}: {e}") from None
                if note:
                    notes.append(note)
                if i == 0:
                    el.file = str(found)
                else:
                    files = list(el.cubefiles)
                    files[i - 1] = str(found)
                    el.cubefiles = files
    spec.meshdir = ""
    spec.texturedir = ""
    cased = [n for n in notes if "differs in case" in n]
    if len(cased) > 3:  # one line for many: the exporter wrote every suffix in upper case
        notes = [n for n in notes if "differs in case" not in n]
        notes.append(f"{len(cased)} file names differ in case from the files on disk, taken ignoring case (e.g. {cased[0]})")
    resolved_uris = sum(1 for n in notes if " -> " in n)
    if resolved_uris > 3:  # one line for many package:// URIs, each case-mismatch on its own
        first = next(n for n in notes if " -> " in n)
        notes = [n for n in notes if " -> " not in n]
        notes.insert(0, f"resolved {resolved_uris} package:// URIs (e.g. {first})")
    return ModelSource(spec, kind, src, tuple(notes), urdf_text)
