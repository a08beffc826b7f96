"""Benchmarks of the core (figures printed by ``robot-rise bench``, recorded in BENCHMARKS.md).

Timings are measured here, never asserted in tests: a noisy CI machine must not fail a build.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import numpy as np

from robot_rise.proof import COMPOSED_KEY, Proof
from robot_rise.model import Robot
from robot_rise.rise import DEFAULT_CANDIDATE_RANK
from robot_rise.sampling import sample_lying
from robot_rise.sim.variants import ModelVariant
from robot_rise.validity import ValidityChecker

__all__ = ["ValidityBenchmark", "bench_validity", "bench_environments", "environment_postures", "environments_table", "ENVIRONMENT_SCENES"]


@dataclass(frozen=True)
class ValidityBenchmark:
    """Validity checks per second on one core, and the share of valid queries."""

    scene: str
    checks: int
    seconds: float
    checks_per_second: float
    valid_fraction: float


def bench_validity(
    robot: Robot, scene: str | os.PathLike[str] = "flat", *, n: int = 20000, seed: int = 0, perturbation_rad: float = 0.3
) -> ValidityBenchmark:
    """Time ``ValidityChecker.is_valid_qpos`` on planner-like queries.

    Queries are settled lying postures (4 of each kind) with every joint perturbed by up to
    ``perturbation_rad`` and clipped to limits, as an RRT explores around lying postures.
    """
    base = sample_lying(robot, "any", 8, seed)
    checker = ValidityChecker(robot, scene)
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        p = base.postures[i % len(base.postures)]
        q = checker.qpos_of(p)
        j = checker.index.qpos_joints
        q[j] = np.clip(q[j] + rng.uniform(-perturbation_rad, perturbation_rad, len(j)), robot.joint_lower, robot.joint_upper)
        rows.append(q)
    queries = np.array(rows)
    checker.is_valid_qpos(queries[0])  # warm up
    t0 = time.perf_counter()
    valid = 0
    for q in queries:
        valid += checker.is_valid_qpos(q)
    dt = time.perf_counter() - t0
    return ValidityBenchmark(str(scene), n, dt, n / dt, valid / n)


# --- rise: the product's main job over random lying postures (issue 6) ---------------------------

BENCH_MODEL_VARIANTS: tuple[ModelVariant, ...] = (
    ModelVariant("mass -10%, friction 0.5", mass_scale=0.9, friction=0.5),
    ModelVariant("mass +10%, friction 1.2", mass_scale=1.1, friction=1.2),
    ModelVariant("servo torque -15%", supply_scale=0.85),
    ModelVariant("one control period of latency", latency_s=0.01),
)
"""Replays of each proven trajectory under model errors (issue 6), each combining two of the
ensemble's errors (``robot_rise.sim.variants``) that ``rise`` proves one at a time. Friction is
absolute (the scene's ground has 0.9). Servo torque -15 % is a 15 % lower
supply voltage than the robot's (stall torque and no-load speed scale with it: exactly 15 % off
for a 12 V robot, 10.2 V lying below the datasheets' rows; between rows, as they interpolate). Latency: targets arrive one
100 Hz control period late. Judged as ``filter.stands_under`` judges (the proof's criteria)."""


@dataclass(frozen=True)
class RiseCase:
    """One posture of the rise benchmark and what became of it."""

    name: str
    kind: str
    proven: bool
    wall_s: float
    duration_s: float
    peak_torque_ratio: float
    motion: str
    reason: str
    robust: dict[str, bool]
    variants: int = 0  # random model variants replayed (bench.margins)
    variants_standing: int = 0
    noise_trials: int = 0  # replays with 1e-6 rad target noise
    noise_flips: int = 0  # ... whose verdict differed
    seconds: dict[str, float] | None = None  # where the wall time went: plan, filter (nominal), ensemble
    stood_from_s: float = float("nan")  # when the final standing stretch began (the judge) [s]
    # where the robot's time went [s]: the planned approach, the library motion from the connecting
    # frame on, and the rest: the blend at the join and what the filter added by slowing
    robot_time: dict[str, float] | None = None
    cpu_s: float = float("nan")  # CPU seconds of the rise, all threads (one core's worth of work) [s]
    composed: bool = False  # its ensemble proof was composed (rise composed=True; robot_rise.proof.composed)
    whole_check: bool | None = None  # a composed output replayed whole on every variant: proven too
    flip_reasons: tuple[str, ...] = ()  # why each noise flip's failing replay failed (bench.margins)


_CONTEXTS: dict[tuple[str, str], object] = {}  # per-process memo of RiseContext (benchmark workers)


def _rise_case(args: tuple) -> RiseCase:
    import time as _time

    from robot_rise.proof import stands_under
    from robot_rise.model import load_robot
    from robot_rise.rise import RiseOptions, rise

    robot_dir, name, kind, posture, scene, budget_s, seed, robustness, variants, noise_trials, rank, *more = args
    composed = bool(more and more[0])
    key = (robot_dir, scene)
    if key not in _CONTEXTS:  # one per worker process: the robot, checker, library and tree
        from robot_rise.rise import RiseContext

        _CONTEXTS[key] = RiseContext.build(load_robot(robot_dir), scene)
    context = _CONTEXTS[key]
    robot = context.robot
    if composed:
        context.warm_start_proofs()  # per robot, before the clock starts (the guard does it at start-up)
    t0 = _time.perf_counter()
    c0 = _time.process_time()
    try:
        result = rise(robot, posture, RiseOptions(scene=scene, seed=seed, budget_s=budget_s, candidate_rank=rank, composed=composed), context=context)
    except Exception as e:  # a benchmark reports failures, it does not stop on them
        return RiseCase(name, kind, False, _time.perf_counter() - t0, float("nan"), float("nan"), "", f"error: {e}", {})
    wall = _time.perf_counter() - t0
    cpu = _time.process_time() - c0
    rep = result.trajectory.report if result.trajectory is not None else {}
    proof = Proof.from_dict(rep) if result.trajectory is not None else None
    robust: dict[str, bool] = {}
    if result.proven and robustness and result.trajectory is not None:
        for variant in BENCH_MODEL_VARIANTS:
            robust[variant.label] = stands_under(robot, result.trajectory, variant, scene=scene)
    was_composed = result.trajectory is not None and COMPOSED_KEY in result.trajectory.report
    whole = None
    if was_composed and result.proven:
        from robot_rise.proof import check

        whole = check(robot, result.trajectory).proven  # the uncomposed proof of the same output
    margins = None
    if result.proven and result.trajectory is not None and (variants or noise_trials):
        from robot_rise.bench.margins import margins_of

        margins = margins_of(robot, result.trajectory, scene=scene, variants=variants, seed=seed, noise_trials=noise_trials)
    return RiseCase(
        name, kind, result.proven, wall, proof.duration_s if proof else float("nan"), proof.peak_torque_ratio if proof else float("nan"),
        str(rep.get("motion", "")), result.reason, robust,
        margins.variants if margins else 0, margins.variants_standing if margins else 0,
        margins.noise_trials if margins else 0, margins.noise_flips if margins else 0,
        _seconds(result, rep),
        proof.stood_from_s if proof and proof.stood_from_s is not None else float("nan"),
        _robot_time(context.library, rep, proof.duration_s) if proof and result.proven else None,
        cpu, was_composed, whole, margins.flip_reasons if margins else (),
    )


def _robot_time(library, report, duration_s: float) -> dict[str, float] | None:
    """Approach, library part, and join blend plus filter slowing of a proven rise [s] (None if not a library join,
    e.g. a recovery after a failed first attempt)."""
    if "recovery" in report or "motion" not in report or "connecting_frame" not in report:
        return None
    tr = library.get(str(report["motion"])).trajectory
    # an overlapped join starts the motion before the approach ends: the approach is the time before it
    approach = float(report.get("plan_duration_s", 0.0)) - float(report.get("join_overlap_s", 0.0))
    rest = float(tr.duration_s - tr.t[int(report["connecting_frame"])])
    return {"approach": approach, "library": rest, "blend_and_slowing": max(0.0, duration_s - approach - rest)}


def _seconds(result, report) -> dict[str, float]:
    """Plan, nominal filter and ensemble seconds summed over the attempts (the ensemble's from the
    filter's report, of the returned trajectory's last filter run only)."""
    plan = sum(a.seconds.get("plan", 0.0) for a in result.attempts)
    filt = sum(a.seconds.get("filter", 0.0) for a in result.attempts)
    ens = float(report.get("ensemble_seconds", 0.0))
    return {"plan": plan, "filter_nominal": max(0.0, filt - ens), "ensemble": ens}


def bench_rise(
    robot: Robot,
    *,
    n_per_kind: int = 20,
    seed: int = 0,
    scene: str = "flat",
    budget_s: float = 30.0,
    jobs: int = 1,
    robustness: bool = True,
    variants: int = 0,
    noise_trials: int = 0,
    progress=None,
    candidate_rank: str = DEFAULT_CANDIDATE_RANK,
    composed: bool = False,
) -> list[RiseCase]:
    """Rise from ``n_per_kind`` supine, prone and lateral (half left, half right) postures.

    ``composed``: as the guard proves (``rise(composed=True)``, start proofs precomputed per
    worker before the clock starts); each composed output is also checked whole.

    Postures come from ``sample_lying`` with seeds ``seed`` (supine, prone) and ``seed``
    (left, right), as the paper's protocol (000 section 5): 20 supine, 20 prone, 20 lateral.
    """
    from concurrent.futures import ProcessPoolExecutor

    half = n_per_kind // 2
    groups = [("supine", n_per_kind), ("prone", n_per_kind), ("left", half), ("right", n_per_kind - half)]
    tasks = []
    for kind, n in groups:
        if n == 0:
            continue
        sample = sample_lying(robot, kind, n, seed, scene=scene)  # type: ignore[arg-type]
        for i, p in enumerate(sample.postures):
            tasks.append((str(robot.directory), f"{kind}_{seed}_{i:03d}", kind, p, scene, budget_s, seed, robustness, variants, noise_trials,
                          candidate_rank, composed))
    results: list[RiseCase] = []
    if jobs <= 1:
        for k, task in enumerate(tasks):
            results.append(_rise_case(task))
            if progress:
                progress(k + 1, len(tasks))
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for k, case in enumerate(pool.map(_rise_case, tasks)):
                results.append(case)
                if progress:
                    progress(k + 1, len(tasks))
    return results


def summarize_rise(cases: list[RiseCase]) -> dict[str, dict[str, float]]:
    """Per lying kind (left and right pooled as lateral) and overall: success, wall-time and duration stats."""
    out: dict[str, dict[str, float]] = {}
    buckets = {"supine": [], "prone": [], "lateral": [], "all": []}  # type: dict[str, list[RiseCase]]
    for c in cases:
        buckets["lateral" if c.kind in ("left", "right") else c.kind].append(c)
        buckets["all"].append(c)
    for key, cs in buckets.items():
        if not cs:
            continue
        wall = np.array([c.wall_s for c in cs])
        ok = [c for c in cs if c.proven]
        dur = np.array([c.duration_s for c in ok]) if ok else np.array([np.nan])
        peak = np.array([c.peak_torque_ratio for c in ok]) if ok else np.array([np.nan])
        cpu = np.array([c.cpu_s for c in cs])
        row = {
            "n": len(cs),
            "success": len(ok) / len(cs),
            "wall_median_s": float(np.median(wall)),
            "wall_p95_s": float(np.percentile(wall, 95)),
            "cpu_median_s": float(np.nanmedian(cpu)) if np.any(np.isfinite(cpu)) else float("nan"),
            "cpu_p95_s": float(np.nanpercentile(cpu, 95)) if np.any(np.isfinite(cpu)) else float("nan"),
            "duration_median_s": float(np.median(dur)),
            "duration_p90_s": float(np.percentile(dur, 90)),
            "stood_from_median_s": float(np.nanmedian([c.stood_from_s for c in ok])) if ok else float("nan"),
            "peak_torque_ratio_max": float(np.max(peak)),
        }
        for label in (v.label for v in BENCH_MODEL_VARIANTS):
            tested = [c for c in ok if label in c.robust]
            if tested:
                row[f"robust: {label}"] = sum(c.robust[label] for c in tested) / len(tested)
        timed = [c.seconds for c in cs if c.seconds]
        for stage in ("plan", "filter_nominal", "ensemble"):
            if timed:
                row[f"{stage}_median_s"] = float(np.median([t.get(stage, 0.0) for t in timed]))
        split = [c.robot_time for c in ok if c.robot_time]
        for part in ("approach", "library", "blend_and_slowing"):
            if split:
                row[f"{part}_median_s"] = float(np.median([t[part] for t in split]))
        measured = [c for c in ok if c.variants]
        if measured:
            shares = np.array([c.variants_standing / c.variants for c in measured])
            row["variant_share_median"] = float(np.median(shares))
            row["variant_share_min"] = float(shares.min())
            row["variant_share_95_or_more"] = float(np.mean(shares >= 0.95))
        composed = [c for c in ok if c.composed]
        if any(c.whole_check is not None for c in cs):
            row["composed"] = len(composed) / len(cs)
            row["whole_check_agrees"] = sum(bool(c.whole_check) for c in composed)
            row["composed_checked"] = len(composed)
        noisy = [c for c in ok if c.noise_trials]
        if noisy:
            row["noise_flips"] = int(sum(c.noise_flips for c in noisy))
            row["noise_trials"] = int(sum(c.noise_trials for c in noisy))
        out[key] = row
    return out


# --- environments of paper 000 section 5.2 (issue 6) ---------------------------------------------

ENVIRONMENT_SCENES: tuple[str, ...] = ("beam", "low_bed", "table", "icy", "soft", "slope")
"""The scenes of paper 000 section 5.2 (configs/scenes/)."""

TABLE_HALF_EXTENTS_M = (0.30, 0.25)  # the table top of configs/scenes/table.xml, about the origin [m]
TABLE_EDGE_OUT_M = 0.15  # half-out postures have their root this far beyond the table's edge [m]


def _yaw_quat(yaw_rad: float) -> np.ndarray:
    return np.array([np.cos(yaw_rad / 2), 0.0, 0.0, np.sin(yaw_rad / 2)])


def _head_direction(quat_wxyz: np.ndarray) -> np.ndarray:
    """Unit (x, y) the head points to when lying: the torso's up axis on the ground."""
    from robot_rise.posture import quat_multiply

    v = quat_multiply(quat_multiply(quat_wxyz, np.array([0.0, 0.0, 0.0, 1.0])), quat_wxyz * np.array([1, -1, -1, -1]))[1:3]
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _table_postures(robot: Robot, n: int, seed: int) -> list[tuple[str, object]]:
    """Half out from under the table (paper 000 Fig. 11), then fully under it.

    ``n`` postures lie half out past one of the four edges in turn, root TABLE_EDGE_OUT_M beyond
    it, turned so that the motion that follows leads out: supine with the head out (the supine
    get-ups roll backwards over the head), prone and lateral with the feet out (they end pushing
    back onto the feet). Then ``max(1, n // 2)`` lie fully under it (nothing can stand there).
    """
    from robot_rise.posture import quat_multiply

    checker = ValidityChecker(robot, "table")
    flat = sample_lying(robot, "any", 6 * n, seed)
    hx, hy = TABLE_HALF_EXTENTS_M
    edges = [(np.array([1.0, 0.0]), hx), (np.array([0.0, 1.0]), hy), (np.array([-1.0, 0.0]), hx), (np.array([0.0, -1.0]), hy)]
    half: list[tuple[str, object]] = []
    under: list[tuple[str, object]] = []
    n_under = max(1, n // 2)
    for kind, p in zip(flat.kinds, flat.postures):
        if len(half) < n and kind == ("supine", "prone", "left", "right")[len(half) % 4]:
            u, h = edges[len(half) % 4]
            want = u if kind == "supine" else -u  # head out, or feet out
            have = _head_direction(p.root_quat_wxyz)
            turn = float(np.arctan2(want[1], want[0]) - np.arctan2(have[1], have[0]))
            quat = quat_multiply(_yaw_quat(turn), p.root_quat_wxyz)
            xy = u * (h + TABLE_EDGE_OUT_M)
            moved = p.with_root(np.array([xy[0], xy[1], p.root_pos[2]]), quat / np.linalg.norm(quat))
            if checker.is_valid(moved):
                half.append((kind, moved))
                continue
        if len(under) < n_under:
            moved = p.with_root(np.array([0.0, 0.0, p.root_pos[2]]))
            if checker.is_valid(moved):
                under.append((kind, moved))
        if len(half) == n and len(under) == n_under:
            break
    return half + under


def environment_postures(robot: Robot, scene: str, n: int, seed: int) -> list[tuple[str, object]]:
    """Lying postures placed for ``scene``: (kind, posture) pairs, kinds cycling supine, prone, left, right.

    Scenes are sampled and settled at the origin, where each has its feature: the beam under the
    face of a robot lying with its head toward +x, the robot on the low bed's edge (legs or head
    over it depending on the yaw), ice, soft ground, the slope. The table is the exception
    (:func:`_table_postures`: ``n`` half out from under it and ``n // 2`` fully under it), since
    settling at its origin would drop many postures onto its top.
    """
    if scene == "table":
        return _table_postures(robot, n, seed)
    sample = sample_lying(robot, "any", n, seed, scene=scene)
    return list(zip(sample.kinds, sample.postures))


def bench_environments(
    robot: Robot,
    *,
    scenes: tuple[str, ...] = ENVIRONMENT_SCENES,
    n: int = 4,
    seed: int = 0,
    budget_s: float = 15.0,
    progress=None,
) -> dict[str, list[RiseCase]]:
    """Rise from ``n`` postures placed in each scene (:func:`environment_postures`).

    Returns:
        per scene, one :class:`RiseCase` per posture (robustness replays skipped: ``rise`` itself
        checks its own model error).
    """
    out: dict[str, list[RiseCase]] = {}
    total = n * len(scenes)
    done = 0
    for scene in scenes:
        cases = []
        for i, (kind, p) in enumerate(environment_postures(robot, scene, n, seed)):
            cases.append(_rise_case((str(robot.directory), f"{scene}_{kind}_{seed}_{i:03d}", kind, p, scene, budget_s, seed, False, 0, 0, DEFAULT_CANDIDATE_RANK)))
            done += 1
            if progress:
                progress(done, total)
        out[scene] = cases
    return out


def environments_table(results: dict[str, list[RiseCase]]) -> str:
    """The BENCHMARKS.md table of :func:`bench_environments` (markdown), then one line per failure."""
    lines = ["| scene | postures | risen | median wall time [s] | reasons of failures |", "| --- | ---: | ---: | ---: | --- |"]
    for scene, cases in results.items():
        ok = sum(c.proven for c in cases)
        wall = float(np.median([c.wall_s for c in cases])) if cases else float("nan")
        fails = "; ".join(f"{c.kind}: {c.reason[:120]}" for c in cases if not c.proven) or "-"
        lines.append(f"| {scene} | {len(cases)} | {ok} | {wall:.1f} | {fails} |")
    lines.append("")
    lines += [f"failed {c.name}: {c.reason}" for cases in results.values() for c in cases if not c.proven]
    return "\n".join(lines)
