"""``build_library``: every strategy adapted to a robot, timed, proven and written, with a report of what works for which lying kind.

The strategies are independent, so they are authored in parallel (one process per strategy, each
into its own scratch directory); the passing motions are then moved into the library directory
and the index written once, in strategy order, atomically. The report says per lying kind which
motions were proven and why the others were not, and names a lying kind with no proven motion.
"""

from __future__ import annotations

import json
import logging
import shutil
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from robot_rise.authoring.write import author_library
from robot_rise.fileio import write_text_atomic
from robot_rise.library import LIBRARY_FORMAT, LYING_KINDS, Strategy, load_strategies
from robot_rise.model import Robot, load_robot

__all__ = ["BuildReport", "build_library", "BUILD_REPORT_FORMAT"]

BUILD_REPORT_FORMAT = "robot-rise/library-build@1"
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BuildReport:
    """What ``build_library`` did: index rows written, the reason per strategy not written, and
    the rows of the library's earlier motions a partial build (``names``) left in place."""

    robot: str
    directory: Path
    written: tuple[dict, ...]
    failed: dict[str, str] = field(default_factory=dict)
    lying: dict[str, str] = field(default_factory=dict)  # strategy name -> lying kind
    kept: tuple[dict, ...] = ()

    def kinds_without_motion(self) -> tuple[str, ...]:
        """Lying kinds the library (written and kept motions) has no motion for."""
        have = {r["lying"] for r in (*self.written, *self.kept)}
        return tuple(k for k in LYING_KINDS if k not in have)

    def to_dict(self) -> dict:
        return {
            "format": BUILD_REPORT_FORMAT,
            "robot": self.robot,
            "written": list(self.written),
            "kept": list(self.kept),
            "failed": [{"name": n, "lying": self.lying.get(n, ""), "reason": r} for n, r in self.failed.items()],
            "kinds_without_motion": list(self.kinds_without_motion()),
        }


def _author_one(robot_dir: str, name: str, scratch: str) -> tuple[list[dict], dict[str, str]]:
    failures: dict[str, str] = {}
    try:
        rows = author_library(Path(scratch), load_robot(robot_dir), names=[name], failures=failures)
    except Exception as e:  # one strategy's crash must not stop the build: it is that strategy's failure
        failures[name] = f"crashed: {type(e).__name__}: {e}"
        rows = []
    return rows, failures


def build_library(
    robot: Robot, out_dir: Path | None = None, *, jobs: int = 1, names: list[str] | None = None, strategies: tuple[Strategy, ...] | None = None
) -> BuildReport:
    """Adapt, time, prove and write every strategy for ``robot`` into its library directory.

    Args:
        robot: the robot (with joint roles).
        out_dir: the library directory (default: ``<robot dir>/<robot.toml library>``).
        jobs: processes (strategies are authored in parallel).
        names: only these strategies (default: all).
        strategies: the strategies (default: the shipped ``configs/strategies``).
    """
    chosen = [s for s in (strategies if strategies is not None else load_strategies()) if not names or s.name in names]
    out = Path(out_dir) if out_dir is not None else robot.directory / robot.library
    out.mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict] = {}
    failed: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix=".build.", dir=out) as scratch_root:
        scratch = {s.name: Path(scratch_root) / s.name for s in chosen}
        if strategies is not None or jobs <= 1:
            for s in chosen:
                f: dict[str, str] = {}
                for r in author_library(scratch[s.name], robot, names=[s.name], strategies=tuple(chosen), failures=f):
                    rows[r["name"]] = r
                failed |= f
                log.info("%s: %s", s.name, "written" if s.name in rows else f"failed: {f.get(s.name)}")
        else:
            with ProcessPoolExecutor(max_workers=jobs) as pool:
                futures = {s.name: pool.submit(_author_one, str(robot.directory), s.name, str(scratch[s.name])) for s in chosen}
                for name, fut in futures.items():
                    got, f = fut.result()
                    rows |= {r["name"]: r for r in got}
                    failed |= f
        for name, row in rows.items():
            for key in ("trajectory", "start"):
                shutil.move(str(scratch[name] / row[key]), str(out / row[key]))
    index_path = out / "index.json"
    old = []
    if index_path.exists() and names:
        try:
            old = [r for r in json.loads(index_path.read_text()).get("motions", []) if r["name"] not in rows and r["name"] not in failed]
        except (ValueError, KeyError):
            old = []
    written = tuple(rows[s.name] for s in chosen if s.name in rows)
    index = {"format": LIBRARY_FORMAT, "robot": robot.name, "motions": [*old, *written]}
    write_text_atomic(index_path, json.dumps(index, indent=1) + "\n")
    report = BuildReport(robot.name, out, written, {s.name: failed[s.name] for s in chosen if s.name in failed}, {s.name: s.lying for s in chosen},
                         tuple(old))
    write_text_atomic(out / "build_report.json", json.dumps(report.to_dict(), indent=1) + "\n")
    return report
