"""``robot-rise library list|show|play NAME|bench|author|build|prove|add FILE``: inspect, replay, benchmark, author, re-prove and extend the motion library."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from robot_rise.cli import EXIT_FAILURE, EXIT_OK
from robot_rise.cli._common import Formatter, print_json
from robot_rise.constants import ENVELOPE_MARGIN
from robot_rise.errors import ConfigError

__all__ = ["register"]


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "library",
        help="inspect, replay, benchmark, author, re-prove and add to the get-up motion library",
        epilog="Example: robot-rise library play prone_knees_first --friction 0.5 --mass 1.1",
    )
    p.add_argument("--dir", type=Path, default=None, help="library directory (default: configs/motions/<robot>)")
    p.add_argument("--robot", type=Path, default=None, help="robot directory (default: the embedded OP3-class robot)")
    sub = p.add_subparsers(dest="library_command", metavar="ACTION", required=True)
    sub.add_parser("list", help="one line per motion", formatter_class=Formatter,
                   epilog="examples:\n  robot-rise library list\n  robot-rise library list --robot robots/wolfgang --json",
                   ).set_defaults(func=_list)
    s = sub.add_parser("show", help="details of one motion", formatter_class=Formatter,
                       epilog="example:\n  robot-rise library show prone_knees_first")
    s.add_argument("name")
    s.set_defaults(func=_show)
    pl = sub.add_parser(
        "play",
        help="play a motion through the servo model and print the judge's verdict",
        formatter_class=Formatter,
        description="Replay one motion of the library from its start posture through the servo model in MuJoCo (optionally\n"
        "with scaled friction and link masses) and print the standing judge's verdict. Exit code 0 if it stands\n"
        "within the envelope without self-collision, 1 if not.",
        epilog="example:\n  robot-rise library play prone_knees_first --friction 0.5 --mass 1.1",
    )
    pl.add_argument("name")
    pl.add_argument("--scene", default="flat", help="scene name or MJCF path (default: flat)")
    pl.add_argument("--friction", type=float, default=1.0, help="friction scale (default 1.0)")
    pl.add_argument("--mass", type=float, default=1.0, help="link mass scale (default 1.0)")
    pl.set_defaults(func=_play)
    b = sub.add_parser("bench", help="connecting-posture selection: K-means tree vs brute force", formatter_class=Formatter,
                       epilog="example:\n  robot-rise library bench --n 1000 --seed 0")
    b.add_argument("--n", type=int, default=1000, help="random lying postures (default 1000)")
    b.add_argument("--seed", type=int, default=0)
    b.set_defaults(func=_bench)
    a = sub.add_parser(
        "author",
        help="regenerate the shipped OP3 motions from the strategies (settle, retime, verify, write; minutes per motion)",
        description="Regenerate a motion library from the strategies in configs/strategies (role keyframes mapped onto "
        "the robot's joints): each motion is settled, retimed in MuJoCo and verified on nominal and the four friction/mass corners; "
        "only passing motions are written and their index rows added or replaced. Progress is logged with -v.",
        epilog="Example: robot-rise -v library author --out /tmp/op3 --only prone_knees_first",
    )
    a.add_argument("--out", type=Path, default=None, help="library directory to write (default: --dir, else configs/motions/op3)")
    a.add_argument(
        "--only",
        "--names",
        dest="names",
        nargs="*",
        default=None,
        metavar="NAME",
        help="motions to rebuild (their index rows are replaced or added; others kept); default: all, dropping rows of motions no longer authored",
    )
    a.set_defaults(func=_author)
    bu = sub.add_parser(
        "build",
        help="adapt every strategy to a robot, prove each with the ensemble, write its library and a report",
        description="Build a robot's motion library from the shipped strategies (configs/strategies: get-up motions "
        "written in joint roles). Each strategy is mapped onto the robot's joints by the [roles] of its robot.toml, its "
        "lying posture settled, its timing found in MuJoCo against the servos' envelope, verified on the friction/mass "
        "corners and proven on the ensemble; only proven motions are written. The report says which strategies work "
        "for which lying kind and why the others failed (also written as build_report.json). A "
        "turn-over strategy (one that ends lying, e.g. a roll onto the front) is built only for a lying kind left without a "
        "motion, followed by the robot's own get-up from where it lands.",
        epilog="Example: robot-rise library build --robot robots/wolfgang --jobs 2",
    )
    bu.add_argument("--out", type=Path, default=None, help="library directory (default: the robot directory's library, robot.toml 'library')")
    bu.add_argument("--jobs", type=int, default=1, help="processes: strategies are built in parallel (default 1)")
    bu.add_argument("--only", dest="names", nargs="*", default=None, metavar="NAME", help="strategies to build (default: all)")
    bu.set_defaults(func=_build)
    pr = sub.add_parser(
        "prove",
        help="re-prove every motion in place (fresh proofs in the files' reports; rows kept)",
        description="Replay every motion of the library from its start posture, judge it, and write the proof into "
        "the file's report (what execute checks before anything moves), without re-authoring it: after the robot "
        "files or the proof changed. A start or row up to four servo ticks past a joint limit is clamped into it; "
        "other rows and entries are kept byte for byte, files are written atomically and only when they change. "
        "Exit code 0 if every motion is proven, 1 if not (its failing proof is written).",
        epilog="Example: robot-rise library prove --dir /tmp/op3",
    )
    pr.add_argument("--dir", default=argparse.SUPPRESS, type=Path, help="library directory (as library --dir DIR)")
    pr.set_defaults(func=_prove)
    ad = sub.add_parser(
        "add",
        help="add your own get-up (keyframes: CSV of joint angles and times, or MuJoCo keyframes) to the library, proven like ours",
        formatter_class=Formatter,
        description="Read keyframes of your own get-up and add them to the robot's library, proven as the library's\n"
        "own motions are. FILE is a CSV with the header 'time_s,<joint>,...' (radians, or --degrees; every\n"
        "driven joint of the robot) and a row per keyframe, or MuJoCo keyframes (.xml: <keyframe><key time\n"
        "qpos/>) of the robot's own model, as export-keyframes writes them. The start is the first keyframe\n"
        "lying as --lying says, settled on the floor (a MuJoCo file's first key where the model has a free\n"
        "joint). The motion must stand on nominal and the four friction/mass corners within the envelope,\n"
        "then its ensemble proof must hold; only then are its files and index row written (atomically).\n"
        "Exit code 0 if proven and written, 1 if not proven (nothing written; with --unproven it is written\n"
        "with proven=false, which execute and getup refuse).",
        epilog="examples:\n  robot-rise library add my_getup.csv --name my_getup --lying prone --dir /tmp/op3\n"
        "  robot-rise library add keys.xml --name my_roll --robot robots/wolfgang --json",
    )
    ad.add_argument("file", metavar="FILE", help="keyframes: a .csv (time_s and joint angles) or a .xml (MuJoCo keyframes)")
    ad.add_argument("--name", required=True, help="the motion's name (its file stem in the library)")
    ad.add_argument("--lying", choices=("supine", "prone", "left", "right"), default=None,
                    help="how the first keyframe lies (needed for a CSV; a MuJoCo file's root is checked against it)")
    ad.add_argument("--degrees", action="store_true", help="the CSV's angles are in degrees (default: radians)")
    ad.add_argument("--strategy", default="", metavar="TEXT", help="one line for people (default: 'imported from FILE')")
    ad.add_argument("--connect-until", dest="connect_until_s", type=float, default=None, metavar="S",
                    help="end of its lying-to-sitting/squatting phase [s] (default: the last row before the body comes upright)")
    ad.add_argument("--unproven", action="store_true", help="write it even when not proven (proven=false: execute and getup refuse it)")
    ad.set_defaults(func=_add)
    # --robot and --dir before the action or after it: `library build --robot DIR` as the help examples write it
    for action in sub.choices.values():
        names = {o for a in action._actions for o in a.option_strings}
        action.add_argument("--json", action="store_true", help="print one JSON object instead of the text")
        if "--robot" not in names:
            action.add_argument("--robot", type=Path, default=argparse.SUPPRESS, help="robot directory (as library --robot DIR)")
        if "--dir" not in names:
            action.add_argument("--dir", type=Path, default=argparse.SUPPRESS, help="library directory (as library --dir DIR)")


def _load(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from robot_rise.library import load_library, robot_library_dir
    from robot_rise.model import load_robot

    robot = load_robot(args.robot)
    return robot, load_library(args.dir if args.dir is not None else robot_library_dir(robot))


def _list(args: argparse.Namespace) -> int:
    _, lib = _load(args)
    if args.json:
        print_json({"motions": [{"name": m.name, "lying": m.lying, "duration_s": m.duration_s,
                                 "peak_envelope_ratio": m.trajectory.report.get("peak_envelope_ratio"),
                                 "strategy": m.strategy} for m in lib.motions]})
        return EXIT_OK
    print(f"{'name':24s} {'lying':7s} {'duration':>9s} {'peak':>5s}  strategy")
    for m in lib.motions:
        peak = m.trajectory.report.get("peak_envelope_ratio")
        peak_s = f"{peak:.2f}" if isinstance(peak, (int, float)) else "-"
        print(f"{m.name:24s} {m.lying:7s} {m.duration_s:8.2f}s {peak_s:>5s}  {m.strategy}")
    return EXIT_OK


def _show(args: argparse.Namespace) -> int:
    _, lib = _load(args)
    m = lib.get(args.name)
    tr = m.trajectory
    if args.json:
        print_json({"name": m.name, "lying": m.lying, "strategy": m.strategy, "duration_s": m.duration_s, "rows": len(tr.t),
                    "connect_until_s": m.connect_until_s, "start_root_pos": [float(x) for x in m.start.root_pos],
                    "start_root_quat_wxyz": [float(x) for x in m.start.root_quat_wxyz],
                    **{k: tr.report[k] for k in ("verdict", "keyframe_times_s") if k in tr.report}})
        return EXIT_OK
    print(f"name:            {m.name}")
    print(f"lying:           {m.lying}")
    print(f"strategy:        {m.strategy}")
    print(f"duration:        {m.duration_s:.3f} s, {len(tr.t)} rows")
    print(f"connect until:   {m.connect_until_s:.3f} s (lying-to-squatting phase indexed for selection)")
    print(f"start root:      pos {[round(float(x), 4) for x in m.start.root_pos]}, quat {[round(float(x), 4) for x in m.start.root_quat_wxyz]}")
    for k in ("verdict", "keyframe_times_s"):
        if k in tr.report:
            print(f"{k + ':':17s}{tr.report[k]}")
    return EXIT_OK


def _play(args: argparse.Namespace) -> int:
    from robot_rise.sim.standing import judge
    from robot_rise.sim.player import Player

    robot, lib = _load(args)
    m = lib.get(args.name)
    player = Player(robot, args.scene, friction_scale=args.friction, mass_scale=args.mass)
    rec = player.play(m.trajectory, m.start)
    v = judge(rec)
    ok = v.standing and v.peak_envelope_ratio <= 1.0 - ENVELOPE_MARGIN and not v.self_collision
    if args.json:
        print_json({"name": m.name, "ok": ok, "summary": v.summary(), "verdict": dataclasses.asdict(v),
                    "duration_s": m.duration_s, "wall_time_s": rec.wall_time_s})
        return EXIT_OK if ok else EXIT_FAILURE
    print(f"{m.name}: {v.summary()}")
    print(f"duration {m.duration_s:.2f} s, played in {rec.wall_time_s:.2f} s wall")
    return EXIT_OK if ok else EXIT_FAILURE


def _bench(args: argparse.Namespace) -> int:
    from robot_rise.bench.library import bench_selection

    robot, lib = _load(args)
    result = bench_selection(robot, lib, n=args.n, seed=args.seed)
    if args.json:
        print_json(dataclasses.asdict(result) | {"agreement": result.agreement})
        return EXIT_OK if result.agreement >= 0.99 else EXIT_FAILURE
    print(result.markdown())
    return EXIT_OK if result.agreement >= 0.99 else EXIT_FAILURE


def _author(args: argparse.Namespace) -> int:
    from robot_rise.authoring import author_library
    from robot_rise.model import load_robot
    from robot_rise.paths import configs_dir

    out = args.out or args.dir or configs_dir() / "motions" / "op3"
    entries = author_library(out, load_robot(args.robot), names=args.names)
    if args.json:
        print_json({"directory": str(out), "written": list(entries)})
        return EXIT_OK if entries else EXIT_FAILURE
    for row in entries:
        print(f"{row['name']:24s} {row['duration_s']:6.2f}s  written to {out}")
    return EXIT_OK if entries else EXIT_FAILURE


def _build(args: argparse.Namespace) -> int:
    from robot_rise.authoring.build import build_library
    from robot_rise.model import load_robot

    robot = load_robot(args.robot)
    if args.jobs < 1:
        raise ConfigError("--jobs must be at least 1")
    report = build_library(robot, args.out, jobs=args.jobs, names=args.names, progress=lambda line: print(line, file=sys.stderr, flush=True))
    code = EXIT_OK if report.written or not report.failed else EXIT_FAILURE
    if args.json:
        print_json({"directory": str(report.directory), **report.to_dict()})
        return code
    print(f"library of {robot.name}: {report.directory}")
    for row in report.written:
        print(f"  proven   {row['lying']:7s} {row['name']:26s} {row['duration_s']:6.2f} s")
    for name, reason in report.failed.items():
        print(f"  failed   {report.lying.get(name, ''):7s} {name:26s} {reason}")
    for name, reason in report.skipped.items():
        print(f"  skipped  {report.lying.get(name, ''):7s} {name:26s} {reason}")
    for row in report.kept:
        print(f"  kept     {row.get('lying', ''):7s} {row.get('name', ''):26s} (not rebuilt)")
    for kind in report.kinds_without_motion():
        print(f"  no proven motion for lying {kind}: rise from {kind} postures will fail on this robot")
    return code


def _prove(args: argparse.Namespace) -> int:
    from robot_rise.authoring.write import reprove_library
    from robot_rise.model import load_robot

    results = reprove_library(args.dir, load_robot(args.robot))
    if args.json:
        print_json({"motions": [{"name": r.name, "proven": r.proof.proven, "problems": list(r.proof.problems),
                                 "peak_torque_ratio": r.proof.peak_torque_ratio, "clamped": list(r.clamped),
                                 "written": r.written} for r in results]})
        return EXIT_OK if all(r.proof.proven for r in results) else EXIT_FAILURE
    for r in results:
        verdict = "PROVEN" if r.proof.proven else "NOT PROVEN: " + "; ".join(r.proof.problems)
        clamped = f"; start clamped into the limits at {', '.join(r.clamped)}" if r.clamped else ""
        print(f"{r.name:24s} {verdict} (peak torque {r.proof.peak_torque_ratio:.2f} of the envelope){clamped}; "
              + ("written" if r.written else "unchanged"))
    return EXIT_OK if all(r.proof.proven for r in results) else EXIT_FAILURE


def _add(args: argparse.Namespace) -> int:
    from robot_rise.authoring.user_motion import add_motion
    from robot_rise.keyframe_import import read_keyframes
    from robot_rise.library import robot_library_dir
    from robot_rise.model import load_robot

    robot = load_robot(args.robot)
    keys = read_keyframes(args.file, robot, degrees=args.degrees)
    directory = args.dir if args.dir is not None else robot_library_dir(robot)
    r = add_motion(directory, robot, keys, name=args.name, lying=args.lying, strategy=args.strategy,
                   connect_until_s=args.connect_until_s, unproven=args.unproven)
    code = EXIT_OK if r.proven else EXIT_FAILURE
    if args.json:
        print_json({"name": r.name, "directory": str(r.directory), "lying": r.lying, "proven": r.proven, "reason": r.reason,
                    "written": r.written, "duration_s": r.duration_s, "keyframes": len(keys.time_s), "format": keys.format,
                    "row": r.row})
        return code
    if r.proven:
        print(f"{r.name}: PROVEN ({r.lying}, {r.duration_s:.2f} s, {len(keys.time_s)} keyframes); added to {r.directory}")
    else:
        written = "; written with proven=false (execute refuses it)" if r.written else "; nothing written"
        print(f"{r.name}: NOT PROVEN: {r.reason}{written}")
    return code
