"""The tamper campaign: proven trajectories edited after their proof, each edit refused before the bus.

Each file is edited ten ways, as a person or a script might (a joint's column moved 0.3 rad, one
row by 1 mrad, the proof's ``proven`` kept while ``command_limits`` is removed, two joints'
names swapped with their columns, time compressed, a row dropped, the root rows moved, the start
nudged, the seal removed, the proof standard relaxed); each edited file, read back from its JSON,
must be refused by the execution permit (which ``execute`` and ``getup`` apply before opening
the bus), and the untouched file must be allowed.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_rise.errors import FormatError
from robot_rise.proof import execution_permit
from robot_rise.fileio import read_json
from robot_rise.model import Robot
from robot_rise.trajectory import trajectory_from_dict

__all__ = ["TAMPERS", "TamperRow", "tamper_campaign"]


def _column(obj: dict[str, Any], joint: int, delta: float) -> None:
    for row in obj["q"]:
        row[joint] += delta


def _one_row(obj: dict[str, Any]) -> None:
    obj["q"][len(obj["q"]) // 2][0] += 1e-3


def _limits_removed(obj: dict[str, Any]) -> None:
    obj["report"].pop("command_limits", None)
    obj["report"]["proven"] = True


def _names_swapped(obj: dict[str, Any]) -> None:
    names = obj["joint_names"]
    names[0], names[1] = names[1], names[0]
    for row in obj["q"]:
        row[0], row[1] = row[1], row[0]


def _faster(obj: dict[str, Any]) -> None:
    obj["t"] = [round(0.9 * t, 6) for t in obj["t"]]


def _row_dropped(obj: dict[str, Any]) -> None:
    k = len(obj["t"]) // 2
    for key in ("t", "q", "root"):
        if obj.get(key) is not None:
            del obj[key][k]


def _root_moved(obj: dict[str, Any]) -> None:
    if obj.get("root"):
        for row in obj["root"]:
            row[2] += 0.01
    else:
        obj["root"] = None
        obj["q"][0][0] += 1e-4


def _start_nudged(obj: dict[str, Any]) -> None:
    joint = next(iter(obj["start"]["joints"]))
    obj["start"]["joints"][joint] += 1e-3


def _seal_removed(obj: dict[str, Any]) -> None:
    obj["report"].pop("seal", None)


def _standard_relaxed(obj: dict[str, Any]) -> None:
    obj["report"]["envelope_limit"] = 1.0


TAMPERS: dict[str, Callable[[dict[str, Any]], None]] = {
    "joint column +0.3 rad": lambda o: _column(o, 2, 0.3),
    "one row +1 mrad": _one_row,
    "command_limits removed, proven kept": _limits_removed,
    "two joints' names and columns swapped": _names_swapped,
    "times x0.9": _faster,
    "a row dropped": _row_dropped,
    "root rows moved 10 mm": _root_moved,
    "start posture +1 mrad": _start_nudged,
    "seal removed": _seal_removed,
    "envelope limit relaxed to 1.0": _standard_relaxed,
}


@dataclass(frozen=True)
class TamperRow:
    """One file's campaign: the untouched file allowed, and each edit refused (with the reason)."""

    file: str
    untouched_allowed: bool
    untouched_reason: str
    refused: dict[str, str]  # edit -> the permit's reason ('' where the edit was allowed: a miss)

    @property
    def misses(self) -> tuple[str, ...]:
        return tuple(edit for edit, reason in self.refused.items() if not reason)


def tamper_campaign(robot: Robot, files: list[Path]) -> list[TamperRow]:
    """Edit each file ten ways; judge each edited copy with the execution permit."""
    rows = []
    for path in files:
        obj = read_json(path, "trajectory file")
        assert isinstance(obj, dict)
        tr = trajectory_from_dict(obj, where=str(path))
        permit = execution_permit(tr.report, robot, tr)
        refused: dict[str, str] = {}
        for name, edit in TAMPERS.items():
            edited = copy.deepcopy(obj)
            edit(edited)
            try:
                etr = trajectory_from_dict(edited, where=f"{path} ({name})")
            except FormatError as e:  # the reader refuses it outright: refused too
                refused[name] = str(e)
                continue
            verdict = execution_permit(etr.report, robot, etr)
            refused[name] = "" if verdict.allowed else verdict.reason
        rows.append(TamperRow(str(path), permit.allowed, permit.reason, refused))
    return rows
