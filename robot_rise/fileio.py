"""Reading and writing our files: JSON read with one clear line whatever the file holds, and
written so that a reader never sees half of one (an interrupted write leaves the old file)."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

from robot_rise.errors import FormatError

__all__ = ["write_text_atomic", "read_json", "MAX_JSON_BYTES"]

MAX_JSON_BYTES = 512 * 1024 * 1024  # a trajectory of 20 joints at 500 Hz for an hour is ~300 MB


def read_json(path: str | os.PathLike[str], what: str) -> object:
    """A JSON file's content; FormatError naming the file and why not (missing, not a regular file
    such as a FIFO that would block, too large, not UTF-8 text, not JSON, nested too deep).

    Args:
        path: the file.
        what: what it should be, for messages ("posture file", "trajectory file").
    """
    p = Path(path)
    try:
        info = p.stat()
    except FileNotFoundError:
        raise FormatError(f"{p}: no such {what}") from None
    except OSError as e:
        raise FormatError(f"{p}: cannot read {what}: {e.strerror or e}") from None
    if not stat.S_ISREG(info.st_mode):
        raise FormatError(f"{p}: not a regular file (a directory, FIFO or device): cannot read it as a {what}")
    if info.st_size > MAX_JSON_BYTES:
        raise FormatError(f"{p}: {info.st_size / 1e6:.0f} MB is more than a {what} holds (at most {MAX_JSON_BYTES / 1e6:.0f} MB)")
    try:
        text = p.read_bytes().decode("utf-8")
    except UnicodeDecodeError as e:
        raise FormatError(f"{p}: not UTF-8 text (byte {e.start}): not a {what}") from None
    except OSError as e:
        raise FormatError(f"{p}: cannot read {what}: {e.strerror or e}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise FormatError(f"{p}: not valid JSON ({e})") from None
    except RecursionError:
        raise FormatError(f"{p}: JSON nested too deep to be a {what}") from None


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, then rename it over ``path`` (the
    temporary file is the process's own: two processes writing one path leave one whole file)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
