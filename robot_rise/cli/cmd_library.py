"""``robot-rise library list|show|play NAME|bench|author|prove``: inspect, replay, benchmark, author and re-prove the motion library."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_rise.cli import EXIT_FAILURE, EXIT_OK
from robot_rise.constants import ENVELOPE_MARGIN

__all__ = ["register"]


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "library",
        help="inspect, replay, benchmark, author and re-prove the get-up motion library",
        epilog="Example: robot-rise library play prone_knees_first --friction 0.5 --mass 1.1",
    )
    p.add_argument("--dir", type=Path, default=None, help="library directory (default: configs/motions/<robot>)")
    p.add_argument("--robot", type=Path, default=None, help="robot directory (default: the embedded OP3-class robot)")
    sub = p.add_subparsers(dest="library_command", metavar="ACTION", required=True)
    sub.add_parser("list", help="one line per motion").set_defaults(func=_list)
    s = sub.add_parser("show", help="details of one motion")
    s.add_argument("name")
    s.set_defaults(func=_show)
    pl = sub.add_parser("play", help="play a motion through the servo model and print the judge's verdict")
    pl.add_argument("name")
    pl.add_argument("--scene", default="flat", help="scene name or MJCF path (default: flat)")
    pl.add_argument("--friction", type=float, default=1.0, help="friction scale (default 1.0)")
    pl.add_argument("--mass", type=float, default=1.0, help="link mass scale (default 1.0)")
    pl.set_defaults(func=_play)
    b = sub.add_parser("bench", help="connecting-posture selection: K-means tree vs brute force")
    b.add_argument("--n", type=int, default=1000, help="random lying postures (default 1000)")
    b.add_argument("--seed", type=int, default=0)
    b.set_defaults(func=_bench)
    a = sub.add_parser(
        "author",
        help="regenerate the OP3 motions from their keyframes (settle, retime, verify, write; minutes per motion)",
        description="Regenerate the OP3 motion library from the keyframes in robot_rise.authoring.op3_motions: "
        "each motion is settled, retimed in MuJoCo and verified on nominal and the four friction/mass corners; "
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
    pr = sub.add_parser(
        "prove",
        help="re-prove every motion in place (fresh proofs in the files' reports; rows kept)",
        description="Replay every motion of the library from its start posture, judge it, and write the proof into "
        "the file's report (what execute checks before anything moves), without re-authoring it: after the robot "
        "files or the proof changed. A start or row up to two servo ticks past a joint limit is clamped into it; "
        "other rows and entries are kept byte for byte, files are written atomically and only when they change. "
        "Exit code 0 if every motion is proven, 1 if not (its failing proof is written).",
        epilog="Example: robot-rise library prove --dir /tmp/op3",
    )
    pr.add_argument("--dir", default=argparse.SUPPRESS, type=Path, help="library directory (as library --dir DIR)")
    pr.set_defaults(func=_prove)


def _load(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from robot_rise.library import load_library
    from robot_rise.model import load_robot

    robot = load_robot(args.robot)
    return robot, load_library(args.dir, robot_name=robot.name)


def _list(args: argparse.Namespace) -> int:
    _, lib = _load(args)
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
    print(f"{m.name}: {v.summary()}")
    print(f"duration {m.duration_s:.2f} s, played in {rec.wall_time_s:.2f} s wall")
    return EXIT_OK if v.standing and v.peak_envelope_ratio <= 1.0 - ENVELOPE_MARGIN and not v.self_collision else EXIT_FAILURE


def _bench(args: argparse.Namespace) -> int:
    from robot_rise.bench.library import bench_selection

    robot, lib = _load(args)
    result = bench_selection(robot, lib, n=args.n, seed=args.seed)
    print(result.markdown())
    return EXIT_OK if result.agreement >= 0.99 else EXIT_FAILURE


def _author(args: argparse.Namespace) -> int:
    from robot_rise.authoring import author_library
    from robot_rise.model import load_robot
    from robot_rise.paths import configs_dir

    out = args.out or args.dir or configs_dir() / "motions" / "op3"
    entries = author_library(out, load_robot(args.robot), names=args.names)
    for row in entries:
        print(f"{row['name']:24s} {row['duration_s']:6.2f}s  written to {out}")
    return EXIT_OK if entries else EXIT_FAILURE


def _prove(args: argparse.Namespace) -> int:
    from robot_rise.authoring.write import reprove_library
    from robot_rise.model import load_robot

    results = reprove_library(args.dir, load_robot(args.robot))
    for r in results:
        verdict = "PROVEN" if r.proof.proven else "NOT PROVEN: " + "; ".join(r.proof.problems)
        clamped = f"; start clamped into the limits at {', '.join(r.clamped)}" if r.clamped else ""
        print(f"{r.name:24s} {verdict} (peak torque {r.proof.peak_torque_ratio:.2f} of the envelope){clamped}; "
              + ("written" if r.written else "unchanged"))
    return EXIT_OK if all(r.proof.proven for r in results) else EXIT_FAILURE
