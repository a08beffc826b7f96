"""The noise check: a proof must not hang on the last digits of its targets (issue 14)."""

from __future__ import annotations

import numpy as np

from robot_rise.filter import FilterConfig, dynamics_filter

from robot_rise.proof import ProofConfig
from robot_rise.proof import (
    NOISE_CHECK_KEY,
    check,
    noise_check,
    noisy_trajectory,
    prove,
    proven_noise_replays,
)
from robot_rise.posture import Posture
from robot_rise.sim.player import Player
from robot_rise.trajectory import Trajectory

SQUAT = dict(l_hip_pitch=-1.0, l_knee=2.0, l_ank_pitch=1.0, r_hip_pitch=1.0, r_knee=-2.0, r_ank_pitch=-1.0)


def _squat(robot, seconds: float) -> Trajectory:
    q0 = robot.stand_qpos[7:].copy()
    q1 = q0.copy()
    for name, value in SQUAT.items():
        q1[robot.joint_index(name)] = value
    stand = Posture(robot.name, robot.stand_qpos[:3], robot.stand_qpos[3:7], dict(zip(robot.joint_names, robot.stand_qpos[7:])))
    return Trajectory(robot.name, robot.joint_names, np.array([0.0, 1.0, 2.0, 3.0]) * seconds / 3, [q0, q1, q1, q0], stand)


def test_noisy_targets_differ_by_at_most_the_noise_and_are_seeded(robot):
    tr = _squat(robot, 3.0)
    a = noisy_trajectory(tr, np.random.default_rng(5), 1e-6)
    b = noisy_trajectory(tr, np.random.default_rng(5), 1e-6)
    assert np.array_equal(a.q, b.q) and np.array_equal(a.t, tr.t)
    assert 0 < np.max(np.abs(a.q - tr.q)) <= 1e-6


def test_a_noiseless_noise_check_is_the_nominal_replay_again(robot):
    # the player is deterministic: zero noise replays the nominal exactly (the gaps are the noise's alone)
    tr = _squat(robot, 3.0)
    player = Player(robot, "flat")
    rec, _, proof = prove(robot, tr, player=player)
    checked, recs = noise_check(tr, rec, player, config=ProofConfig(noise_replays=2, noise_rad=0.0))
    assert proof.proven and checked.holds and len(recs) == 2
    for r in checked.replays:
        assert r.tilt_gap_rad == 0.0 and r.height_gap_m == 0.0 and r.joint_gap_rad == 0.0
        assert r.peak_torque_ratio <= proof.peak_torque_ratio  # the noisy replays stop 0.5 s after the end
    assert checked.to_dict()["holding"] == 2


def test_a_proof_that_noise_breaks_is_refused_by_check_and_reshaped_by_the_filter(robot):
    # a quick squat filtered without the noise check; 0.05 rad of target noise
    # (a stand-in for a knife edge: 1e-6 rad breaks only chaotic landings) pushes it over
    noisy = FilterConfig(proof=ProofConfig(ensemble=False, noise_replays=3, noise_rad=0.05))
    fast = dynamics_filter(robot, _squat(robot, 0.45), config=FilterConfig(proof=ProofConfig(ensemble=False, noise_replays=0)))
    assert fast.proven, fast.reason
    refused = check(robot, fast.trajectory, config=noisy.proof)
    assert not refused.proven
    assert any("target noise +-0.05 rad" in p for p in refused.problems), refused.problems
    # the filter with the noise check slows where the noisy replays broke, until they hold
    result = dynamics_filter(robot, _squat(robot, 0.45), config=noisy)
    assert result.proven, result.reason
    entry = result.trajectory.report[NOISE_CHECK_KEY]
    assert entry["replays"] == entry["holding"] == 3 and entry["worst_torque_ratio"] <= 0.9
    assert result.trajectory.duration_s > fast.trajectory.duration_s and result.trajectory.report["noise_rounds"] >= 1
    assert check(robot, result.trajectory, config=noisy.proof).proven


def test_a_noisy_replay_that_ends_elsewhere_than_the_noiseless_one_does_not_hold(robot):
    # judged against the replay of another motion (a squat held down): same torque, another end
    tr = _squat(robot, 3.0)
    held = Trajectory(robot.name, robot.joint_names, tr.t, [tr.q[0], tr.q[1], tr.q[1], tr.q[1]], tr.start)
    player = Player(robot, "flat")
    other, _, _ = prove(robot, held, player=player)
    checked, _ = noise_check(tr, other, player, config=ProofConfig(noise_replays=1))
    assert not checked.holds
    assert "ends elsewhere" in checked.failures()[0] and checked.replays[0].joint_gap_rad > 1.0


def test_a_replay_of_a_proof_runs_as_many_noisy_replays_as_the_proof_did(robot):
    # a motion may ask for more (Motion.noise_replays): check of its output replays them all
    result = dynamics_filter(robot, _squat(robot, 3.0), config=FilterConfig(proof=ProofConfig(ensemble=False, noise_replays=9)))
    assert result.proven and result.trajectory.report[NOISE_CHECK_KEY]["replays"] == 9
    assert proven_noise_replays(result.trajectory, 6) == 9 and proven_noise_replays(result.trajectory, 12) == 12
    assert proven_noise_replays(result.trajectory, 0) == 0  # no noise check asked: none
    assert proven_noise_replays(_squat(robot, 3.0), 6) == 6  # a file proven before the noise check
