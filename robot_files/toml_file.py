"""TOML files: the one reader helper (one line whatever the file holds) and the one writer.

Reading is the standard library's ``tomllib``; writing is ``tomli-w`` (the two agree on every
value: what :func:`write_toml` writes, :func:`read_toml` reads back equal). TOML writers keep no
comments, so a file's comments are given as a header of ``#`` lines.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import tomli_w

from robot_files.errors import RobotFileError

__all__ = ["read_toml", "toml_text", "write_toml"]


def read_toml(path: str | os.PathLike[str], what: str, *, hint: str = "") -> dict[str, Any]:
    """The tables of the TOML file ``path``.

    Args:
        path: the file.
        what: what it should be, for messages ("servo map", "servo catalog", "file").
        hint: the hint of a missing file's error.

    Raises:
        RobotFileError: missing, unreadable (a directory, no permission), not UTF-8 or not TOML;
            one line naming the file.
    """
    p = Path(path)
    try:
        with open(p, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise RobotFileError(f"missing {what} {p}", hint=hint) from None
    except OSError as e:
        raise RobotFileError(f"{p}: cannot read {what}: {e.strerror or e}") from None
    except tomllib.TOMLDecodeError as e:
        raise RobotFileError(f"{p}: not valid TOML: {e}") from None
    except UnicodeDecodeError as e:
        raise RobotFileError(f"{p}: not UTF-8 text (byte {e.start}): not a {what}") from None


def toml_text(data: Mapping[str, Any], *, comments: Sequence[str] = ()) -> str:
    """``data`` as TOML text (``tomli-w``), after ``comments`` as ``#`` lines.

    Raises:
        RobotFileError: a value TOML cannot hold (None, an object).
    """
    try:
        body = tomli_w.dumps(data)
    except (TypeError, ValueError) as e:
        raise RobotFileError(f"cannot write TOML: {e}") from None
    header = "".join(f"# {line}\n" if line else "#\n" for line in comments)
    return header + body


def write_toml(path: str | os.PathLike[str], data: Mapping[str, Any], *, comments: Sequence[str] = ()) -> None:
    """Write ``data`` to ``path`` as TOML (see :func:`toml_text`)."""
    Path(path).write_text(toml_text(data, comments=comments), encoding="utf-8")
