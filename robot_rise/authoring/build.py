"""``build_library``: every strategy adapted to a robot, timed, proven and written, with a report of what works for which lying kind.

The strategies are independent, so they are authored in parallel (one process per strategy, each
into its own scratch directory); the passing motions are then moved into the library directory
and the index written once, in strategy order, atomically. The report says per lying kind which
motions were proven and why the others were not, and names a lying kind with no proven motion.

Turn-over strategies (``"lands"``) come second, and only for a lying kind the get-ups left without
a motion: each is followed by the robot's proven get-ups of the kind it lands in, quickest first
(:func:`robot_rise.authoring.turn_over.author_turn_over`, started when the body lies at rest there:
:func:`robot_rise.authoring.turn_over.landing`), and the first proven is written.
"""

from __future__ import annotations

import json
import logging
import shutil
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from robot_rise.authoring.robustness import robustness_players
from robot_rise.authoring.turn_over import author_turn_over, landing
from robot_rise.authoring.write import author_library
from robot_rise.errors import ConfigError
from robot_rise.fileio import write_text_atomic
from robot_rise.library import LIBRARY_FORMAT, LYING_KINDS, Strategy, load_strategies
from robot_rise.model import Robot, load_robot
from robot_rise.trajectory import read_trajectory

__all__ = ["BuildReport", "build_library", "BUILD_REPORT_FORMAT", "PROGRESS_EVERY_S"]

PROGRESS_EVERY_S = 30.0  # a build says what it is doing at least this often (it runs for minutes)

BUILD_REPORT_FORMAT = "robot-rise/library-build@1"
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BuildReport:
    """What ``build_library`` did: index rows written, the reason per strategy not written, the
    rows of the library's earlier motions a partial build (``names``) left in place, and the
    turn-overs not built because their lying kind has a motion."""

    robot: str
    directory: Path
    written: tuple[dict, ...]
    failed: dict[str, str] = field(default_factory=dict)
    lying: dict[str, str] = field(default_factory=dict)  # strategy name -> lying kind
    kept: tuple[dict, ...] = ()
    skipped: dict[str, str] = field(default_factory=dict)  # turn-overs not needed: their lying kind has a motion

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
            "skipped": [{"name": n, "lying": self.lying.get(n, ""), "reason": r} for n, r in self.skipped.items()],
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


def _author_turn_over(robot: Robot | str, turn: str, get_ups: list[tuple[dict, str]], scratch: str,
                      strategies: tuple[Strategy, ...] | None = None) -> tuple[list[dict], dict[str, str]]:
    """The turn-over ``turn`` followed by each of ``get_ups`` ((index row, trajectory file),
    quickest first) until one is written (:func:`robot_rise.authoring.turn_over.author_turn_over`);
    ``robot`` is the robot, or its directory in a worker process."""
    try:
        robot = load_robot(robot) if isinstance(robot, str) else robot
        turn_over = next(s for s in (strategies if strategies is not None else load_strategies()) if s.name == turn)
        players = robustness_players(robot)
        landed = landing(robot, turn_over, players)
        if landed.landed_s is None:
            return [], {turn: f"does not land {turn_over.lands}: {landed.reason}"}
        reasons = []
        for row, path in get_ups:
            written, why = author_turn_over(Path(scratch), robot, turn_over, landed, row, read_trajectory(path), players)
            if written is not None:
                return [written], {}
            reasons.append(f"then {row['name']}: {why}")
        return [], {turn: f"lands {turn_over.lands} at rest by {landed.landed_s:.2f} s; " + "; ".join(reasons)}
    except Exception as e:  # as _author_one: this turn-over's failure, not the build's
        return [], {turn: f"crashed: {type(e).__name__}: {e}"}


@contextmanager
def _heartbeat(progress: Callable[[str], None] | None, what: Callable[[], str]) -> Iterator[None]:
    """Call ``progress`` every ``PROGRESS_EVERY_S`` with ``what()`` and the time so far, until the block ends."""
    if progress is None:
        yield
        return
    stop = threading.Event()
    t0 = time.monotonic()

    def beat() -> None:
        while not stop.wait(PROGRESS_EVERY_S):
            progress(f"  ... {what()} ({time.monotonic() - t0:.0f} s so far)")

    thread = threading.Thread(target=beat, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def build_library(
    robot: Robot,
    out_dir: Path | None = None,
    *,
    jobs: int = 1,
    names: list[str] | None = None,
    strategies: tuple[Strategy, ...] | None = None,
    progress: Callable[[str], None] | None = None,
) -> BuildReport:
    """Adapt, time, prove and write every strategy for ``robot`` into its library directory.

    Args:
        robot: the robot (with joint roles).
        out_dir: the library directory (default: ``<robot dir>/<robot.toml library>``).
        jobs: processes (strategies are authored in parallel).
        names: only these strategies (default: all).
        strategies: the strategies (default: the shipped ``configs/strategies``).
        progress: called with one line per strategy started and finished, and at least every
            ``PROGRESS_EVERY_S`` while one runs (the CLI prints them; None: silent).

    Raises:
        ConfigError: ``names`` names a strategy there is not.
    """
    everything = strategies if strategies is not None else load_strategies()
    unknown = sorted(set(names or ()) - {s.name for s in everything})
    if unknown:
        raise ConfigError(f"no strategy named {', '.join(unknown)}", hint=f"strategies: {', '.join(s.name for s in everything)}")
    chosen = [s for s in everything if not names or s.name in names]
    get_ups = [s for s in chosen if s.lands is None]
    turn_overs = [s for s in chosen if s.lands is not None]
    out = Path(out_dir) if out_dir is not None else robot.directory / robot.library
    out.mkdir(parents=True, exist_ok=True)
    index_path = out / "index.json"
    before: list[dict] = []
    if index_path.exists() and names:
        try:
            before = list(json.loads(index_path.read_text()).get("motions", []))
        except (ValueError, KeyError):
            before = []
    rows: dict[str, dict] = {}  # strategy name -> its row (a turn-over's row names the turn-over and the get-up)
    failed: dict[str, str] = {}
    skipped: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix=".build.", dir=out) as scratch_root:
        scratch = {s.name: Path(scratch_root) / s.name for s in chosen}
        say = progress or (lambda line: None)
        t_build = time.monotonic()

        def outcome(name: str, f: dict[str, str], t0: float) -> None:
            what = "proven, written" if name in rows else f"not proven: {f.get(name, '?')}"
            say(f"{name}: {what} ({time.monotonic() - t0:.0f} s; build {time.monotonic() - t_build:.0f} s)")

        running: list[str] = []
        with _heartbeat(progress, lambda: "building " + ", ".join(running)):
            if strategies is not None or jobs <= 1:
                for k, s in enumerate(get_ups, start=1):
                    say(f"[{k}/{len(get_ups)}] {s.name} ({s.lying}): adapting, timing and proving")
                    running[:] = [s.name]
                    t0 = time.monotonic()
                    f: dict[str, str] = {}
                    for r in author_library(scratch[s.name], robot, names=[s.name], strategies=tuple(chosen), failures=f):
                        rows[r["name"]] = r
                    failed |= f
                    outcome(s.name, f, t0)
                    log.info("%s: %s", s.name, "written" if s.name in rows else f"failed: {f.get(s.name)}")
            else:
                say(f"{len(get_ups)} get-up strategies on {jobs} processes: {', '.join(s.name for s in get_ups)}")
                with ProcessPoolExecutor(max_workers=jobs) as pool:
                    t0 = time.monotonic()
                    futures = {s.name: pool.submit(_author_one, str(robot.directory), s.name, str(scratch[s.name])) for s in get_ups}
                    running[:] = list(futures)
                    for name, fut in futures.items():
                        got, f = fut.result()
                        rows |= {r["name"]: r for r in got}
                        failed |= f
                        running.remove(name)
                        outcome(name, f, t0)
        rebuilt = {s.name for s in chosen}
        kept = [r for r in before if r["name"] not in rebuilt and r.get("turn_over") not in rebuilt]
        have = [*rows.values(), *kept]
        tasks: dict[str, list[tuple[dict, str]]] = {}
        known = {s.name for s in everything if s.lands is None}
        for turn in turn_overs:
            own = sorted(r["name"] for r in have if r["lying"] == turn.lying)
            followers = sorted((r for r in have if r["lying"] == turn.lands and r["name"] in known), key=lambda r: float(r["duration_s"]))
            if own:
                skipped[turn.name] = f"not needed: lying {turn.lying} has {', '.join(own)}"
            elif not followers:
                failed[turn.name] = f"lands {turn.lands}, and the robot has no proven {turn.lands} get-up to follow it"
            else:
                # a get-up of this build is still in its scratch directory, a kept one in the library's
                tasks[turn.name] = [(r, str((scratch[r["name"]] if r["name"] in rows else out) / r["trajectory"])) for r in followers]
        if tasks:
            say(f"turn-overs onto a proven get-up: {', '.join(tasks)}")
        running[:] = list(tasks)
        with _heartbeat(progress, lambda: "building " + ", ".join(running)):
            if strategies is not None or jobs <= 1:
                done = {t: _author_turn_over(robot, t, g, str(scratch[t]), tuple(everything)) for t, g in tasks.items()}
            else:
                with ProcessPoolExecutor(max_workers=jobs) as pool:
                    futures = {t: pool.submit(_author_turn_over, str(robot.directory), t, g, str(scratch[t])) for t, g in tasks.items()}
                    done = {t: fut.result() for t, fut in futures.items()}
        for turn, (got, f) in done.items():
            if got:
                rows[turn] = got[0]
            failed |= f
            say(f"{turn}: " + (f"proven, written as {got[0]['name']}" if got else f"not proven: {f.get(turn, '?')}"))
            log.info("%s: %s", turn, f"written as {got[0]['name']}" if got else f"failed: {f.get(turn)}")
        for name, row in rows.items():
            for key in ("trajectory", "start"):
                shutil.move(str(scratch[name] / row[key]), str(out / row[key]))
    written = tuple(rows[s.name] for s in chosen if s.name in rows)
    index = {"format": LIBRARY_FORMAT, "robot": robot.name, "motions": [*kept, *written]}
    write_text_atomic(index_path, json.dumps(index, indent=1) + "\n")
    report = BuildReport(robot.name, out, written, {s.name: failed[s.name] for s in chosen if s.name in failed}, {s.name: s.lying for s in chosen},
                         tuple(kept), {s.name: skipped[s.name] for s in chosen if s.name in skipped})
    write_text_atomic(out / "build_report.json", json.dumps(report.to_dict(), indent=1) + "\n")
    return report
