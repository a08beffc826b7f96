"""Batch tasks: one get-up each (robot, scene, posture, options), with an id derived from its inputs.

The id is a digest of everything that changes the task's result:

- the robot's files (``Robot.digest()``) and its motion library's files
  (:func:`robot_rise.library.library_digest`);
- the scene's name and its files (:func:`scene_files_digest`);
- the rise options that change a result (:func:`options_key`: planning budget, candidates,
  retries and every field of the dynamics filter's configuration, ensemble proof included),
  with the defaults filled in, so naming a default explicitly keeps the id;
- the batch seed (planner seed), and the posture: for a sampled posture the kind and its index,
  for a posture file the digest of its content (:func:`posture_content`; its name does not count).

So the same inputs always name the same task: a re-run of a batch finds what is done by id, and
a changed robot, library or scene file, or another margin, budget or ``--no-ensemble``, makes
new tasks instead of silently reusing results proven under other conditions.

Sampled tasks sample their own posture (``sample_lying`` with one posture and a seed derived from
the batch seed and the index), so tasks are independent: any subset runs in any order, on any
worker, with the same result. Posture-file tasks carry the posture itself (:attr:`BatchTask.posture`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from robot_rise.errors import PostureError, RobotRiseError, SceneError
from robot_rise.library import library_digest
from robot_rise.model import Robot, model_files
from robot_rise.paths import scene_path
from robot_rise.sampling import LYING_KINDS

__all__ = [
    "TASK_SCHEME", "RESULT_OPTIONS", "BatchTask", "PostureFile", "task_id", "posture_seed", "make_tasks",
    "options_key", "scene_files_digest", "posture_content", "read_posture_dir",
]

TASK_SCHEME = "robot-rise/batch-task@2"
"""Part of every id: a change of what a task computes from its inputs changes this, and so every id."""

RESULT_OPTIONS = ("budget_s", "candidates", "retries", "filter_config", "composed")
"""The fields of :class:`robot_rise.rise.RiseOptions` a batch may set; each is part of the id."""
_KEYED_ONLY_IF_SET = ("composed",)  # options added after stores were written: at their default they leave the id as it was


@dataclass(frozen=True)
class BatchTask:
    """One get-up to prove.

    Attributes:
        id: :func:`task_id` of the inputs.
        robot_dir: the robot directory the worker loads.
        robot: the robot's name.
        robot_digest: SHA-256 of the robot's files.
        scene: the scene (shipped name or MJCF path).
        kind: lying kind (supine, prone, left, right; for a posture file, how it lies).
        seed: the batch seed (also the planner seed).
        index: the posture's index among those of its robot, scene and kind (sampled), or among
            the robot's posture files in name order.
        scene_digest: :func:`scene_files_digest` of the scene.
        posture: canonical posture@1 JSON of a posture file ('' for a sampled posture).
        posture_file: the posture file's name ('' for a sampled posture).
        posture_digest: SHA-256 of ``posture`` ('' for a sampled posture).
        options: :func:`options_key` of the rise options.
    """

    id: str
    robot_dir: str
    robot: str
    robot_digest: str
    scene: str
    kind: str
    seed: int
    index: int
    scene_digest: str = ""
    posture: str = ""
    posture_file: str = ""
    posture_digest: str = ""
    options: str = ""


def task_id(robot_digest: str, scene: str, kind: str, seed: int, index: int, *, scene_digest: str = "",
            library: str = "", options: str = "", posture_digest: str = "") -> str:
    """A 20-hex-digit id, the same for the same inputs on every machine.

    A posture file's task is named by ``posture_digest`` (its content), not by ``kind`` and ``index``.
    """
    source: list[Any] = ["file", posture_digest] if posture_digest else ["sampled", kind, int(index)]
    text = json.dumps([TASK_SCHEME, robot_digest, library, scene, scene_digest, options, int(seed), source])
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def posture_seed(seed: int, index: int) -> int:
    """The sampler's seed of posture ``index`` of a batch seeded ``seed`` (independent streams)."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


def _jsonable(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = dataclasses.asdict(value)
        # a FilterConfig's proof standard keyed beside its own fields, as before the two were apart
        # (robot_rise.proof.ProofConfig): the ids of stores written then still match
        nested = fields.pop("proof", None) if type(value).__name__ == "FilterConfig" else None
        return {"type": type(value).__name__, **{k: _jsonable(v) for k, v in {**(nested or {}), **fields}.items()}}
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise RobotRiseError(f"rise option value {value!r} cannot be part of a task id")


def options_key(rise_options: Mapping[str, Any] | None = None) -> str:
    """Canonical JSON of the rise options that change a result, every default filled in.

    Raises:
        RobotRiseError: an option a batch does not take (not in :data:`RESULT_OPTIONS`).
    """
    from robot_rise.rise import RiseOptions

    given = dict(rise_options or {})
    unknown = sorted(set(given) - set(RESULT_OPTIONS))
    if unknown:
        raise RobotRiseError(f"rise option {unknown[0]!r} is not a batch option; a batch takes {', '.join(RESULT_OPTIONS)}")
    defaults = RiseOptions()
    full = {name: given.get(name, getattr(defaults, name)) for name in RESULT_OPTIONS}
    full = {k: v for k, v in full.items() if not (k in _KEYED_ONLY_IF_SET and v == getattr(defaults, k))}
    return json.dumps(_jsonable(full), sort_keys=True, separators=(",", ":"))


def _files_digest(main: Path, others: Sequence[Path], base: Path) -> str:
    h = hashlib.sha256()
    h.update(main.read_bytes())
    for path in others:
        h.update(os.path.relpath(path, base).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def scene_files_digest(scene: str | os.PathLike[str]) -> str:
    """SHA-256 of the scene's MJCF and of every file it loads (included XML, meshes, textures).

    Raises:
        SceneError: no such scene, or a file it loads is missing.
    """
    path = scene_path(scene)
    if not path.is_file():
        raise SceneError(f"no scene {str(scene)!r} ({path} does not exist)", hint="shipped scenes: flat, beam, low_bed, table, slope, icy, soft; or an MJCF file")
    try:
        return _files_digest(path, model_files(path), path.parent)
    except RobotRiseError as e:
        raise SceneError(f"scene {scene}: {e}") from None


def posture_content(obj: Any, *, where: str = "posture") -> str:
    """The canonical posture@1 JSON of a parsed posture file: what its task id is a digest of.

    Key order, whitespace and number spelling do not change it; any value does.

    Raises:
        PostureError: ``obj`` is not a posture@1 object.
    """
    from robot_rise.posture import posture_from_dict, posture_to_dict

    return json.dumps(posture_to_dict(posture_from_dict(obj, where=where)), sort_keys=True, separators=(",", ":"))


@dataclass(frozen=True)
class PostureFile:
    """One posture file of a ``--postures`` directory.

    Attributes:
        name: the file name.
        robot: the robot it names.
        kind: how it lies (``classify_lying``: supine, prone, left, right or upright).
        posture: canonical posture@1 JSON (:func:`posture_content`).
        digest: SHA-256 of ``posture``.
    """

    name: str
    robot: str
    kind: str
    posture: str
    digest: str


def read_posture_dir(directory: str | os.PathLike[str], robots: Sequence[Robot]) -> list[PostureFile]:
    """Every ``*.json`` posture file of ``directory``, in name order, checked against the robot it names.

    Every file is read before anything runs: a file that is not JSON, not a posture@1 object,
    names none of ``robots``, or does not fit it (joints, limits past the clamping tolerance)
    refuses the whole batch, with one line per bad file. Files of identical content are one posture.

    Raises:
        RobotRiseError: no such directory, no posture file in it, or bad files (one line each).
    """
    from robot_rise.posture import posture_from_dict
    from robot_rise.sampling import classify_lying

    root = Path(directory)
    if not root.is_dir():
        raise RobotRiseError(f"--postures {root}: no such directory")
    paths = sorted(p for p in root.glob("*.json") if p.is_file())
    if not paths:
        raise RobotRiseError(f"--postures {root}: no posture file (*.json) in it", hint="robot-rise sample --kind supine --n 20 --out DIR writes some")
    by_name: dict[str, list[Robot]] = {}
    for r in robots:
        by_name.setdefault(r.name, []).append(r)
    out: list[PostureFile] = []
    bad: list[str] = []
    for path in paths:
        try:
            try:
                obj = json.loads(path.read_text())
            except (UnicodeDecodeError, json.JSONDecodeError) as e:
                raise PostureError(f"{path}: not valid JSON ({e})") from None
            content = posture_content(obj, where=str(path))
            name = obj["robot"]
            if name not in by_name:
                raise PostureError(f"{path}: posture is for robot {name!r}; the batch's robots are {', '.join(sorted(by_name))}")
            for robot in by_name[name]:
                posture = posture_from_dict(obj, robot, where=str(path))
        except RobotRiseError as e:
            bad.append(str(e).splitlines()[0])
            continue
        out.append(PostureFile(path.name, name, classify_lying(posture.root_quat_wxyz), content, hashlib.sha256(content.encode()).hexdigest()))
    if bad:
        raise RobotRiseError(f"--postures {root}: {len(bad)} of {len(paths)} files are not postures of the batch's robots; "
                             "nothing was run:\n  " + "\n  ".join(bad), hint="fix or move those files, then run the same command again")
    return out


def make_tasks(
    robots: Sequence[Robot],
    *,
    n: int | None = None,
    seed: int,
    kinds: Sequence[str] = LYING_KINDS,
    scenes: Sequence[str] = ("flat",),
    postures: Sequence[PostureFile] | None = None,
    rise_options: Mapping[str, Any] | None = None,
) -> list[BatchTask]:
    """The tasks of a batch, in robot, scene, then kind and index (or posture file) order.

    Sampled (``n``): ``n`` postures per robot, scene and kind. Given (``postures``, from
    :func:`read_posture_dir`): each posture once per scene, for the robots it names; identical
    contents are one task.

    Raises:
        RobotRiseError: neither or both of ``n`` and ``postures``, n < 1, an unknown kind, no
            robot, kind or scene, a missing scene, or a rise option a batch does not take.
    """
    if (n is None) == (postures is None):
        raise RobotRiseError("a batch takes either --n N (sampled postures) or --postures DIR, not both" if n is not None
                             else "a batch needs --n N (sampled postures) or --postures DIR")
    if n is not None and n < 1:
        raise RobotRiseError(f"--n must be at least 1, got {n}")
    bad = [k for k in kinds if k not in LYING_KINDS]
    if bad:
        raise RobotRiseError(f"unknown lying kind {bad[0]!r}; choose from {', '.join(LYING_KINDS)}")
    if not robots or not scenes or (postures is None and not kinds):
        raise RobotRiseError("a batch needs at least one robot, kind and scene")
    options = options_key(rise_options)
    scene_digests = {str(s): scene_files_digest(s) for s in scenes}
    tasks: list[BatchTask] = []
    seen: set[str] = set()
    for robot in robots:
        digest, library = robot.digest(), library_digest(robot)
        for scene, sdigest in scene_digests.items():
            common = {"robot_dir": str(robot.directory), "robot": robot.name, "robot_digest": digest, "scene": scene, "seed": seed,
                      "scene_digest": sdigest, "options": options}
            if postures is None:
                for kind in kinds:
                    for i in range(n):  # type: ignore[arg-type]
                        tid = task_id(digest, scene, kind, seed, i, scene_digest=sdigest, library=library, options=options)
                        tasks.append(BatchTask(tid, kind=kind, index=i, **common))
                continue
            mine = [p for p in postures if p.robot == robot.name]
            for i, p in enumerate(mine):
                tid = task_id(digest, scene, p.kind, seed, i, scene_digest=sdigest, library=library, options=options, posture_digest=p.digest)
                if tid in seen:  # the same content under another file name
                    continue
                seen.add(tid)
                tasks.append(BatchTask(tid, kind=p.kind, index=i, posture=p.posture, posture_file=p.name, posture_digest=p.digest, **common))
    return tasks
