"""robot-rise robot: inspect a robot directory, or make a scaled variant (retargeting)."""

from __future__ import annotations

import argparse
import dataclasses

from robot_rise.cli._common import Formatter, load_robot_arg, print_json
from robot_rise.model import compose
from robot_rise.errors import ConfigError
from robot_rise.retarget import BodyScale, scale_robot
from robot_rise.robot_import import import_robot


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("robot", help="inspect a robot or make a scaled variant", formatter_class=Formatter,
                       epilog="example:\n  robot-rise robot scale --arms 1.3 --torso 1.2 --out robots/op3_long")
    rsub = p.add_subparsers(dest="robot_command", metavar="ACTION", required=True)
    show = rsub.add_parser("show", help="joints, limits, servos, mass", formatter_class=Formatter,
                           epilog="example:\n  robot-rise robot show --robot configs/robots/op3")
    show.add_argument("--robot", metavar="DIR", help="robot directory (default: the embedded robot)")
    show.add_argument("--json", action="store_true", help="print one JSON object instead of the text")
    show.set_defaults(func=run_show)
    sc = rsub.add_parser("scale", help="write a robot directory with scaled arms, legs and torso",
                         formatter_class=Formatter,
                         epilog="example:\n  robot-rise robot scale --arms 1.3 --torso 1.2 --out robots/op3_long\n"
                         "  robot-rise rise --robot robots/op3_long --from lying.json --out rise.json")
    sc.add_argument("--robot", metavar="DIR", help="source robot directory (default: the embedded robot)")
    sc.add_argument("--out", required=True, metavar="DIR", help="new robot directory")
    sc.add_argument("--arms", type=float, default=1.0, help="arm segment length factor (default 1.0)")
    sc.add_argument("--legs", type=float, default=1.0, help="leg segment length factor (default 1.0)")
    sc.add_argument("--torso", type=float, default=1.0, help="torso length factor (default 1.0)")
    sc.add_argument("--name", help="new robot name (default: <source>_scaled)")
    sc.add_argument("--json", action="store_true", help="print one JSON object instead of the text")
    sc.set_defaults(func=run_scale)
    im = rsub.add_parser(
        "import",
        help="write a robot directory from an MJCF, URDF or xacro file",
        formatter_class=Formatter,
        description="Import a robot as its team published it: strips actuators and sensors (robot_rise adds its own servo\n"
        "model), keeps collision filters, copies meshes, infers legs, arms, head, joint roles and signs, adds sole and\n"
        "torso sites, finds a standing posture (the 'stand' keyframe, else searched and held by the servo model) and\n"
        "writes robot.toml (every inference, to correct by editing it) and servos.toml. ROS packages (package://,\n"
        "$(find)), file names whose case differs from the disk, CAD inertias and meshes MuJoCo refuses, fixed links\n"
        "between the base and the limbs, and root frames that are not x forward, z up are handled; each fix is printed.",
        epilog="examples:\n  robot-rise robot import wolfgang.xml --out robots/wolfgang --servo-model MX-106 --servo-model KNEE_JOINT=XH540-W270\n"
        "  robot-rise robot import my_description/urdf/robot.urdf --out robots/mine --servos my_servos.toml\n"
        "  robot-rise robot import robot.urdf.xacro --package-path ~/ws/src --servos my_servos.toml --out robots/mine --dry-run",
    )
    im.add_argument("model", metavar="MODEL", help="MJCF (.xml), URDF (.urdf, any case) or xacro (.xacro, .urdf.xacro)")
    im.add_argument("--out", required=True, metavar="DIR", help="robot directory to write (must not exist, unless --force)")
    src = im.add_mutually_exclusive_group(required=True)
    src.add_argument("--servos", metavar="SERVOS.toml", help="your servo map (IDs, models, directions, offsets, limits)")
    src.add_argument("--servo-model", action="append", metavar="M|JOINT=M", help="write a template servo map: M for every joint, JOINT=M for one (repeat)")
    im.add_argument("--name", help="robot name (default: the model file's name)")
    im.add_argument("--supply-voltage", type=float, metavar="V",
                    help="the servos' supply in volts, e.g. 14.8 for a 4S LiPo (default: the servo map's, else 12.0)")
    im.add_argument("--force", action="store_true", help="replace an existing --out directory")
    im.add_argument("--package-path", action="append", default=[], metavar="DIR",
                    help="a directory holding ROS packages (or a package) for package://NAME and $(find NAME); repeat for more;\n"
                    "searched after the model file's own ancestors and before ROS_PACKAGE_PATH")
    im.add_argument("--stand", metavar="POSTURE.json",
                    help="the robot standing (format robot-rise/posture@1): tried before the model's 'stand' keyframe and the search")
    im.add_argument("--dry-run", action="store_true", help="print every inference and fix, write nothing")
    im.add_argument("--json", action="store_true", help="print one JSON object (the inferences and fixes in 'notes') instead of the text")
    im.set_defaults(func=run_import)


def register_bench(bsub: argparse._SubParsersAction) -> None:
    b = bsub.add_parser(
        "import", help="import every robot file of ../shared/robots and a synthetic file per import feature",
        formatter_class=Formatter,
        description="Per file: imported or the one-line reason, the body's mass against the file's, collision geoms kept,\n"
        "roles found, the standing posture, seconds (one process).",
        epilog="example:\n  robot-rise bench import --robots ../shared/robots",
    )  # fmt: skip
    b.add_argument("--robots", metavar="DIR", default="../shared/robots", help="the published robot files (default: ../shared/robots)")
    b.add_argument("--no-synthetic", action="store_true", help="only the published files")
    b.add_argument("--json", action="store_true", help="print JSON")
    b.set_defaults(func=run_bench_import)


def run_bench_import(args: argparse.Namespace) -> int:
    import dataclasses
    import sys
    from pathlib import Path

    from robot_rise.bench.import_robots import bench_import, format_import_table
    from robot_rise.cli._common import print_json

    rows = bench_import(Path(args.robots), synthetic=not args.no_synthetic, progress=lambda line: print(line, file=sys.stderr, flush=True))
    if args.json:
        print_json([dataclasses.asdict(r) for r in rows])
    else:
        print(format_import_table(rows))
    return 0 if all(r.imported for r in rows) else 1


def run_show(args: argparse.Namespace) -> int:
    robot = load_robot_arg(args)
    m = compose(robot, None)
    if args.json:
        print_json({"name": robot.name, "directory": str(robot.directory), "library": str(robot.library),
                    "supply_voltage_v": robot.supply_voltage_v, "mass_kg": float(m.body_mass.sum()),
                    "stand_height_m": robot.stand_height_m,
                    "joints": [{"id": s.id, "joint": s.joint, "model": s.model, "lower_rad": float(lo), "upper_rad": float(hi)}
                               for s, lo, hi in zip(robot.servos, robot.joint_lower, robot.joint_upper)]})
        return 0
    print(f"robot {robot.name} ({robot.directory}); library {robot.library}; servo supply {robot.supply_voltage_v:g} V")
    print(f"  mass {m.body_mass.sum():.3f} kg, stand height {robot.stand_height_m:.3f} m (torso above soles)")
    for s, lo, hi in zip(robot.servos, robot.joint_lower, robot.joint_upper):
        print(f"  id {s.id:2d} {s.joint:12s} {s.model:11s} [{lo:+.3f}, {hi:+.3f}] rad")
    return 0


def run_scale(args: argparse.Namespace) -> int:
    src = load_robot_arg(args)
    robot = scale_robot(src, args.out, BodyScale(arms=args.arms, legs=args.legs, torso=args.torso), name=args.name)
    m = compose(robot, None)
    if args.json:
        print_json({"directory": str(args.out), "name": robot.name, "mass_kg": float(m.body_mass.sum()),
                    "stand_height_m": robot.stand_height_m})
        return 0
    print(f"wrote {args.out}: robot {robot.name}, mass {m.body_mass.sum():.3f} kg, stand height {robot.stand_height_m:.3f} m")
    return 0


def run_import(args: argparse.Namespace) -> int:
    models: dict[str, str] = {}
    for item in args.servo_model or ():
        joint, sep, model = item.partition("=")
        if sep and not (joint and model):
            raise ConfigError(f"--servo-model {item!r}: expected MODEL or JOINT=MODEL")
        models[joint if sep else "*"] = model if sep else joint
    result = import_robot(args.model, args.out, servos=args.servos, servo_models=models or None, name=args.name,
                           supply_voltage_v=args.supply_voltage, force=args.force, package_paths=args.package_path,
                           stand=args.stand, dry_run=args.dry_run)
    if args.json:
        print_json({**dataclasses.asdict(result), "directory": str(result.directory)})
        return 0
    for note in result.notes:
        print(f"  {note}")
    if not result.written:
        print(f"dry run: robot {result.name} would import into {result.directory} (nothing written)")
        return 0
    print(f"wrote {result.directory}: robot {result.name} (check robot.toml and servos.toml; build its library: robot-rise library build --robot {result.directory})")
    return 0
