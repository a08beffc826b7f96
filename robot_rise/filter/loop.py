"""The filter loop: reshape servo targets until MuJoCo proves them, or say why not.

Paper 000 section 4.3 tracks the smoothed plan in a physics engine and connects it to the
database motion at the most similar frame with blending. A robot has no root actuation and its
strength is its servos', so here the "tracking controller" is the servo model itself (the
targets ARE what the servos receive) and the filter reshapes the targets, never the physics:

1. join the planned path to the library motion from the connecting frame on (the caller's:
   ``rise`` cross-fades the motion's start into the approach's end, ``join_overlap_s``, then
   steps after ``quick_blend_s``, then pauses ``blend_s``; 000 section 4.3);
2. play it through the servo model (robot_rise.sim.player) from the start posture;
3. find violations: torque beyond (1 - margin - headroom) of the torque-speed envelope (the
   headroom keeps ``check``'s verdict, at 1 - margin, under fresh target noise; dissertation 003
   eq. 2.2 strength limits; for us the DC-motor envelope), ZMP outside the support polygon while
   on the feet (003 eq. 2.11-2.14), the motion diverging from the plan (tracking error beyond
   the servo's saturation for longer than ``divergence_hold_s``: a roll that does not happen, a
   limb blocked), and finally the standing judge;
4. reshape: slow the offending windows down (time scaling, 003 eq. 2.9-2.10's comfort control
   does this by lowering speed where torque exceeds the limit); when the judge fails with no
   local violation, slow the motion after the join; on sloped ground (paper 000 section 5.2's
   10 deg slope) the library's flat-ground stance is first turned to the slope: from the moment
   the robot is on its feet the ankles take up the ground's tilt and the legs' lengths its
   difference across the feet, in the heading the robot really stands in (``slope.py``), so the
   body above them stays vertical; a body of other proportions than the library's (paper 000
   section 5.3, retargeting), propped on its arms and feet at another lean than the library
   motion, gets its shoulders' pitch offset until its torso leans as the library's did
   (``lean.py``), so it comes onto its feet with its centre of mass over them;
5. iterate until everything passes or ``max_iterations`` is reached, then say why not;
   a proven result's slowing (whole padded windows x``slow_factor``: a sample at 0.905 of the
   envelope costs ~0.2 s) is trimmed back by bisection over ``trim_levels`` nominal replays
   (``_trim``), and the shortest proven so takes step 6 in its place; the untrimmed one goes on
   where the trimmed one fails them, and where the untrimmed one itself fails the ensemble (its
   variants replayed first: a second timing tried against the same fixed variants is a second
   chance to pass them by luck; one more ensemble replay per kept trim);
6. once proven on the nominal model, replay it with 1e-6 rad of target noise (``noise.py``) and
   slow where a noisy replay breaks, then on every model variant (``ensemble.py``) and slow where
   a variant falls, each a few rounds.

The output trajectory holds the commanded targets (not the plan) and a report proving them: the
``Proof``'s entries, then the filter's own (``filter_iterations``, ``filter_history``, ``trim``, and
``slope_stance`` / ``lean_adapted`` when it turned the stance or adapted the lean).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robot_rise.filter.command_limits import COMMAND_LIMITS_KEY, CommandLimits, command_limits_for, conform
from robot_rise.filter.config import FilterConfig
from robot_rise.proof.ensemble import COMBINED_VARIANTS_KEY, EnsembleReplayer, EnsembleResult, with_ensemble
from robot_rise.filter.join import time_scale
from robot_rise.proof.prediction import PREDICTED_KEY, predicted_positions
from robot_rise.filter.lean import LEAN_ITERATIONS, adapt_lean, arm_levers
from robot_rise.proof.noise import NOISE_CHECK_KEY, NoiseCheck, noise_check, with_noise
from robot_rise.proof.verdict import Proof, prove_with_violations
from robot_rise.filter.slope import SLOPE_MIN_RAD, ground_tilt_vector, turn_stance_to_slope
from robot_rise.proof.violations import Violation, find_violations, saturation_rad
from robot_rise.model import Robot
from robot_rise.posture import Posture
from robot_rise.sim.player import Player, Recording
from robot_rise.sim.standing import StandVerdict
from robot_rise.trajectory import Trajectory

__all__ = ["FilterIteration", "FilterResult", "dynamics_filter"]

log = logging.getLogger(__name__)

MIN_TRIM_S = 0.01  # a trim that saves less is not kept (its replays were spent on conforming's own stretch) [s]
TRIM_KEY = "trim"  # the report's list of what each trim cut (``_trim``)


@dataclass(frozen=True)
class FilterIteration:
    """What one iteration saw."""

    iteration: int
    duration_s: float
    peak_envelope_ratio: float
    standing: bool
    violations: tuple[str, ...]


@dataclass(frozen=True)
class FilterResult:
    """Outcome of the filter: the commanded trajectory (with its proof report) and the evidence.

    Attributes:
        proven: the final trajectory is proven (``proof.proven``).
        trajectory: the final commanded targets; its report holds ``report``.
        recording: the final trajectory's replay.
        verdict: the judge's verdict on it.
        proof: its proof.
        iterations: what each iteration saw.
        reason: why not proven (empty when proven).
        report: the proof's entries and the filter's (iterations, history, slope stance, lean).
    """

    proven: bool
    trajectory: Trajectory
    recording: Recording
    verdict: StandVerdict
    proof: Proof
    iterations: tuple[FilterIteration, ...]
    reason: str = ""
    report: dict[str, Any] = field(default_factory=dict)


def dynamics_filter(
    robot: Robot,
    commanded: Trajectory,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    config: FilterConfig = FilterConfig(),
    start: Posture | None = None,
    protect_until_s: float = 0.0,
    progress: Callable[[int, int], None] | None = None,
    ensemble: EnsembleReplayer | None = None,
    join_row: int | None = None,
    command_limits: CommandLimits | None = None,
    stop_at_join: bool = False,
) -> FilterResult:
    """Reshape ``commanded`` until it stands the robot up within the servo limits on the nominal
    model and on every model variant, or say why not.

    Args:
        robot: the robot.
        commanded: first guess of the servo targets (e.g. join_with_blend(plan, motion, frame)).
        scene: scene the motion is proven in.
        config: filter tuning (``config.proof.ensemble`` switches the ensemble proof).
        start: the posture the robot really lies in (default: commanded.start).
        protect_until_s: never stretch before this time (e.g. to keep a key posture's timing).
        join_row: the first row of the library motion (``join_with_blend``, ``join_with_overlap``); with
            ``config.max_stretch`` the motion from there on is slowed to at most that multiple of
            its commanded duration (the approach before it as far as ``max_duration_s``).
        progress: called as progress(iteration, max_iterations).
        ensemble: the variants' players to reuse (default: built here when ``config.proof.ensemble``).
        command_limits: what the executor will enforce (default: ``command_limits_for(robot)``):
            the targets are kept within them, so executing the proven trajectory clamps nothing.
        stop_at_join: a nominal replay already over the torque margin when it reaches
            ``join_row`` stops there (its approach's violations reshape the next iteration). For
            a library part that may not be slowed (``motion_max_stretch`` ~1: the composed proof),
            where playing it on cannot make that replay proven.

    Returns:
        FilterResult whose trajectory holds the final commanded targets and the proof report
        (the best proven iteration's, else the last one's).
    """
    start = start or commanded.start
    # proven with headroom under the bound `check` judges: a fresh noise draw keeps the verdict
    config = config.proving()
    player = Player(robot, scene)
    if config.proof.ensemble and ensemble is None:
        ensemble = EnsembleReplayer(robot, scene)
    limits = command_limits or command_limits_for(robot)
    noise_rounds = 0

    trims: list[dict[str, Any]] = []  # what each trim cut (``_trim``)
    untrimmed: tuple[FilterResult, bool] | None = None  # the nominal result a trimmed one was cut from (not yet noise checked), its stop_at_join

    def noised(result: FilterResult, stop: bool, rounds: bool = True) -> FilterResult:
        """``result``'s noise check (``noise.py``), slowing where a noisy replay breaks (``rounds``)."""
        nonlocal noise_rounds
        while result.proven and config.proof.noise_replays > 0:
            checked, recs = noise_check(result.trajectory, result.recording, player, start=start, config=config.proof)
            result = _with_noise_check(result, checked)
            if checked.holds or not rounds or noise_rounds >= config.noise_rounds:
                break
            noise_rounds += 1
            saturation = saturation_rad(robot)
            found = [v for r, c in zip(recs, checked.replays) if not c.holds for v in find_violations(r, config.proof, saturation_rad=saturation)]
            slowed = _slowed(result.trajectory, found, config, protect_until_s)
            if slowed.duration_s > config.max_duration_s or _overstretched(slowed, commanded, join_row, _stretch_cap(config)):
                break
            log.info("noise round %d: %s; slowing", noise_rounds, "; ".join(checked.failures()[:2]))
            again = _nominal_filter(robot, dataclasses.replace(slowed, report=commanded.report), player, scene=scene, config=config,
                                    start=start, protect_until_s=protect_until_s, progress=progress, limits=limits, join_row=join_row,
                                    stop_at_join=stop)
            if not again.proven:
                break
            result = again
        return result

    def nominal(guess: Trajectory, stop: bool) -> FilterResult:
        """The nominal filter, its slowing trimmed (``_trim``), then its noise check, slowing where a noisy replay breaks.
        A trimmed result a noisy replay breaks gives way to the untrimmed one (``untrimmed`` keeps it
        for the ensemble: the trim gives way to it too where a variant falls with either timing;
        the untrimmed one then goes on to the ensemble's slowing rounds)."""
        nonlocal untrimmed
        result = _nominal_filter(robot, guess, player, scene=scene, config=config, start=start, protect_until_s=protect_until_s,
                                 progress=progress, limits=limits, join_row=join_row, stop_at_join=stop)
        untrimmed = None
        if result.proven and config.trim_levels > 0:
            trimmed = _trim(robot, result, guess, player, scene=scene, config=config, start=start, protect_until_s=protect_until_s,
                            limits=limits, join_row=join_row, stop_at_join=stop)
            if trimmed is not None:
                trims.append(trimmed[1])
                checked = noised(trimmed[0], stop, rounds=False)
                if checked.proven:
                    untrimmed = (result, stop)
                    return checked
                trims[-1]["kept"] = False
                log.info("trimmed: a noisy replay breaks it; untrimmed")
        return noised(result, stop)

    def replay(tr: Trajectory) -> tuple[EnsembleResult, list[Recording]]:
        nonlocal ensemble_s
        t0 = time.perf_counter()
        assert ensemble is not None
        out = ensemble.replay(tr, start=start, config=config.proof)
        ensemble_s += time.perf_counter() - t0
        return out

    def fall_back(base: FilterResult, stop: bool, replayed: tuple[EnsembleResult, list[Recording]]
                  ) -> tuple[FilterResult, tuple[EnsembleResult, list[Recording]] | None]:
        """The untrimmed result, noise checked, and its ensemble replay where the check kept its timing."""
        checked = noised(base, stop)
        return checked, (replayed if np.array_equal(checked.trajectory.t, base.trajectory.t) else None)

    result = nominal(commanded, stop_at_join)
    rounds = 0
    recs: list[Recording] = []
    ensemble_s = 0.0
    known: tuple[EnsembleResult, list[Recording]] | None = None  # ``result``'s ensemble replay, where already done
    pending: tuple[FilterResult, bool, tuple[EnsembleResult, list[Recording]]] | None = None  # a trim's untrimmed result that stood
    while ensemble is not None and result.proven:
        if untrimmed is not None:
            # a trim is kept only where the timing it was cut from stands on the same variants:
            # else the trimmed one passing them is luck (OP3 prone_1_098: the untrimmed failed 4
            # of 19, the trimmed passed 19 and stood in 42 of 50 random variants)
            (base, stop), untrimmed = untrimmed, None
            base_replay = replay(base.trajectory)
            fell = len(base_replay[0].failures())
            trims[-1]["untrimmed_ensemble_standing"] = len(base_replay[0].verdicts) - fell
            if fell:
                log.info("trimmed: %d variants fall with its untrimmed timing; untrimmed", fell)
                trims[-1]["kept"] = False
                (result, known), recs = fall_back(base, stop, base_replay), []
                continue
            pending = (base, stop, base_replay)
        replayed, recs = known if known is not None else replay(result.trajectory)
        known = None
        failures = replayed.failures()
        proof = with_ensemble(result.proof, replayed)
        report = {**result.report, **proof.to_dict()}
        final = dataclasses.replace(result.trajectory, report={**result.trajectory.report, **proof.to_dict()})
        reason = "" if not failures else "; ".join(failures[:3]) + f" ({len(failures)} of {len(recs)} model variants fall)"
        result = dataclasses.replace(result, proven=proof.proven, trajectory=final, proof=proof, reason=reason, report=report)
        log.info("ensemble: %d of %d variants stand", proof.ensemble_standing, len(recs))
        if failures and pending is not None:  # the trimmed timing is a fluke of the nominal model: the untrimmed one, which stood
            log.info("trimmed: %d variants fall; untrimmed", len(failures))
            trims[-1]["kept"] = False
            (result, known), recs, pending = fall_back(*pending), [], None
            continue
        pending = None
        if not failures or rounds >= config.ensemble_rounds:
            break
        rounds += 1
        # the motion is a fluke of the nominal model: slow where the falling variants went wrong
        saturation = saturation_rad(robot)
        found = [v for r, vv in zip(recs, replayed.verdicts) if not vv.standing for v in find_violations(r, config.proof, saturation_rad=saturation)]
        slowed = _slowed(result.trajectory, found, config, protect_until_s)
        if slowed.duration_s > config.max_duration_s or _overstretched(slowed, commanded, join_row, config.motion_max_stretch):
            break
        log.info("ensemble round %d: %d variants fall; slowing", rounds, len(failures))
        again = nominal(dataclasses.replace(slowed, report=commanded.report), False)
        if not again.proven:
            break
        result, recs = again, []
    # what the executor needs: the limits it was proven under, the positions to expect
    executed = {TRIM_KEY: trims, COMMAND_LIMITS_KEY: limits.to_dict(), PREDICTED_KEY: predicted_positions(result.recording, ensemble=recs),
                COMBINED_VARIANTS_KEY: config.proof.combined_variants,
                "ensemble_seconds": ensemble_s, "ensemble_rounds": rounds, "noise_rounds": noise_rounds}
    return dataclasses.replace(result, report={**result.report, **executed},
                               trajectory=dataclasses.replace(result.trajectory, report={**result.trajectory.report, **executed}))


def _nominal_filter(
    robot: Robot,
    commanded: Trajectory,
    player: Player,
    *,
    scene: str | os.PathLike[str] | None,
    config: FilterConfig,
    start: Posture,
    protect_until_s: float,
    progress: Callable[[int, int], None] | None,
    limits: CommandLimits,
    join_row: int | None = None,
    stop_at_join: bool = False,
) -> FilterResult:
    """The filter on the nominal model: reshape until proven there (the loop of the module docstring),
    the targets always within the executor's ``limits``."""
    saturation = saturation_rad(robot)
    current = commanded
    history: list[FilterIteration] = []
    best: tuple[Trajectory, Recording, StandVerdict, Proof] | None = None  # best proven so far
    best_violations = 0  # how many violations the best proven one still has (fewer is better)
    last: tuple[Trajectory, Recording, StandVerdict, Proof] | None = None
    soft = 0
    tilt = ground_tilt_vector(player.model, player.index.ground_geoms)
    slope_pending = float(np.linalg.norm(tilt)) >= SLOPE_MIN_RAD
    slope_info: dict[str, Any] | None = None
    levers = arm_levers(robot, player.model, player.index.robot_geoms)
    trunk = np.flatnonzero(player.model.geom_bodyid[player.index.robot_geoms] == player.index.root_body)
    lean_total = np.zeros_like(current.q)
    lean_used = 0  # lean adaptations so far (at most LEAN_ITERATIONS); each one earns an extra iteration
    lean_info: dict[str, Any] | None = None
    it = 0
    while it < config.max_iterations + lean_used:
        it += 1
        current = conform(current, limits)
        stop_at_s = float(current.t[join_row]) if stop_at_join and join_row is not None and 0 < join_row < len(current.t) else None
        rec, verdict, proof, found = prove_with_violations(robot, current, scene=scene, config=config.proof, player=player, start=start,
                                                           saturation_rad=saturation, stop_at_s=stop_at_s)
        if slope_pending and not proof.proven and rec.stopped_s is None:
            # flat-ground stance on a slope: turn it to the slope once, in the heading the robot stood in
            slope_pending = False
            turned = turn_stance_to_slope(robot, current, rec, player.model, tilt)
            if turned is not None:
                history.append(FilterIteration(it, current.duration_s, verdict.peak_envelope_ratio, verdict.standing, ("stance turned to the slope",)))
                log.info("filter iteration %d: stance turned to the slope: %s", it, turned[1])
                last = (current, rec, verdict, proof)
                current, slope_info = turned
                continue
        violations = [v for v in found if v.t_start_s <= current.duration_s]
        if lean_used < LEAN_ITERATIONS and not verdict.standing and current.root is not None and not any(v.kind == "torque" for v in violations):
            # torque first (time scaling changes how the body moves); then a lean other than the library's on arms and feet
            adapted = adapt_lean(robot, current, rec, levers, trunk, lean_total, join_row)
            if adapted is not None:
                lean_used += 1
                history.append(FilterIteration(it, current.duration_s, verdict.peak_envelope_ratio, verdict.standing, (f"lean on arms and feet adapted (error {math.degrees(adapted[2]):.1f} deg)",)))
                log.info("filter iteration %d: lean on arms and feet adapted, error %.1f deg", it, math.degrees(adapted[2]))
                last = (current, rec, verdict, proof)
                current, lean_total = adapted[0], adapted[1]
                lean_info = {"shoulder_joints": [lv.joint for lv in levers], "max_offset_rad": float(np.max(np.abs(lean_total))), "iterations": lean_used}
                continue
        history.append(
            FilterIteration(it, current.duration_s, verdict.peak_envelope_ratio, verdict.standing, tuple(v.describe() for v in violations))
        )
        log.info("filter iteration %d: %s; %d violations", it, verdict.summary(), len(violations))
        if progress is not None:
            progress(it, config.max_iterations)
        last = (current, rec, verdict, proof)
        if proof.proven:
            if best is None or len(violations) < best_violations:
                best, best_violations = (current, rec, verdict, proof), len(violations)
            if not violations:
                break
            soft += 1
            if soft > config.soft_iterations:
                break
        windows = [
            (max(v.t_start_s - config.window_pad_s, protect_until_s), min(v.t_end_s + config.window_pad_s, current.duration_s))
            for v in violations
        ]
        windows = [(a, b) for a, b in windows if b > a]
        if not windows and not proof.proven:
            # failed without a local cause: slow down everything after the protected part
            windows = [(protect_until_s, current.duration_s)]
        if not windows:
            break
        stretched = time_scale(current, windows, config.slow_factor)
        if stretched.duration_s > config.max_duration_s or _overstretched(stretched, commanded, join_row, _stretch_cap(config)):
            break
        current = stretched
    assert last is not None
    current, rec, verdict, proof = best if best is not None else last
    ok = proof.proven
    reason = "" if ok else "; ".join(proof.problems) + (f" (after {len(history)} filter iterations)")
    full_report = {
        **proof.to_dict(),
        **({"slope_stance": slope_info} if slope_info is not None else {}),
        **({"lean_adapted": lean_info} if lean_info is not None else {}),
        "filter_iterations": len(history),
        "filter_history": [
            {"iteration": h.iteration, "duration_s": h.duration_s, "peak_torque_ratio": h.peak_envelope_ratio, "standing": h.standing, "violations": list(h.violations)}
            for h in history
        ],
    }
    final = Trajectory(robot.name, current.joint_names, current.t, current.q, start, {**current.report, **full_report}, None)
    return FilterResult(ok, final, rec, verdict, proof, tuple(history), reason, full_report)


def _trim(
    robot: Robot,
    result: FilterResult,
    guess: Trajectory,
    player: Player,
    *,
    scene: str | os.PathLike[str] | None,
    config: FilterConfig,
    start: Posture,
    protect_until_s: float,
    limits: CommandLimits,
    join_row: int | None,
    stop_at_join: bool,
) -> tuple[FilterResult, dict[str, Any]] | None:
    """The nominal filter's proven ``result`` with less of the time it added to ``guess``, proven as it was.

    The filter slows whole padded windows by ``slow_factor`` per iteration: coarse steps of a few
    tenths of a second each. Here the time it added (the result's row times minus ``guess``'s, row
    by row: slowing and conforming move times only) is scaled by a fraction found by bisection
    over ``config.trim_levels`` nominal replays; the shortest proven there in one iteration, with
    no more violations than ``result``, is returned (the caller then checks it against noise and
    the ensemble as it would have checked ``result``). None where no shorter one is proven."""
    final = result.trajectory
    if len(final.t) != len(guess.t) or final.duration_s <= guess.duration_s + 1e-6:
        return None
    added = final.t - guess.t
    if np.any(np.diff(added) < -1e-9):  # not a stretch of the guess's clock: leave it be
        return None
    saturation = saturation_rad(robot)
    allowed = len([v for v in find_violations(result.recording, config.proof, saturation_rad=saturation) if v.t_start_s <= final.duration_s])
    one = dataclasses.replace(config, max_iterations=1, soft_iterations=0)
    best: tuple[float, FilterResult] | None = None
    lo, hi = 0.0, 1.0  # the fraction of the added time kept: hi proven, lo not (or, at 0, the guess's own timing, not replayed here)
    for _ in range(config.trim_levels):
        mid = 0.5 * (lo + hi)
        tried = dataclasses.replace(final, t=guess.t + mid * added, report=guess.report)
        res = _nominal_filter(robot, tried, player, scene=scene, config=one, start=start, protect_until_s=protect_until_s,
                              progress=None, limits=limits, join_row=join_row, stop_at_join=stop_at_join)
        ok = res.proven and len(res.iterations) == 1 and len(res.iterations[0].violations) <= allowed
        log.info("trim to %.3f of the added %.2f s: %s", mid, float(added[-1]), "proven" if ok else "not proven")
        if ok:
            best, hi = (mid, res), mid
        else:
            lo = mid
    if best is None:
        return None
    alpha, res = best
    saved = final.duration_s - res.trajectory.duration_s
    if saved <= MIN_TRIM_S:  # the time added was conforming's, which every replay puts back
        return None
    log.info("trimmed: %.2f s of the filter's %.2f s of slowing kept, %.2f s sooner", alpha * float(added[-1]), float(added[-1]), saved)
    # the untrimmed result's filter history first: the trimmed one's iteration is its last
    n = len(result.iterations)
    ours = dataclasses.replace(res.iterations[0], iteration=n + 1)
    history = result.report.get("filter_history", []) + [{**h, "iteration": n + 1} for h in res.report.get("filter_history", [])]
    # the rows are the untrimmed result's, so is what turned the stance or adapted the lean in them
    carried = {k: result.report[k] for k in ("slope_stance", "lean_adapted") if k in result.report}
    entries = {**carried, "filter_iterations": len(history), "filter_history": history}
    res = dataclasses.replace(res, iterations=result.iterations + (ours,), report={**res.report, **entries},
                              trajectory=res.trajectory.with_report(**entries))
    return res, {"fraction_kept": alpha, "saved_s": saved, "untrimmed_duration_s": final.duration_s, "kept": True}


def _with_noise_check(result: FilterResult, checked: NoiseCheck) -> FilterResult:
    """``result`` with its noise check's verdict in its proof, report and trajectory's report."""
    proof = with_noise(result.proof, checked)
    entries = {**proof.to_dict(), NOISE_CHECK_KEY: checked.to_dict()}
    failures = checked.failures()
    reason = result.reason if not failures else "; ".join(failures[:2]) + f" ({len(failures)} of {len(checked.replays)} noisy replays)"
    return dataclasses.replace(result, proven=proof.proven, proof=proof, reason=reason, report={**result.report, **entries},
                               trajectory=dataclasses.replace(result.trajectory, report={**result.trajectory.report, **entries}))


def _slowed(trajectory: Trajectory, found: list[Violation], config: FilterConfig, protect_until_s: float) -> Trajectory:
    """``trajectory`` slowed around the violations ``found`` (padded), everything after
    ``protect_until_s`` where none is local."""
    windows = [(max(v.t_start_s - config.window_pad_s, protect_until_s), min(v.t_end_s + config.window_pad_s, trajectory.duration_s))
               for v in found]
    windows = [(a, b) for a, b in windows if b > a] or [(protect_until_s, trajectory.duration_s)]
    return time_scale(trajectory, windows, config.slow_factor)


def _stretch_cap(config: FilterConfig) -> float | None:
    """The nominal filter's bound on slowing the library part: the tighter of the two."""
    caps = [c for c in (config.max_stretch, config.motion_max_stretch) if c is not None]
    return min(caps) if caps else None


def _overstretched(stretched: Trajectory, commanded: Trajectory, join_row: int | None, max_stretch: float | None) -> bool:
    """The part from ``join_row`` on (the whole without one) slowed beyond ``max_stretch`` x its
    commanded duration. Rows never move (slowing and conforming change times only), so the row
    index marks the same posture in both."""
    if max_stretch is None:
        return False
    row = 0 if join_row is None or not 0 <= join_row < len(commanded.t) else join_row
    return stretched.t[-1] - stretched.t[row] > max_stretch * (commanded.t[-1] - commanded.t[row]) + 1e-9
