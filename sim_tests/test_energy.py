"""Tests of the robot_rise.planning.energy package: repulsive energy, gradient, Algorithms 1-2, local minima, refinement."""

from __future__ import annotations

import dataclasses
import math
import time

import mujoco
import numpy as np
import pytest

from robot_rise.constants import ENERGY_LOCAL_MINIMUM_PATIENCE, OUTPUT_SPACING_RAD
from robot_rise.model import load_robot
from robot_rise.planning import energy as energy_module
from robot_rise.bench.energy_problems import crossed_problems, straight_motion_is_illegal
from robot_rise.planning.energy import (
    EnergyConfig,
    EnergyPlanner,
    EnergyWindow,
    PositionalConstraint,
    RepulsiveEnergy,
    energy_interpolate,
    plan_energy,
    tangent_difference,
    tangent_step,
)
from robot_rise.planning.energy import constraints as energy_constraints
from robot_rise.planning.energy import dense as energy_dense
from robot_rise.planning.energy import planner as energy_planner
from robot_rise.planning.energy.gli import GliMatrix, gli_difference
from robot_rise.planning.motion_validator import MotionValidator
from robot_rise.planning.problem import PlanningProblem, PlanStatus
from robot_rise.validity import ValidityChecker


@pytest.fixture(scope="module")
def setup():
    robot = load_robot()
    checker = ValidityChecker(robot, "flat")
    return robot, checker, RepulsiveEnergy(checker)


@pytest.fixture(scope="module")
def problems(setup):
    robot, checker, _ = setup
    return {p.kind: p for p in crossed_problems(robot, checker, n=1)}


def _stand(robot, checker, jitter=0.0, seed=0):
    q = checker.model.qpos0.copy()
    q[checker.index.qpos_root] = robot.stand_qpos[:7]
    q[checker.index.qpos_joints] = robot.stand_qpos[7:] + np.random.default_rng(seed).normal(size=robot.n_joints) * jitter
    return q


def test_that_every_name_in_all_resolves():
    for name in energy_module.__all__:
        assert hasattr(energy_module, name), name


@pytest.mark.parametrize("falloff_d", [2, 3, 5])
def test_that_the_analytic_gradient_matches_finite_differences(setup, falloff_d):
    robot, checker, _ = setup
    energy = RepulsiveEnergy(checker, EnergyConfig(falloff_d=falloff_d))
    m = checker.model
    for seed in range(3):
        q = _stand(robot, checker, jitter=0.3, seed=seed)
        q[checker.index.qpos_root[2]] += 0.05  # off the ground: smooth branch of the softening
        value = energy(q)
        fd = np.zeros(m.nv)
        h = 1e-6
        for k in range(m.nv):
            e = np.zeros(m.nv)
            e[k] = h
            fd[k] = (energy(tangent_step(m, q, e), gradient=False).total - energy(tangent_step(m, q, -e), gradient=False).total) / (2 * h)
        assert np.allclose(value.gradient, fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())


def test_that_the_gradient_is_right_for_touching_links_and_the_ground_too(setup, problems):
    robot, checker, energy = setup
    m = checker.model
    q = checker.qpos_of(problems["crossed_arms"].start)  # lying: links rest on the ground
    value = energy(q)
    fd = np.zeros(m.nv)
    h = 1e-7
    for k in range(m.nv):
        e = np.zeros(m.nv)
        e[k] = h
        fd[k] = (energy(tangent_step(m, q, e), gradient=False).total - energy(tangent_step(m, q, -e), gradient=False).total) / (2 * h)
    assert np.allclose(value.gradient, fd, rtol=1e-3, atol=1e-5 * np.abs(fd).max())


def test_that_the_energy_rises_steeply_as_two_links_approach(setup, problems):
    robot, checker, energy = setup
    q = checker.qpos_of(problems["crossed_arms"].start)  # left forearm above the right one
    k = checker.index.qpos_joints[robot.joint_index("l_sho_pitch")]
    values = []
    for delta in (0.0, 0.05, 0.1):  # lowering the left arm brings the forearms together
        qq = q.copy()
        qq[k] += delta
        values.append(energy(qq, gradient=False))
    assert values[0].min_self_m > values[1].min_self_m > values[2].min_self_m
    assert values[2].internal - values[1].internal > values[1].internal - values[0].internal > 0.0


def test_that_the_ground_term_grows_as_the_robot_sinks(setup):
    robot, checker, energy = setup
    q = _stand(robot, checker)
    high, low = q.copy(), q.copy()
    high[checker.index.qpos_root[2]] += 0.05
    assert energy(high).external < energy(q).external
    low[checker.index.qpos_root[2]] -= 0.01
    assert energy(low).external > energy(q).external
    assert energy(low).min_external_m < 0.0


def test_that_a_descent_step_lowers_the_energy(setup, problems):
    robot, checker, energy = setup
    q = checker.qpos_of(problems["crossed_legs"].start)
    v = energy(q)
    step = -0.01 * v.gradient / np.linalg.norm(v.gradient)
    assert energy(tangent_step(checker.model, q, step)).total < v.total


def test_that_the_crossed_limb_problems_have_legal_ends_and_a_penetrating_straight_motion(setup, problems):
    robot, checker, _ = setup
    assert set(problems) == {"crossed_arms", "crossed_legs", "arm_under_back"}
    for p in problems.values():
        assert checker.is_valid(p.start) and checker.is_valid(p.goal)
        assert straight_motion_is_illegal(checker, p.start, p.goal)


@pytest.mark.parametrize("kind", ["crossed_arms", "crossed_legs", "arm_under_back"])
def test_that_the_energy_planner_solves_the_crossed_limb_problems_with_a_legal_path(setup, problems, kind):
    robot, checker, _ = setup
    p = problems[kind]
    result = plan_energy(PlanningProblem(p.start, p.goal, checker, budget_s=30.0))
    assert result.status is PlanStatus.EXACT_SOLUTION, result.reason
    q = result.path.qpos(checker)
    assert np.allclose(q[0], checker.qpos_of(p.start))
    assert np.allclose(q[-1], checker.qpos_of(p.goal), atol=1e-9)
    assert _legal_path(checker, q)


def test_that_the_planner_object_and_function_agree_and_are_deterministic(setup, problems):
    robot, checker, _ = setup
    p = problems["crossed_arms"]
    problem = PlanningProblem(p.start, p.goal, checker, budget_s=30.0)
    a = plan_energy(problem)
    b = EnergyPlanner()(problem)
    assert a.solved and b.solved
    assert np.array_equal(a.path.joints, b.path.joints)


def test_that_an_illegal_start_is_reported_not_raised(setup, problems):
    robot, checker, _ = setup
    p = problems["crossed_arms"]
    sunk = p.start.with_root(root_pos=p.start.root_pos - np.array([0, 0, 0.03]))
    result = plan_energy(PlanningProblem(sunk, p.goal, checker))
    assert result.status is PlanStatus.INVALID_START
    assert "ground collision" in result.reason


def test_that_joint_limits_hold_along_the_path(setup, problems):
    robot, checker, _ = setup
    p = problems["crossed_arms"]  # elbows start 5 degrees from their limits
    result = plan_energy(PlanningProblem(p.start, p.goal, checker, budget_s=30.0))
    assert result.solved
    assert np.all(result.path.joints >= robot.joint_lower - 1e-9)
    assert np.all(result.path.joints <= robot.joint_upper + 1e-9)


def _hand_heights(checker, qs, body, local):
    """Height of a body point along the path, with 20 postures per straight segment."""
    m = checker.model
    d = mujoco.MjData(m)
    bid = m.body(body).id
    out = []
    dense = [qs[0]] + [tangent_step(m, a, tangent_difference(m, a, b) * s) for a, b in zip(qs[:-1], qs[1:]) for s in np.linspace(0.05, 1.0, 20)]
    for q in dense:
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        out.append(float((d.xpos[bid] + d.xmat[bid].reshape(3, 3) @ local)[2]))
    return np.array(out)


def test_that_a_positional_constraint_keeps_a_hand_on_its_height(setup):
    robot, checker, _ = setup
    # standing 5 cm above the ground, the right arm swings from behind to in front: unconstrained,
    # the hand dips on the way; constrained (eq. 12, height only), it stays near its start height
    q0 = _stand(robot, checker)
    q0[checker.index.qpos_root[2]] += 0.05
    q1 = q0.copy()
    k = checker.index.qpos_joints[robot.joint_index("r_sho_pitch")]
    q0[k], q1[k] = -1.0, 1.0
    body, local = "r_el_link", np.array([-0.01, -0.13, 0.0])
    h0 = _hand_heights(checker, [q0, q1], body, local)
    target = float(np.mean(h0))  # the ends differ by ~1 cm (elbow offset): hold their mean
    assert abs(h0[0] - h0[1]) < 0.03
    c = PositionalConstraint(body, local, np.array([0.0, 0.0, target]), axes=(2,))
    free = energy_interpolate(checker, q0, q1, budget_s=20.0)
    held = energy_interpolate(checker, q0, q1, constraints=(c,), budget_s=20.0)
    assert free.status is PlanStatus.EXACT_SOLUTION and held.status is PlanStatus.EXACT_SOLUTION, held.reason
    dip_free = target - np.min(_hand_heights(checker, free.qpos, body, local))
    dip_held = target - np.min(_hand_heights(checker, held.qpos, body, local))
    assert held.stats["constrained_steps"] > 0
    assert dip_free > 0.02  # unconstrained, the swinging hand drops by centimetres
    assert dip_held < 0.25 * dip_free


def test_that_the_energy_window_detects_a_stall_after_the_patience():
    w = EnergyWindow(top=100.0, fraction=0.02, patience=ENERGY_LOCAL_MINIMUM_PATIENCE)
    assert not w.update(99.5, gap=1.0, min_progress=0.003)  # first gap counts as progress
    hits = [w.update(99.5, gap=1.0, min_progress=0.003) for _ in range(ENERGY_LOCAL_MINIMUM_PATIENCE)]
    assert hits[-1] and not any(hits[:-1])


def test_that_the_energy_window_slides_when_the_energy_falls():
    w = EnergyWindow(top=100.0, fraction=0.02, patience=3)
    w.update(99.0, gap=1.0, min_progress=0.003)
    for e in (97.0, 95.0, 93.0, 91.0, 89.0):
        assert not w.update(e, gap=1.0, min_progress=0.003)
    assert w.top == 89.0


def test_that_a_local_minimum_is_reported_as_a_failure_with_its_reason(setup, problems, monkeypatch):
    robot, checker, _ = setup
    p = problems["crossed_legs"]
    # a window that never slides and a gap that never shrinks: the detector must fire
    monkeypatch.setattr(EnergyWindow, "update", lambda self, e, gap, mp: True)
    out = energy_interpolate(checker, checker.qpos_of(p.start), checker.qpos_of(p.goal), budget_s=10.0)
    assert out.status is PlanStatus.FAILED
    assert "local minimum" in out.reason


def test_that_tangent_difference_and_step_are_inverse(setup):
    robot, checker, _ = setup
    a = _stand(robot, checker, jitter=0.2, seed=1)
    b = _stand(robot, checker, jitter=0.2, seed=2)
    b[checker.index.qpos_root[3:]] = [math.cos(0.4), 0.0, math.sin(0.4), 0.0]
    v = tangent_difference(checker.model, a, b)
    assert np.allclose(tangent_step(checker.model, a, v), b, atol=1e-9)


def test_that_the_shared_segment_checker_checks_both_ends_of_a_qpos_segment(setup, problems):
    robot, checker, _ = setup
    good = checker.qpos_of(problems["crossed_arms"].start)  # supine, resting 0.5 mm above the ground
    sunk = good.copy()
    sunk[checker.index.qpos_root[2]] -= 0.006  # through the 2 mm tolerance
    assert not checker.is_valid_qpos(sunk)
    validator = MotionValidator.for_checker(checker, 0.005)
    assert validator.qpos_segment_valid(good, good)
    assert not validator.qpos_segment_valid(sunk, good) and not validator.qpos_segment_valid(good, sunk)


def test_that_ground_contact_rows_stop_a_step_that_would_sink_a_resting_robot(setup, problems):
    robot, checker, energy = setup
    q = checker.qpos_of(problems["crossed_arms"].start)  # supine, resting 0.5 mm above the ground
    p = EnergyConfig()
    scale = energy_module.tangent_scale(checker, p.root_translation_scale_m)
    v = np.zeros(checker.model.nv)
    v[checker.index.qvel_root[2]] = -0.006  # straight down by 6 mm: through the 2 mm tolerance
    assert not checker.is_valid_qpos(tangent_step(checker.model, q, v))
    K, C = energy.ground_contact_rows(q, v, energy_module.GROUND_CONTACT_ZONE_M)
    assert K.shape[0] > 0 and K.shape == (len(C), checker.model.nv)
    empty = (np.zeros((0, checker.model.nv)), np.zeros(0))
    Ks, Cs = energy_constraints.with_ground_contacts(energy, q, v * scale, *empty, np.zeros(checker.model.nv), scale, p)
    dy = energy_constraints.project_constraints(v * scale, Ks, Cs, np.zeros(checker.model.nv), p)
    q_new = tangent_step(checker.model, q, dy / scale)
    qj = checker.index.qpos_joints  # the planner's hard joint bound (eq. 13) after every step
    q_new[qj] = np.clip(q_new[qj], robot.joint_lower, robot.joint_upper)
    assert checker.is_valid_qpos(q_new)
    assert checker.lowest_point_z(q_new) >= checker.lowest_point_z(q) - 0.001
    # a step that lifts the robot touches no constraint
    K_up, _ = energy.ground_contact_rows(q, -v, energy_module.GROUND_CONTACT_ZONE_M)
    assert K_up.shape[0] == 0


def test_that_the_safe_zone_key_postures_keep_the_ends_and_a_legal_path(setup, problems):
    robot, checker, energy = setup
    p = problems["crossed_legs"]
    raw = energy_interpolate(checker, checker.qpos_of(p.start), checker.qpos_of(p.goal), energy=energy, budget_s=30.0)
    assert raw.status is PlanStatus.EXACT_SOLUTION, raw.reason
    gli = GliMatrix(robot, checker.model, checker.index)
    keys = energy_module.safe_zone_keyframes(checker, raw.qpos, gli)
    assert 2 <= len(keys) < len(raw.qpos)
    assert np.array_equal(keys[0], raw.qpos[0]) and np.array_equal(keys[-1], raw.qpos[-1])
    assert all(any(np.array_equal(k, r) for r in raw.qpos) for k in keys)  # a subsequence of the raw path
    assert _legal_path(checker, keys)
    for a, b in zip(keys[:-1], keys[1:]):
        assert gli_difference(gli(a), gli(b)) < 0.3  # eq. (8): one safe subspace


def test_that_the_safe_zone_joins_two_nearby_postures_with_one_straight_motion(setup):
    robot, checker, energy = setup
    # standing 5 cm up, one arm swings 0.3 rad in the open: eq. (8) is far below 0.3, so Algorithm 1
    # (section 5.2.2) interpolates linearly at once; without the safe zone it walks alpha steps
    q0 = _stand(robot, checker)
    q0[checker.index.qpos_root[2]] += 0.05
    q1 = q0.copy()
    q1[checker.index.qpos_joints[robot.joint_index("r_sho_pitch")]] += 0.3
    gli = GliMatrix(robot, checker.model, checker.index)
    assert gli_difference(gli(q0), gli(q1)) < 0.3
    safe = energy_interpolate(checker, q0, q1, energy=energy, budget_s=10.0)
    walk = energy_interpolate(checker, q0, q1, params=EnergyConfig(use_safe_zone=False), energy=energy, budget_s=10.0)
    assert safe.status is PlanStatus.EXACT_SOLUTION and walk.status is PlanStatus.EXACT_SOLUTION
    assert len(safe.qpos) == 2 and safe.stats["iterations"] == 1
    assert len(walk.qpos) >= 0.3 / EnergyConfig().step_rad - 1


def test_that_the_crossed_legs_ends_are_outside_one_safe_subspace(setup, problems):
    robot, checker, _ = setup
    p = problems["crossed_legs"]
    gli = GliMatrix(robot, checker.model, checker.index)
    # the legs' linkages wind the other way round: eq. (8) must see it (threshold 0.3)
    assert gli_difference(gli(checker.qpos_of(p.start)), gli(checker.qpos_of(p.goal))) >= 0.3


def _key_path(checker, p):
    out = plan_energy(PlanningProblem(p.start, p.goal, checker, budget_s=30.0), params=EnergyConfig(second_stage=None))
    assert out.solved, out.reason
    return out.path.qpos(checker)


def test_that_resampling_keeps_the_vertices_and_bounds_the_spacing(setup, problems):
    robot, checker, _ = setup
    keys = _key_path(checker, problems["crossed_legs"])
    dense = energy_module.resample_path(checker, keys, 0.05)
    assert len(dense) > len(keys)
    assert all(any(np.allclose(k, r) for r in dense) for k in keys)
    scale = energy_module.tangent_scale(checker)
    steps = [float(np.linalg.norm(scale * tangent_difference(checker.model, a, b))) for a, b in zip(dense[:-1], dense[1:])]
    assert max(steps) <= 0.05 + 1e-9


@pytest.mark.parametrize("kind", ["crossed_arms", "crossed_legs", "arm_under_back"])
def test_that_the_second_stage_smooths_the_motion_and_keeps_it_legal(setup, problems, kind):
    robot, checker, _ = setup
    keys = _key_path(checker, problems[kind])
    stats: dict = {}
    out = energy_module.second_stage(checker, keys, stats=stats)
    assert np.array_equal(out[0], keys[0]) and np.array_equal(out[-1], keys[-1])
    assert all(checker.is_valid_qpos(q) for q in out)
    assert _legal_path(checker, out)
    assert np.all(out[:, checker.index.qpos_joints] >= robot.joint_lower - 1e-9)
    assert np.all(out[:, checker.index.qpos_joints] <= robot.joint_upper + 1e-9)
    # the corners of the key-posture polyline are rounded: the trajectory Laplacian falls by half or more
    spacing = energy_module.SecondStageConfig().frame_spacing_rad
    before = energy_module.trajectory_laplacian_energy(checker, energy_module.resample_path(checker, keys, spacing))
    after = energy_module.trajectory_laplacian_energy(checker, out)
    assert stats["laplacian_before"] == pytest.approx(before)
    assert after < 0.5 * before


def test_that_the_second_stage_reduces_the_linear_momentum_deviation(setup, problems):
    robot, checker, _ = setup
    keys = _key_path(checker, problems["crossed_legs"])
    sp = energy_module.SecondStageConfig

    def com_second_difference(path):  # eq. (18) at equal time steps: sum |c_(t-1) - 2 c_t + c_(t+1)|^2
        m, d = checker.model, mujoco.MjData(checker.model)
        c = []
        for q in path:
            d.qpos[:] = q
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            c.append(d.subtree_com[1].copy())
        c = np.array(c)
        return float(np.sum((c[:-2] - 2 * c[1:-1] + c[2:]) ** 2))

    lap_only = energy_module.second_stage(checker, keys, params=sp(w_lm=0.0))
    with_lm = energy_module.second_stage(checker, keys, params=sp(w_lm=50.0))
    assert com_second_difference(with_lm) < com_second_difference(lap_only)


class _RefuseNewPostures:
    """A checker that accepts only the postures it was given (every other one is 'illegal')."""

    def __init__(self, checker, allowed):
        self._checker = checker
        self._allowed = [np.array(q) for q in allowed]

    def __getattr__(self, name):
        return getattr(self._checker, name)

    def is_valid_qpos(self, q):
        return any(np.allclose(q, a, atol=1e-12, rtol=0.0) for a in self._allowed)


def test_that_the_second_stage_keeps_a_frame_whose_change_the_checker_refuses(setup, problems):
    robot, checker, _ = setup
    keys = _key_path(checker, problems["crossed_arms"])
    dense = energy_module.resample_path(checker, keys, 0.1)
    # only the frames themselves are "legal" (segment checks need their interior too: allow the
    # straight motions' check postures by taking the refusing checker only for frames)
    params = energy_module.SecondStageConfig(frame_spacing_rad=0.1, iterations=3)
    refusing = _RefuseNewPostures(checker, dense)
    stats: dict = {}
    out = energy_module.second_stage(refusing, dense, params=params, stats=stats, resolution_m=1.0)
    assert np.allclose(out, dense)  # every change was refused: the motion is unchanged, and legal
    assert stats["held"] == len(dense) - 2 and stats["iterations"] == 1  # nothing moved: converged


def _unstraightened_keys(checker, p):
    out = plan_energy(PlanningProblem(p.start, p.goal, checker, budget_s=30.0), params=EnergyConfig(second_stage=None, straighten_limbs=False))
    assert out.solved, out.reason
    return out.path.qpos(checker)


def _limb_excursion(checker, path, limb):
    """Largest deviation [rad] of a limb's joints from the straight motion start -> end along the rows."""
    robot = checker.robot
    cols = [checker.index.qpos_joints[robot.joint_index(j)] for j in robot.limbs[limb]]
    q = path[:, cols]
    u = np.linspace(0.0, 1.0, len(q))[:, None]  # any monotone fraction: the ends of a still limb agree
    return float(np.max(np.abs(q - q[0]))) if np.allclose(q[0], q[-1]) else float(np.max(np.abs(q - (q[0] + u * (q[-1] - q[0])))))


def test_that_straightening_stops_the_legs_moving_for_the_crossed_arms_and_keeps_the_path_legal(setup, problems):
    robot, checker, _ = setup
    keys = _unstraightened_keys(checker, problems["crossed_arms"])
    # the energy spreads the legs for an arm problem (section 5.1's "unnecessary expansion")
    assert _limb_excursion(checker, keys, "left_leg") > 0.05 and _limb_excursion(checker, keys, "right_leg") > 0.05
    stats: dict = {}
    out = energy_module.straighten_limbs(checker, keys, stats=stats)
    assert out.shape == keys.shape
    assert np.array_equal(out[0], keys[0]) and np.array_equal(out[-1], keys[-1])
    assert all(checker.is_valid_qpos(q) for q in out)
    assert _legal_path(checker, out)
    assert {"root", "left_leg", "right_leg"} <= set(stats["straightened"])
    assert _limb_excursion(checker, out, "left_leg") < 1e-9 and _limb_excursion(checker, out, "right_leg") < 1e-9
    # the arms cannot both move straight: that is the penetrating straight motion of the problem
    assert not {"left_arm", "right_arm"} <= set(stats["straightened"])


def test_that_straightening_keeps_the_path_when_the_checker_refuses_every_new_posture(setup, problems):
    robot, checker, _ = setup
    keys = _unstraightened_keys(checker, problems["crossed_arms"])
    stats: dict = {}
    out = energy_module.straighten_limbs(_RefuseNewPostures(checker, keys), keys, stats=stats)
    assert np.array_equal(out, keys) and stats["straightened"] == []


def test_that_the_default_planner_straightens_and_writes_its_motion_densely(setup, problems):
    robot, checker, _ = setup
    result = plan_energy(PlanningProblem(problems["crossed_arms"].start, problems["crossed_arms"].goal, checker, budget_s=30.0))
    assert result.solved
    leg = result.stats["legs"][-1]
    assert "left_leg" in leg["straightened"] and leg["second_stage"]["output"] in ("polyline", "bspline")
    q = result.path.qpos(checker)
    assert _limb_excursion(checker, q, "left_leg") < 1e-9
    scale = energy_module.tangent_scale(checker)
    steps = [float(np.linalg.norm(scale * tangent_difference(checker.model, a, b))) for a, b in zip(q[:-1], q[1:])]
    assert max(steps) <= OUTPUT_SPACING_RAD * 1.5  # the B-spline's samples: near the spacing


def test_that_the_dense_output_is_legal_dense_and_no_rougher_than_the_polyline(setup, problems):
    robot, checker, _ = setup
    frames = energy_module.second_stage(checker, _key_path(checker, problems["arm_under_back"]))
    stats: dict = {}
    out = energy_module.dense_output(checker, frames, stats=stats)
    assert np.array_equal(out[0], frames[0]) and np.array_equal(out[-1], frames[-1])
    assert len(out) >= 4 * len(frames) and stats["output_frames"] == len(out)
    assert _legal_path(checker, out)
    poly = energy_module.resample_path(checker, frames, OUTPUT_SPACING_RAD)
    # with an arm under the back the B-spline is legal and times smoother than the frames'
    # polyline (which bends at every frame): measured 2026-12-03 (timing by path length), J x D^5
    # 3.2x lower; on crossed arms the two time alike and the polyline is kept
    assert stats["output"] == "bspline"
    assert energy_dense.timed_roughness(checker, out) < 0.5 * energy_dense.timed_roughness(checker, poly)


def test_that_the_dense_output_falls_back_to_the_polyline_when_the_curve_is_refused(setup, problems):
    robot, checker, _ = setup
    frames = energy_module.second_stage(checker, _key_path(checker, problems["crossed_arms"]))
    poly = energy_module.resample_path(checker, frames, OUTPUT_SPACING_RAD)
    stats: dict = {}
    out = energy_module.dense_output(_RefuseNewPostures(checker, poly), frames, stats=stats, resolution_m=1.0)
    assert stats["output"] == "polyline" and np.allclose(out, poly)


def _min_jerk(duration_s, amplitude, period_s=0.002):
    t = np.arange(0.0, duration_s + 1e-9, period_s)
    tau = t / duration_s
    q = amplitude[None, :] * (10 * tau**3 - 15 * tau**4 + 6 * tau**5)[:, None]
    return t, q


def test_that_jerk_at_a_common_duration_is_exact_for_a_uniformly_slower_motion():
    from robot_rise.bench.energy_metrics import common_duration_jerk, dimensionless_jerk
    from robot_rise.planning.timing import integrated_squared_jerk

    amp = np.array([1.0, -0.5, 0.2])
    t1, q1 = _min_jerk(1.0, amp)
    t2, q2 = _min_jerk(2.0, amp)
    j1, j2 = integrated_squared_jerk(t1, q1), integrated_squared_jerk(t2, q2)
    assert j1 / j2 == pytest.approx(32.0, rel=0.05)  # the raw integral: slower is "smoother"
    assert common_duration_jerk(j1, 1.0, 2.0) == pytest.approx(j2, rel=0.05)
    assert dimensionless_jerk(t1, q1) == pytest.approx(dimensionless_jerk(t2, q2), rel=0.05)
    # minimum-jerk closed form: the integral of q'''^2 is 720 A^2 / D^5 per joint
    assert j1 == pytest.approx(720.0 * float(np.sum(amp**2)), rel=0.05)


def test_that_the_common_duration_is_the_longest_of_the_three_planners():
    from robot_rise.bench.energy import BenchRow
    from robot_rise.bench.energy_tables import with_common_duration_jerk

    def row(planner, jerk, dur, solved=True):
        return BenchRow(planner, "crossed", "crossed_legs", 0, solved, 0.1, 0.2, 1.0, 0.0, 0.0, jerk, dur, "")

    rows = [row("energy", 3200.0, 1.0), row("ompl_rrtconnect", 50.0, 2.0), row("rrt_blossom", 1.0, 9.0, solved=False),
            row("energy_raw", 100.0, 4.0)]
    out = {r.planner: r for r in with_common_duration_jerk(rows)}
    assert out["energy"].jerk_common_duration == pytest.approx(100.0)  # 3200 (1/2)^5
    assert out["ompl_rrtconnect"].jerk_common_duration == pytest.approx(50.0)
    assert math.isnan(out["rrt_blossom"].jerk_common_duration)  # unsolved: neither a reference nor a value
    assert out["energy_raw"].jerk_common_duration == pytest.approx(100.0 * 2.0**5)  # ablations use the three's reference


def test_that_the_energy_window_fires_on_real_planner_iterations_with_a_short_patience(setup, problems):
    robot, checker, energy = setup
    p = problems["crossed_legs"]
    a, b = checker.qpos_of(p.start), checker.qpos_of(p.goal)
    # section 8 fed by the planner itself (no monkeypatching): with a patience of 1, the first
    # iteration that neither lowers the window nor brings the ends closer is a "local minimum"
    short = energy_interpolate(checker, a, b, params=EnergyConfig(patience=1), energy=energy, budget_s=30.0)
    assert short.status is PlanStatus.FAILED
    assert "local minimum (paper 004 section 8)" in short.reason and "for 1 iterations" in short.reason
    full = energy_interpolate(checker, a, b, energy=energy, budget_s=30.0)  # the paper's 50 iterations
    assert full.status is PlanStatus.EXACT_SOLUTION
    assert short.stats["iterations"] < full.stats["iterations"]


def test_that_plan_with_the_energy_planner_writes_the_same_trajectory_format(setup, problems, tmp_path):
    from robot_rise.cli import main
    from robot_rise.posture import write_posture
    from robot_rise.trajectory import read_trajectory

    robot, checker, _ = setup
    p = problems["crossed_legs"]
    write_posture(tmp_path / "a.json", p.start)
    write_posture(tmp_path / "b.json", p.goal)
    outs = {}
    for planner in ("energy", "rrt-blossom"):
        rc = main(["plan", "--planner", planner, "--from", str(tmp_path / "a.json"), "--to", str(tmp_path / "b.json"),
                   "--budget", "20", "--out", str(tmp_path / f"{planner}.json")])
        assert rc == 0, planner
        outs[planner] = read_trajectory(tmp_path / f"{planner}.json")
    e, r = outs["energy"], outs["rrt-blossom"]
    assert e.joint_names == r.joint_names == tuple(robot.joint_names)
    assert e.root is not None and e.root.shape == (len(e.t), 7)
    for tr in (e, r):  # rows at one period of at most the timing's 20 ms
        dt = np.diff(tr.t)
        assert np.allclose(dt, dt[0], rtol=1e-3) and dt[0] <= 0.02 + 1e-9
    start = np.array([p.start.joints[n] for n in robot.joint_names])
    goal = np.array([p.goal.joints[n] for n in robot.joint_names])
    assert np.allclose(e.q[0], start, atol=1e-9) and np.allclose(e.q[-1], goal, atol=1e-9)
    assert e.report["planner"]["name"] == "EnergyPlanner"
    assert set(e.report) == set(r.report)  # same report sections (planner, timing, ...)


def test_that_every_benchmark_planner_is_named_and_the_ablations_differ_from_the_default():
    from robot_rise.bench import energy as bench_energy

    planners = dict(bench_energy.bench_planners())
    assert set(planners) - {"ompl_rrtconnect"} <= set(bench_energy.PLANNER_NAMES)
    assert set(bench_energy.ABLATIONS) <= set(planners)
    default = planners["energy"].params
    assert not planners["energy_nostraighten"].params.straighten_limbs and default.straighten_limbs
    assert not planners["energy_nodense"].params.dense_output and default.dense_output
    r1 = planners["energy_r1"].params  # the default before issue 7's second round
    assert r1.second_stage.frame_spacing_rad == 0.05 and r1.second_stage.w_lm == 1.0
    assert not r1.straighten_limbs and not r1.dense_output
    for name in ("energy_keys", "energy_noshortcut", "energy_oldsmooth", "energy_abc"):  # key postures, nothing after
        k = planners[name].params
        assert k.keyframes and k.second_stage is None and not k.straighten_limbs, name
    for name in ("energy_s2", "energy_s2_noshortcut", "energy_s2_oldsmooth", "energy_s2_abc"):  # + the second stage alone
        s2 = planners[name].params
        assert s2.keyframes and s2.second_stage == energy_module.SecondStageConfig() and not s2.straighten_limbs and not s2.dense_output, name
    raw = planners["energy_raw"].params
    assert not raw.keyframes and raw.second_stage is None and not raw.straighten_limbs

    def what(name):  # what a row measures: its planner (kind and parameters) and its smoothing
        pl = planners[name]
        return type(pl).__name__, getattr(pl, "params", getattr(pl, "config", None)), bench_energy._smoothing(name)

    rows = list(planners)
    copies = [(a, b) for i, a in enumerate(rows) for b in rows[i + 1:] if what(a) == what(b)]
    assert copies == []  # no row repeats another (the main rows included)


def test_that_a_tie_for_the_lowest_jerk_is_counted_as_a_tie_not_for_the_first_planner():
    from robot_rise.bench.energy import BenchRow
    from robot_rise.bench.energy_tables import paired_jerk_table

    def row(planner, variant, jerk):
        return BenchRow(planner, "crossed", "crossed_arms", variant, True, 0.1, 0.2, 1.0, 0.0, 0.0, jerk, 1.0, "")

    rows = [row("energy", 0, 5.0), row("rrt_blossom", 0, 5.0), row("energy", 1, 1.0), row("rrt_blossom", 1, 2.0)]
    table = paired_jerk_table(rows, "jerk")
    assert table.splitlines()[-1] == "| crossed_arms | 2 | 1 | 0 | 1 |"


def _legal_path(checker, q):
    """Every straight segment of the qpos rows legal at 5 mm (the planner's own segment checker)."""
    validator = MotionValidator.for_checker(checker, 0.005)
    return all(validator.qpos_segment_valid(a, b) for a, b in zip(q[:-1], q[1:]))


def test_that_the_second_stage_stops_between_iterations_once_its_deadline_has_passed(setup, problems):
    robot, checker, _ = setup
    keys = _key_path(checker, problems["crossed_legs"])
    stats: dict = {}
    out = energy_module.second_stage(checker, keys, deadline=time.monotonic() - 1.0, stats=stats)
    assert stats["stopped_on_budget"] and stats["iterations"] == 0
    assert np.array_equal(out, energy_module.resample_path(checker, keys, energy_module.SecondStageConfig().frame_spacing_rad))
    assert _legal_path(checker, out)
    free: dict = {}
    energy_module.second_stage(checker, keys, deadline=time.monotonic() + 60.0, stats=free)
    assert not free["stopped_on_budget"] and free["iterations"] > 0


def test_that_each_refinement_step_keeps_a_legal_motion_when_its_deadline_has_passed(setup, problems):
    robot, checker, _ = setup
    p = problems["crossed_arms"]
    raw = energy_interpolate(checker, checker.qpos_of(p.start), checker.qpos_of(p.goal), budget_s=30.0)
    assert raw.status is PlanStatus.EXACT_SOLUTION
    gli = GliMatrix(robot, checker.model, checker.index)
    gone = time.monotonic() - 1.0
    s: dict = {}
    keys = energy_module.safe_zone_keyframes(checker, raw.qpos, gli, deadline=gone, stats=s)
    assert s["stopped_on_budget"] and np.array_equal(keys, raw.qpos)  # nothing reduced: the raw, legal path
    keys = _unstraightened_keys(checker, p)
    s = {}
    assert np.array_equal(energy_module.straighten_limbs(checker, keys, deadline=gone, stats=s), keys)
    assert s["stopped_on_budget"] and s["straightened"] == []
    frames = energy_module.second_stage(checker, keys)
    s = {}
    out = energy_module.dense_output(checker, frames, deadline=gone, stats=s)
    assert s["stopped_on_budget"] and s["output"] == "polyline" and _legal_path(checker, out)


@pytest.mark.parametrize("budget_s", [0.05, 0.3])
def test_that_the_planner_keeps_a_tiny_budget_and_returns_a_legal_path(setup, problems, monkeypatch, budget_s):
    robot, checker, _ = setup
    p = problems["crossed_legs"]
    # the first stage computed beforehand (it alone can take longer than the budget): what is
    # timed is the refinement after it, which used to run to the end whatever the budget
    first = energy_interpolate(checker, checker.qpos_of(p.start), checker.qpos_of(p.goal), budget_s=30.0)
    assert first.status is PlanStatus.EXACT_SOLUTION
    monkeypatch.setattr(energy_planner, "energy_interpolate", lambda *a, **k: dataclasses.replace(first, stats=dict(first.stats)))
    plan_energy(PlanningProblem(p.start, p.goal, checker, budget_s=30.0))  # warm-up: first imports (scipy.sparse) are not the planner's
    t0 = time.monotonic()
    result = plan_energy(PlanningProblem(p.start, p.goal, checker, budget_s=budget_s))
    elapsed = time.monotonic() - t0
    assert result.solved, result.reason
    assert elapsed < budget_s + 0.25  # one indivisible step (a second-stage iteration, a segment check) past it
    assert result.stats["stopped_on_budget"]  # named in the result (and logged)
    q = result.path.qpos(checker)
    assert np.allclose(q[0], checker.qpos_of(p.start)) and np.allclose(q[-1], checker.qpos_of(p.goal), atol=1e-9)
    assert _legal_path(checker, q)


def test_that_a_budget_spent_in_the_first_stage_is_a_timeout_on_time(setup, problems):
    robot, checker, _ = setup
    p = problems["crossed_legs"]
    t0 = time.monotonic()
    result = plan_energy(PlanningProblem(p.start, p.goal, checker, budget_s=0.02))
    assert result.status is PlanStatus.TIMEOUT and time.monotonic() - t0 < 0.02 + 0.25


def test_that_the_default_budget_is_not_reached_on_the_crossed_limb_problems(setup, problems):
    robot, checker, _ = setup
    p = problems["crossed_legs"]
    result = plan_energy(PlanningProblem(p.start, p.goal, checker, budget_s=30.0))
    assert result.solved and result.stats["stopped_on_budget"] == []
    assert result.stats["legs"][-1]["second_stage"]["stopped_on_budget"] is False


def test_that_the_planner_numbers_live_in_robot_rise_constants():
    import ast
    from pathlib import Path

    from robot_rise import constants as c

    sp = energy_module.SecondStageConfig()
    assert (sp.iterations, sp.frame_spacing_rad, sp.w_lap, sp.w_lm, sp.halvings, sp.tolerance_rad) == (
        c.SECOND_STAGE_ITERATIONS, c.SECOND_STAGE_FRAME_SPACING_RAD, c.SECOND_STAGE_W_LAP, c.SECOND_STAGE_W_LM,
        c.SECOND_STAGE_HALVINGS, c.SECOND_STAGE_TOLERANCE_RAD)
    ep = EnergyConfig()
    assert (ep.external_weight, ep.max_iterations) == (c.ENERGY_EXTERNAL_WEIGHT, c.ENERGY_MAX_ITERATIONS)
    assert energy_module.FALLOFF_RETRY_SCHEDULE == c.FALLOFF_RETRY_SCHEDULE
    assert energy_module.GROUND_CONTACT_ZONE_M == c.GROUND_CONTACT_ZONE_M
    # no module-level number of its own in the planner's modules (one config place, with the paper
    # beside it); the geometry modules keep their own tessellation and tolerance numbers beside their reasons
    modules = sorted(p for p in Path(energy_module.__file__).parent.glob("*.py") if p.name not in ("capsules.py", "hull_fit.py", "gli.py"))
    assert len(modules) > 1
    for path in modules:
        tree = ast.parse(path.read_text())
        own = [t.id for node in tree.body if isinstance(node, ast.Assign) for t in node.targets
               if isinstance(t, ast.Name) and isinstance(node.value, (ast.Constant, ast.Tuple)) and t.id.isupper() and t.id != "__all__"]
        assert own == [], path.name
