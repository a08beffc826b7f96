from __future__ import annotations

import numpy as np
import pytest

from robot_rise.proof import ProofConfig
from robot_rise.filter import (
    FilterConfig,
    command_limits_for,
    conform,
    dynamics_filter,
    join_with_blend,
    join_with_overlap,
    overlap_of,
    time_scale,
)
from robot_rise.proof import prove
from robot_rise.posture import Posture
from robot_rise.trajectory import Trajectory

SQUAT = dict(l_hip_pitch=-1.0, l_knee=2.0, l_ank_pitch=1.0, r_hip_pitch=1.0, r_knee=-2.0, r_ank_pitch=-1.0)


def _stand(robot) -> Posture:
    return Posture(robot.name, robot.stand_qpos[:3], robot.stand_qpos[3:7], dict(zip(robot.joint_names, robot.stand_qpos[7:])))


def _squat_trajectory(robot, seconds: float) -> Trajectory:
    q0 = robot.stand_qpos[7:].copy()
    q1 = q0.copy()
    for name, value in SQUAT.items():
        q1[robot.joint_index(name)] = value
    t = np.array([0.0, 1.0, 2.0, 3.0]) * seconds / 3
    return Trajectory(robot.name, robot.joint_names, t, [q0, q1, q1, q0], _stand(robot))


def test_time_scale_stretches_only_inside_the_window(robot):
    tr = _squat_trajectory(robot, 3.0)
    out = time_scale(tr, [(1.0, 2.0)], 2.0)
    assert np.allclose(out.t, [0, 1, 3, 4])
    assert np.array_equal(out.q, tr.q)


def test_join_turns_a_mismatch_into_a_blend_within_the_speed_bound(robot):
    tr = _squat_trajectory(robot, 3.0)
    shifted = Trajectory(robot.name, robot.joint_names, tr.t, tr.q + 0.6, tr.start)
    joined = join_with_blend(tr, shifted, 1, blend_s=0.2, max_speed_rad_s=2.0)
    k = len(tr.t)
    assert np.allclose(joined.q[:k], tr.q)
    assert np.allclose(joined.q[k:], shifted.q[1:])
    gap = joined.t[k] - joined.t[k - 1]
    assert gap == pytest.approx(max(0.2, np.max(np.abs(tr.q[-1] - shifted.q[1])) / 2.0))
    assert np.all(np.diff(joined.t) > 0)


def test_an_overlapped_join_starts_the_motion_before_the_plan_ends_and_cross_fades_into_it(robot):
    plan = _squat_trajectory(robot, 3.0)  # rows at 0, 1, 2, 3 s; ends at rest on the stand
    t = np.linspace(0.0, 2.0, 21)
    q = np.array([plan.q[-1] + 0.3 * s for s in t / 2.0])  # the motion leaves the stand at 0.15 rad/s per joint
    motion = Trajectory(robot.name, robot.joint_names, t, q, plan.start)
    joined, row = join_with_overlap(plan, motion, 0, overlap_s=0.5)
    assert row == 3 and np.allclose(joined.q[:3], plan.q[:3])  # the plan's rows before 2.5 s
    assert joined.t[row] == pytest.approx(2.5)  # the motion's first row, 0.5 s before the plan ends
    assert joined.duration_s == pytest.approx(2.5 + 2.0)
    assert np.all(np.diff(joined.t) > 0)
    halfway = plan.q[-2] + 0.5 * (plan.q[-1] - plan.q[-2])
    assert np.allclose(joined.q[row], halfway)  # where the plan's targets are then: the cross-fade starts from them
    after = joined.t >= 3.0 - 1e-9  # past the overlap: the motion's own rows
    assert np.allclose(joined.q[after], motion.q[5:])
    inside = (joined.t > 2.5) & (joined.t < 3.0)
    ends = np.stack([halfway, plan.q[-1], motion.q[5]])
    lo, hi = ends.min(axis=0), ends.max(axis=0)
    assert np.all((joined.q[inside] >= lo - 1e-9) & (joined.q[inside] <= hi + 1e-9))  # a blend of the two, no overshoot
    # an overlap of more than half the plan is cut to half: the approach keeps its first half
    _, row = join_with_overlap(plan, motion, 0, overlap_s=10.0)
    assert row == 2 and overlap_of(plan, motion, 0, 10.0) == pytest.approx(1.5)
    # and to the motion's rest: the fade ends within the motion, on its last targets
    late, row = join_with_overlap(plan, motion, 18, overlap_s=0.5)
    assert overlap_of(plan, motion, 18, 0.5) == pytest.approx(0.2) and late.t[row] == pytest.approx(2.8)
    assert np.allclose(late.q[-1], motion.q[-1]) and late.duration_s == pytest.approx(3.0)
    # nothing to overlap: the motion's last frame, a plan of one row
    one_row = Trajectory(robot.name, robot.joint_names, [0.0], plan.q[-1:], plan.start)
    assert overlap_of(plan, motion, 20, 0.5) == 0.0 and overlap_of(one_row, motion, 0, 0.5) == 0.0
    with pytest.raises(ValueError, match="nothing to overlap"):
        join_with_overlap(plan, motion, 20, overlap_s=0.5)


def test_a_slow_squat_is_proven_and_reports_its_numbers(robot):
    rec, verdict, proof = prove(robot, _squat_trajectory(robot, 3.0))
    assert proof.proven, proof.problems
    assert verdict.standing
    assert 0 < proof.peak_torque_ratio <= 0.9
    assert set(proof.peak_torque_ratio_per_joint) == set(robot.joint_names)
    assert proof.min_zmp_margin_m > 0
    assert proof.ground_contacts == ("l_foot", "r_foot")
    assert len(proof.robot_digest) == 64 and len(proof.scene_digest) == 64


def test_a_too_fast_squat_is_slowed_by_the_filter_until_it_is_within_the_envelope_less_the_headroom(robot):
    fast = _squat_trajectory(robot, 0.45)
    _, _, before = prove(robot, fast)
    assert not before.proven and before.peak_torque_ratio > 0.9
    config = FilterConfig()
    result = dynamics_filter(robot, fast, config=config)
    assert result.proven, result.reason
    # proven under the bound less the headroom, so check's fresh noise (judged at the bound) keeps it
    proving_limit = 1.0 - config.proof.envelope_margin - config.proof.proof_headroom
    assert config.proof.proof_headroom > 0 and result.proof.envelope_limit == pytest.approx(proving_limit)
    assert result.proof.peak_torque_ratio <= proving_limit
    assert result.trajectory.duration_s > fast.duration_s
    assert result.report["filter_iterations"] >= 2
    assert result.trajectory.report["proven"] is True and result.proof.proven
    # the output is the commanded targets, replayable: check agrees
    _, _, again = prove(robot, result.trajectory)
    assert again.proven and again.envelope_limit == pytest.approx(1.0 - config.proof.envelope_margin)


def test_a_motion_timing_window_stops_the_slowing_at_its_bound(robot):
    # a momentum motion stands only near its own timing (Motion.max_stretch): the filter does not
    # replay ever slower versions of it, the next candidate is cheaper
    fast = conform(_squat_trajectory(robot, 0.45), command_limits_for(robot))  # what the executor can stream
    capped = dynamics_filter(robot, fast, config=FilterConfig(motion_max_stretch=1.05, proof=ProofConfig(ensemble=False)), join_row=0)
    assert not capped.proven
    assert capped.trajectory.duration_s <= 1.05 * fast.duration_s + 1e-9
    assert capped.report["filter_iterations"] == 1
    free = dynamics_filter(robot, fast, config=FilterConfig(proof=ProofConfig(ensemble=False)), join_row=0)
    assert free.proven and free.trajectory.duration_s > 1.05 * fast.duration_s


def test_an_impossible_motion_fails_with_a_reason(robot):
    tr = _squat_trajectory(robot, 3.0)
    q = tr.q.copy()
    q[1:3, robot.joint_index("l_hip_roll")] = -1.0  # kick a leg out sideways: falls over
    q[1:3, robot.joint_index("r_hip_roll")] = 1.0
    q[1:3, robot.joint_index("l_knee")] = 0.0
    bad = Trajectory(robot.name, robot.joint_names, tr.t, q, tr.start)
    result = dynamics_filter(robot, bad, config=FilterConfig(max_iterations=2))
    if result.proven:
        pytest.skip("the robot happened to stay up; not an impossible motion for this model")
    assert result.reason and "filter iterations" in result.reason
    assert result.trajectory.report["proven"] is False


def test_a_slow_squat_still_stands_under_every_variant_of_the_ensemble(robot):
    from robot_rise.proof import EnsembleReplayer, stands_under
    from robot_rise.sim.variants import ENSEMBLE, ModelVariant

    tr = _squat_trajectory(robot, 3.0)
    result, _ = EnsembleReplayer(robot, "flat", threads=1).replay(tr)
    assert len(result.verdicts) == len(ENSEMBLE) >= 12 and result.all_stand, result.failures()
    # a robot with a third of its servo torque cannot hold a deep squat
    assert not stands_under(robot, tr, ModelVariant("weak servos", supply_scale=1.0 / 3.0))


def test_a_replay_over_the_margin_by_the_join_stops_there_and_the_filter_still_slows_the_approach(robot):
    from robot_rise.proof.verdict import prove_with_violations
    from robot_rise.proof.violations import saturation_rad
    from robot_rise.sim.player import Player

    fast = conform(_squat_trajectory(robot, 0.45), command_limits_for(robot))
    join_s = float(fast.t[3])  # the squat is the "approach" (over the margin on the way back up), the last row the library part
    rec, _, proof, found = prove_with_violations(robot, fast, scene="flat", config=ProofConfig(), player=Player(robot, "flat"),
                                                 start=fast.start, saturation_rad=saturation_rad(robot), stop_at_s=join_s)
    assert rec.stopped_s is not None and rec.t[-1] <= join_s + 1e-9
    assert not proof.proven and proof.problems[0].startswith("replay stopped at")
    assert found and all(v.t_start_s <= join_s for v in found)
    result = dynamics_filter(robot, fast, config=FilterConfig(proof=ProofConfig(ensemble=False)), join_row=3, stop_at_join=True)
    assert result.proven, result.reason
    assert result.recording.stopped_s is None and result.report["filter_iterations"] >= 2
    assert prove(robot, result.trajectory)[2].proven  # the whole replay agrees
