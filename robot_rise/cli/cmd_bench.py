"""robot-rise bench: print the figures BENCHMARKS.md records.

Other CLI modules can add benchmark sub-commands by exposing ``register_bench(subparsers)``.
"""

from __future__ import annotations

import argparse
import sys
import importlib
import pkgutil
from typing import TYPE_CHECKING

from robot_rise.cli._common import Formatter, add_robot_args, load_robot_arg, print_json
from robot_rise.errors import RobotRiseError

if TYPE_CHECKING:
    from collections.abc import Iterator

    from robot_rise.bench.live_faults import FaultRig, OpenRig
    from robot_rise.posture import Posture

LIVE_FAULTS_EPILOG = """example:
  robot-rise bench live-faults --trials 5 --seed 0
The twin lies down (supine, prone, left, right in turn) and getup runs on the emulated bus; at a
random 20-70 % of the first get-up it executes, one fault strikes a servo among those moving
fastest then, or the IMU: servo-silent (the servo stops answering), overload (it raises its
Overload error: its firmware cuts its torque), blocked (its shaft stops moving), imu-silent (the
OpenCR at ID 200 stops answering), push (a 60 N shove at the torso for 0.2 s, at 70-90 % of the
get-up, once the body is off the floor: the IMU, read in every cycle, sees the torso leave the
proof's tilt). Every goal on the bus is checked against the servo map's limits.
"""

BUS1_FAULTS_EPILOG = """example:
  robot-rise bench bus1-faults --kind overload --kind host-killed
20 servos on Protocol 1.0 at 1 Mbps (16 MX-28 with 1.0 firmware, 4 AX-18A); the executor streams a
wave riding each joint's limits at 100 Hz while one fault strikes at a seeded 20-70 % of it: drop,
corrupt, truncate (2 % of the status packets), missing-mx / missing-ax (a servo stops answering),
overload (the alarm bit: Alarm Shutdown takes its torque), overheating, undervoltage (9 V),
overvoltage (15.5 V), on the emulator in-process on a fake clock; host-terminated (SIGTERM) and
host-killed (SIGKILL) to a child process streaming over a pseudo-terminal. Every goal on the bus is
checked against the servo map's limits; exit 1 unless every fault was stopped or reported with no
goal out of limits, no traceback and the servos left holding, free or torque off.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench",
        help="run a benchmark and print its figures",
        formatter_class=Formatter,
        epilog="example:\n  robot-rise bench validity --scene flat --scene table",
    )
    bsub = p.add_subparsers(dest="bench", metavar="BENCHMARK", required=True)
    v = bsub.add_parser("validity", help="validity checks per second on one core", formatter_class=Formatter,
                        epilog="example:\n  robot-rise bench validity --n 20000")
    v.add_argument("--scene", action="append", help="scene(s) to measure (default: flat and table)")
    v.add_argument("--n", type=int, default=20000, help="queries per scene (default: 20000)")
    v.add_argument("--seed", type=int, default=0)
    v.add_argument("--json", action="store_true", help="print JSON")
    add_robot_args(v, scene=False)
    v.set_defaults(func=run_validity)
    r = bsub.add_parser("rise", help="rise from random lying postures: success, wall time, duration, robustness",
                        formatter_class=Formatter, epilog="example:\n  robot-rise bench rise --n-per-kind 20 --seed 0 --jobs 2")
    r.add_argument("--n-per-kind", type=int, default=20, help="postures per kind: supine, prone, lateral (default: 20)")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--scene", default="flat")
    r.add_argument("--budget", type=float, default=30.0, help="planning budget per candidate [s]")
    r.add_argument("--jobs", type=int, default=1, help="worker processes (default: 1; wall times are per posture either way)")
    r.add_argument("--no-robustness", action="store_true", help="skip the replays under model errors")
    r.add_argument("--variants", type=int, default=0, metavar="N",
                   help="replay each proven output on N random model variants and report the share that stands")
    r.add_argument("--noise-trials", type=int, default=0, metavar="K",
                   help="re-prove each proven output K times with 1e-6 rad noise on its targets; count verdict flips")
    r.add_argument("--rank", choices=("duration", "distance"), default="duration",
                   help="which library motion rise tries first: the quickest expected get-up (default) or the nearest")
    r.add_argument("--composed", action="store_true",
                   help="prove as the guard does: compose each ensemble proof with the library motions' start proofs "
                        "(precomputed per worker) where it applies; each composed output is also checked whole")
    r.add_argument("--json", action="store_true")
    add_robot_args(r, scene=False)
    r.set_defaults(func=run_rise)
    g = bsub.add_parser("margins", help="random model variants and 1e-6 rad target noise: how far from falling",
                        formatter_class=Formatter,
                        epilog="examples:\n  robot-rise bench margins --library --variants 50 --noise-trials 3\n"
                               "  robot-rise bench margins out/rise.json --variants 50")
    g.add_argument("trajectories", nargs="*", metavar="TRAJ", help="trajectory files (default with --library: every library motion)")
    g.add_argument("--library", action="store_true", help="every motion of the robot's library")
    g.add_argument("--variants", type=int, default=50, metavar="N", help="random model variants per trajectory (default: 50)")
    g.add_argument("--noise-trials", type=int, default=3, metavar="K", help="noisy re-proofs per trajectory (default: 3)")
    g.add_argument("--seed", type=int, default=1)
    g.add_argument("--json", action="store_true")
    add_robot_args(g)
    g.set_defaults(func=run_margins)
    from robot_rise.bench.rise import ENVIRONMENT_SCENES

    e = bsub.add_parser("environments", help="rise from postures placed in each scene of paper 000 section 5.2",
                        formatter_class=Formatter,
                        epilog="example:\n  robot-rise bench environments --n 4 --seed 0 --scene slope --scene table")
    e.add_argument("--scene", action="append", choices=ENVIRONMENT_SCENES, help="scene(s) (default: all six)")
    e.add_argument("--n", type=int, default=4, help="postures per scene, kinds cycling supine, prone, left, right (default: 4)")
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--budget", type=float, default=15.0, help="planning budget per candidate [s] (default: 15)")
    e.add_argument("--json", action="store_true", help="print every case as JSON")
    add_robot_args(e, scene=False)
    e.set_defaults(func=run_environments)
    from robot_rise.bench.live_faults import LiveFault

    f = bsub.add_parser("live-faults", help="faults injected while the live get-up rises on the twin: stopped safely, "
                        "in limits, reason given", formatter_class=Formatter, epilog=LIVE_FAULTS_EPILOG)
    f.add_argument("--trials", type=int, default=3, help="trials per fault kind (default: 3)")
    f.add_argument("--seed", type=int, default=0, help="first seed: start posture, IMU noise, fault time (default: 0)")
    f.add_argument("--kind", action="append", choices=[k.value for k in LiveFault],
                   help="fault kind(s) (default: all)")
    f.add_argument("--budget", type=float, default=5.0, help="planning budget per candidate motion [s] (default: 5)")
    f.add_argument("--json", action="store_true", help="print every trial and the summary as JSON")
    add_robot_args(f, scene=False)
    f.set_defaults(func=run_live_faults)
    t = bsub.add_parser("tamper", help="proven trajectories edited ten ways after their proof: each edit refused before the bus",
                        formatter_class=Formatter,
                        epilog="examples:\n  robot-rise bench tamper\n  robot-rise bench tamper out/rises/*.json --rises 0 --robot robots/mine")
    t.add_argument("files", nargs="*", metavar="TRAJ", help="proven trajectory files (default: every motion of the robot's library)")
    t.add_argument("--rises", type=_count, default=20, help="also this many fresh rise outputs from random lying postures (default: 20)")
    t.add_argument("--seed", type=_count, default=0, help="seed of the lying postures (default: 0)")
    t.add_argument("--json", action="store_true", help="print JSON")
    add_robot_args(t, scene=False)
    t.set_defaults(func=run_tamper)
    m = bsub.add_parser("mock-execute", help="proven trajectories executed on --mock and --mock --twin: faults, clamped cycles, band used",
                        formatter_class=Formatter,
                        epilog="examples:\n  robot-rise bench mock-execute --rises 0\n  robot-rise bench mock-execute out/rises/*.json --rises 0")
    m.add_argument("files", nargs="*", metavar="TRAJ", help="proven trajectory files (default: every motion of the robot's library)")
    m.add_argument("--rises", type=_count, default=30, help="also this many fresh rise outputs from random lying postures (default: 30)")
    m.add_argument("--seed", type=_count, default=0, help="seed of the lying postures (default: 0)")
    m.add_argument("--json", action="store_true", help="print JSON")
    add_robot_args(m, scene=False)
    m.set_defaults(func=run_mock_execute)
    from robot_rise.bench.bus1_faults import Bus1Fault

    b1 = bsub.add_parser("bus1-faults", help="Protocol 1.0: the 2.0 fault campaign on a 20-servo 1.0 bus (MX-28 + AX-18A): "
                         "goals in limits, every fault stopped or reported, no traceback",
                         formatter_class=Formatter, epilog=BUS1_FAULTS_EPILOG)
    b1.add_argument("--kind", action="append", choices=[k.value for k in Bus1Fault], help="fault kind(s) (default: all)")
    b1.add_argument("--seed", type=_count, default=0, help="seed of the strike times, struck servos and lost statuses (default: 0)")
    b1.add_argument("--json", action="store_true", help="print every row and the totals as JSON")
    b1.set_defaults(func=run_bus1_faults)
    _register_planners(bsub)
    import robot_rise.cli as cli_pkg

    for info in pkgutil.iter_modules(cli_pkg.__path__):
        if info.name.startswith("cmd_") and info.name != "cmd_bench":
            module = importlib.import_module(f"robot_rise.cli.{info.name}")
            if hasattr(module, "register_bench"):
                module.register_bench(bsub)


def _register_planners(bsub: argparse._SubParsersAction) -> None:
    """The planner benchmarks (issues 5 and 7) and the player's speed."""
    from robot_rise.bench.energy import PLANNER_NAMES
    from robot_rise.bench.energy_problems import PROBLEM_KINDS, PROBLEM_SETS
    from robot_rise.bench.planning import PlanningBenchOptions

    e = bsub.add_parser("energy", help="the energy planner (paper 004) beside RRT-blossom and OMPL RRT-Connect: success, "
                        "times, length, clearance, jerk", formatter_class=Formatter,
                        epilog="examples:\n  robot-rise bench energy --sets crossed --n 5 --budget 20 --out out/bench_energy_crossed.json\n"
                               "  robot-rise bench energy --sets lying60 --budget 10 --lying-cache out/lying60_seed1.json\n"
                               "  robot-rise bench energy --merge out/bench_energy_crossed.json out/bench_energy_lying60.json")
    e.add_argument("--sets", nargs="*", default=["crossed"], choices=PROBLEM_SETS, help="problem sets")
    e.add_argument("--n", type=int, default=5, help="variants per crossed-limb kind")
    e.add_argument("--budget", type=float, default=30.0, help="planning budget per run [s]")
    e.add_argument("--seed", type=int, default=0, help="crossed-limb jitter seed and planner seed base")
    e.add_argument("--lying-seed", type=int, default=1, help="sampling seed of the 60 lying postures")
    e.add_argument("--planners", nargs="*", default=None, help=f"prefixes of {', '.join(PLANNER_NAMES)}")
    e.add_argument("--kinds", nargs="*", default=list(PROBLEM_KINDS), choices=PROBLEM_KINDS, help="crossed-limb kinds")
    e.add_argument("--out", default=None, help="write every run (and the arguments) as JSON here")
    e.add_argument("--merge", nargs="*", default=None, help="print the tables of saved --out files instead of running")
    e.add_argument("--lying-cache", default=None, help="keep the sampled lying60 problems in this JSON file (reused when it matches)")
    e.add_argument("--json", action="store_true", help="print every run as JSON instead of the tables")
    e.set_defaults(func=run_energy)
    d = PlanningBenchOptions()
    g = bsub.add_parser("planning", help="RRT-blossom beside OMPL's RRT-Connect and PRM on the frozen problems: success, "
                        "time, length, clearance", formatter_class=Formatter,
                        epilog="examples:\n  robot-rise bench planning --seed 1 --budget 10 --out out/bench_planning.json\n"
                               "  robot-rise bench planning --sets turnover60 --seed 1 --budget 10 --out out/bench_planning_turnover60.json")
    g.add_argument("--seed", type=int, default=d.seed, help="planner seed of the flat60 problems")
    g.add_argument("--budget", type=float, default=d.budget, help="planning budget per run [s]")
    g.add_argument("--obstacle-seeds", type=int, default=d.obstacle_seeds, help="planner seeds per beam/bed/table problem")
    g.add_argument("--planners", default=d.planners,
                   help=f"comma-separated, of rrt_blossom, rrt_blossom_focused, ompl_rrtconnect, ompl_prm (default {d.planners})")
    g.add_argument("--sets", default=d.sets, help="problem sets to run")
    g.add_argument("--only", default=d.only, help="comma-separated problem names (e.g. left/4) to run alone")
    g.add_argument("--problems", default=d.problems, help="frozen problem file (default configs/bench/planning_problems.json)")
    g.add_argument("--regenerate", action="store_true", help="sample and select the problems again and overwrite --problems")
    g.add_argument("--sample-seed", type=int, default=d.sample_seed, help="lying-posture sampling seed for --regenerate")
    g.add_argument("--turnover-library", default=d.turnover_library,
                   help="with --regenerate: the prone-only library directory of the turnover60 set (commit 8e60c43)")
    g.add_argument("--out", default=d.out, help=f"results JSON, rewritten after every run (default {d.out})")
    g.add_argument("--json", action="store_true", help="print the summary and every run as JSON instead of the tables")
    g.set_defaults(func=run_planning)
    y = bsub.add_parser("player", help="physics steps per second of the player, every library motion",
                        formatter_class=Formatter, epilog="example:\n  robot-rise bench player --repeat 3")
    y.add_argument("--library", default=None, help="motion library directory (default: the shipped op3 library)")
    y.add_argument("--repeat", type=int, default=5, help="plays per motion (medians reported)")
    y.add_argument("--compare", default=None, metavar="DIR", help="also time DIR/sim.py (+ DIR/judge.py), interleaved")
    y.add_argument("--json", action="store_true", help="print the figures per motion as JSON")
    y.set_defaults(func=run_player)


def run_energy(args: argparse.Namespace) -> int:
    import dataclasses
    import time

    from robot_rise.bench.energy import BenchRow, load_rows, run_benchmark, write_results
    from robot_rise.bench.energy_tables import energy_report

    if args.merge:
        merged = load_rows(args.merge)
        if args.json:
            print_json({"rows": [dataclasses.asdict(r) for r in merged]})
        else:
            print(energy_report(merged))
        return 0
    recorded = {k: getattr(args, k) for k in ("sets", "n", "budget", "seed", "lying_seed", "planners", "kinds", "out", "merge",
                                              "lying_cache", "verbose")}
    t0 = time.monotonic()
    done: list[BenchRow] = []

    def save(row: BenchRow) -> None:  # after every run, so that a long run keeps what it measured
        done.append(row)
        if args.out:
            write_results(args.out, done, args=recorded, wall_s=time.monotonic() - t0)

    rows = run_benchmark(sets=tuple(args.sets), n=args.n, budget_s=args.budget, seed=args.seed, lying_seed=args.lying_seed,
                         planners=args.planners, kinds=tuple(args.kinds), progress=save, lying_cache=args.lying_cache)
    if args.out:
        write_results(args.out, rows, args=recorded, wall_s=time.monotonic() - t0)
    if args.json:
        print_json({"rows": [dataclasses.asdict(r) for r in rows], "wall_s": time.monotonic() - t0})
        return 0
    print(energy_report(rows))
    print(f"\nwall {time.monotonic() - t0:.0f} s")
    return 0


def run_planning(args: argparse.Namespace) -> int:
    import dataclasses

    from robot_rise.bench.planning import PlanningBenchOptions, bench_planning, planning_report

    options = PlanningBenchOptions(**{f.name: getattr(args, f.name) for f in dataclasses.fields(PlanningBenchOptions)})
    summary, runs = bench_planning(options)
    if args.json:
        print_json({"summary": summary, "runs": [dataclasses.asdict(r) for r in runs]})
    else:
        print(planning_report(summary, runs))
    return 0


def run_player(args: argparse.Namespace) -> int:
    from robot_rise.bench.player import bench, player_table

    rows = bench(args.library, args.repeat, args.compare)
    if args.json:
        print_json({"motions": rows, "repeat": args.repeat})
        return 0
    print(player_table(rows, repeat=args.repeat, library_dir=args.library, compare=args.compare))
    return 0


def run_validity(args: argparse.Namespace) -> int:
    from robot_rise.bench.rise import bench_validity

    robot = load_robot_arg(args)
    results = [bench_validity(robot, s, n=args.n, seed=args.seed) for s in (args.scene or ["flat", "table"])]
    if args.json:
        print_json([r.__dict__ for r in results])
    else:
        for r in results:
            print(f"validity checks, scene {r.scene}: {r.checks_per_second:,.0f} checks/s on one core ({r.checks} queries in {r.seconds:.2f} s, {100 * r.valid_fraction:.0f}% valid)")
    return 0


def run_rise(args: argparse.Namespace) -> int:
    from robot_rise.bench.rise import bench_rise, summarize_rise
    from robot_rise.cli._common import Progress

    robot = load_robot_arg(args)
    total = 3 * args.n_per_kind
    cases = bench_rise(robot, n_per_kind=args.n_per_kind, seed=args.seed, scene=args.scene, budget_s=args.budget, candidate_rank=args.rank,
                       jobs=args.jobs, robustness=not args.no_robustness, variants=args.variants,
                       noise_trials=args.noise_trials, progress=Progress("rising", total), composed=args.composed)
    summary = summarize_rise(cases)
    if args.json:
        print_json({"summary": summary, "cases": [c.__dict__ for c in cases]})
        return 0
    print("| kind | n | success | wall median / p95 [s] | get-up duration median / p90 [s] | standing from, median [s] "
          "| robot time, medians: approach / library / blend and slowing [s] | peak torque ratio (max) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for kind, row in summary.items():
        split = " / ".join(f"{row[f'{part}_median_s']:.2f}" if f"{part}_median_s" in row else "-"
                           for part in ("approach", "library", "blend_and_slowing"))
        print(f"| {kind} | {row['n']} | {100 * row['success']:.0f}% | {row['wall_median_s']:.1f} / {row['wall_p95_s']:.1f} | "
              f"{row['duration_median_s']:.2f} / {row['duration_p90_s']:.2f} | {row['stood_from_median_s']:.2f} | {split} | "
              f"{row['peak_torque_ratio_max']:.2f} |")
    for kind, row in summary.items():
        if "ensemble_median_s" in row:
            print(f"{kind}: median seconds: plan {row['plan_median_s']:.2f}, filter (nominal) {row['filter_nominal_median_s']:.2f}, "
                  f"ensemble {row['ensemble_median_s']:.2f}")
        if "composed" in row:
            print(f"{kind}: {100 * row['composed']:.0f} % proven composed; the whole check agrees on {row['whole_check_agrees']} of "
                  f"{row['composed_checked']}; CPU per rise median {row['cpu_median_s']:.2f} s, p95 {row['cpu_p95_s']:.2f} s")
        if "variant_share_median" in row:
            print(f"{kind}: random variants standing per trajectory: median {100 * row['variant_share_median']:.0f} %, "
                  f"min {100 * row['variant_share_min']:.0f} %; {100 * row['variant_share_95_or_more']:.0f} % of trajectories "
                  f"stand in >= 95 % of them")
        if "noise_trials" in row:
            print(f"{kind}: {row['noise_flips']} verdict flips in {row['noise_trials']} replays with 1e-6 rad target noise")
    robust = {k: v for k, v in summary.get("all", {}).items() if k.startswith("robust: ")}
    for label, rate in robust.items():
        print(f"{label.removeprefix('robust: ')}: {100 * rate:.0f}% of proven trajectories still stand")
    for c in cases:
        if not c.proven:
            print(f"failed {c.name}: {c.reason[:300]}")
    return 0


def run_margins(args: argparse.Namespace) -> int:
    from robot_rise.bench.margins import margins_of
    from robot_rise.cli._common import Progress, load_trajectory_for
    from robot_rise.library import load_library, robot_library_dir

    robot = load_robot_arg(args)
    named = [(path, load_trajectory_for(robot, path)) for path in args.trajectories]
    if args.library:
        named += [(m.name, m.trajectory) for m in load_library(robot_library_dir(robot)).motions]
    if not named:
        raise RobotRiseError("no trajectory to measure", hint="pass TRAJ files or --library")
    progress = Progress("margins", len(named))
    rows = []
    for k, (name, tr) in enumerate(named):
        m = margins_of(robot, tr, scene=args.scene, variants=args.variants, seed=args.seed, noise_trials=args.noise_trials)
        rows.append({"name": str(name), "proven": m.proven, "variants": m.variants, "standing": m.variants_standing,
                     "share": m.variant_share, "noise_trials": m.noise_trials, "noise_flips": m.noise_flips, "failures": list(m.failures)})
        progress(k + 1)
    if args.json:
        print_json(rows)
        return 0
    print(f"| trajectory | proven | random variants standing (seed {args.seed}) | verdict flips under 1e-6 rad noise |")
    print("| --- | :---: | ---: | ---: |")
    for r in rows:
        print(f"| {r['name']} | {'yes' if r['proven'] else 'no'} | {r['standing']} / {r['variants']} ({100 * r['share']:.0f} %) | "
              f"{r['noise_flips']} / {r['noise_trials']} |")
    return 0


def run_environments(args: argparse.Namespace) -> int:
    from robot_rise.bench.rise import ENVIRONMENT_SCENES, bench_environments, environments_table
    from robot_rise.cli._common import Progress

    robot = load_robot_arg(args)
    scenes = tuple(args.scene or ENVIRONMENT_SCENES)
    if args.n < 1:
        raise RobotRiseError(f"--n {args.n}: at least one posture per scene")
    results = bench_environments(robot, scenes=scenes, n=args.n, seed=args.seed, budget_s=args.budget,
                                 progress=Progress("rising", args.n * len(scenes)))
    if args.json:
        print_json({s: [c.__dict__ for c in cases] for s, cases in results.items()})  # RiseCase: plain fields
    else:
        print(environments_table(results))
    return 0


def run_live_faults(args: argparse.Namespace) -> int:
    from robot_rise.bench.live_faults import (
        FaultTrial,
        LiveFault,
        live_fault_trials,
        live_faults_table,
        summarize_live_faults,
    )
    from robot_rise.cli._common import Progress

    if args.trials < 1:
        raise RobotRiseError(f"--trials {args.trials}: at least 1")
    robot = load_robot_arg(args)
    kinds = [LiveFault(k) for k in dict.fromkeys(args.kind)] if args.kind else list(LiveFault)
    progress = Progress("faults", args.trials * len(kinds))
    done: list[FaultTrial] = []

    def on_trial(t: FaultTrial) -> None:
        done.append(t)
        progress(len(done))

    trials = live_fault_trials(_fault_rig_opener(args), robot, kinds=kinds, trials=args.trials, seed=args.seed,
                               on_trial=on_trial)
    summary = summarize_live_faults(trials)
    if args.json:
        print_json({"robot": robot.name, "seed": args.seed, "trials_per_kind": args.trials, "summary": summary,
                    "trials": [t.to_dict() for t in trials]})
    else:
        print(live_faults_table(summary))
    # a trial where no get-up was executed (none proven) struck nothing: it fails no safety figure
    return 0 if all((t.stopped_safely or not t.mid_rise) and not t.out_of_limit for t in trials) else 1


def _fault_rig_opener(args: argparse.Namespace) -> OpenRig:
    """The live session of ``getup --mock --twin`` as a ``robot_rise.bench.live_faults.OpenRig``."""
    import contextlib

    import drivers.mockbus as mb
    from robot_rise.bench.live_faults import FaultRig
    from robot_rise.cli.cmd_getup import open_live_session

    @contextlib.contextmanager
    def open_rig(start: Posture, seed: int) -> Iterator[FaultRig]:
        live = argparse.Namespace(mock=True, twin=True, port=None, robot=args.robot, scene="flat", baud=None,
                                  seed=seed, budget=args.budget)
        name = None
        try:
            with open_live_session(live, start=start) as s:
                name = s.io.connection.url.removeprefix("dxlsim://")
                bus, twin = mb.attached(name), s.twin
                if bus is None or twin is None:
                    raise RobotRiseError("the live session has no emulated bus with a twin")
                yield FaultRig(s.io, s.planner, s.estimator, bus, s.io.map, s.truth,
                               upright=lambda: bool(twin.state().upright),
                               push=lambda force, seconds: twin.push((force[0], force[1], 0.0), seconds))
        finally:
            if name is not None:
                mb.detach(name)  # the bus holds the twin: let both go

    return open_rig


def run_tamper(args: argparse.Namespace) -> int:
    import dataclasses
    import tempfile
    from pathlib import Path

    from robot_rise.bench.tamper import TAMPERS, tamper_campaign

    robot = load_robot_arg(args)
    with tempfile.TemporaryDirectory(prefix="robot-rise-tamper-") as tmp:
        rows = tamper_campaign(robot, _proven_files(args, robot, Path(tmp)))
    edits = len(rows) * len(TAMPERS)
    refused = sum(len(TAMPERS) - len(r.misses) for r in rows)
    false_refusals = [r for r in rows if not r.untouched_allowed]
    if args.json:
        print_json({"rows": [dataclasses.asdict(r) for r in rows], "edits": edits, "refused": refused, "false_refusals": len(false_refusals)})
    else:
        for r in rows:
            state = "untouched allowed" if r.untouched_allowed else f"UNTOUCHED REFUSED ({r.untouched_reason})"
            misses = f"; ALLOWED: {', '.join(r.misses)}" if r.misses else ""
            print(f"{Path(r.file).name:40s} {state}; {len(TAMPERS) - len(r.misses)}/{len(TAMPERS)} edits refused{misses}")
        print(f"{refused} of {edits} edits refused ({100 * refused / max(edits, 1):.0f} %), {len(false_refusals)} of {len(rows)} untouched files refused")
    return 0 if refused == edits and not false_refusals else 1


def run_bus1_faults(args: argparse.Namespace) -> int:
    from robot_rise.bench.bus1_faults import Bus1Fault, bus1_fault_campaign, bus1_faults_table

    kinds = [Bus1Fault(k) for k in dict.fromkeys(args.kind)] if args.kind else list(Bus1Fault)
    rows = bus1_fault_campaign(kinds, seed=args.seed)
    if args.json:
        print_json({"seed": args.seed, "rows": [r.to_dict() for r in rows], "ok": sum(r.ok for r in rows), "total": len(rows),
                    "goals_written": sum(r.goals_written for r in rows),
                    "goals_out_of_limits": sum(r.goals_out_of_limits for r in rows),
                    "tracebacks": sum(r.traceback_seen for r in rows)})
    else:
        print(bus1_faults_table(rows))
    return 0 if all(r.ok for r in rows) else 1


def _count(text: str) -> int:
    """A count flag: a whole number >= 0."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, not {n}")
    return n


def run_mock_execute(args: argparse.Namespace) -> int:
    import dataclasses
    import tempfile
    from pathlib import Path

    from robot_rise.bench.mock_execute import execute_on_mock

    robot = load_robot_arg(args)
    with tempfile.TemporaryDirectory(prefix="robot-rise-mock-execute-") as tmp:
        files = _proven_files(args, robot, Path(tmp))
        def say(run) -> None:  # type: ignore[no-untyped-def]
            if not args.json:
                state = "clean" if run.clean else f"exit {run.exit_code}; {'; '.join(run.faults) or run.said or 'no fault'}"
                print(f"{Path(run.file).name:40s} {'twin' if run.twin else 'mock':4s} {state}; clamped cycles {run.clamped_cycles}; "
                      f"band used {run.band_ratio}", flush=True)
        runs = [r for twin in (False, True) for r in execute_on_mock(files, robot, twin=twin, progress=say)]
    clean = sum(r.clean for r in runs)
    worst = max((r.band_ratio for r in runs if r.band_ratio is not None), default=None)
    if args.json:
        print_json({"runs": [dataclasses.asdict(r) for r in runs], "clean": clean, "total": len(runs), "worst_band_ratio": worst})
    else:
        print(f"{clean} of {len(runs)} runs clean (no fault, no clamped cycle) over {len(files)} files; "
              f"most of the band used: {worst}")
    return 0 if clean == len(runs) else 1


def _proven_files(args: argparse.Namespace, robot, directory):  # type: ignore[no-untyped-def]
    """The files a campaign runs: ``args.files`` (default: the robot's library) and ``args.rises``
    fresh rise outputs written to ``directory``."""
    from pathlib import Path

    from robot_rise.bench.mock_execute import rise_outputs
    from robot_rise.library import load_library, robot_library_dir

    files = [Path(f) for f in args.files] or [m_dir / str(m) for m_dir, m in _library_files(load_library(robot_library_dir(robot)))]
    if args.rises:
        print(f"rising from {args.rises} random lying postures ...", file=sys.stderr, flush=True)
        files += rise_outputs(robot, args.rises, directory, seed=args.seed)
    return files


def _library_files(library):  # type: ignore[no-untyped-def]
    """(directory, trajectory file name) of every motion of a library (index order)."""
    import json

    index = json.loads((library.directory / "index.json").read_text())
    return [(library.directory, row["trajectory"]) for row in index["motions"]]
