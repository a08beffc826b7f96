"""Tests of robot_rise.planning.energy.capsules: exact segment distances and the robot as capsules."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.optimize import minimize

from robot_rise.model import compose, load_robot, model_index
from robot_rise.planning.energy import capsules
from robot_rise.planning.energy.capsules import (
    ground_halfspaces,
    non_adjacent_pairs,
    robot_capsules,
    segment_closest_points,
    segment_distance,
    world_capsules,
)


def _brute_force_distance(p0, p1, q0, q1) -> float:
    """Minimum over a fine grid, polished by a bounded optimiser."""
    s = np.linspace(0.0, 1.0, 201)
    a = p0 + s[:, None] * (p1 - p0)
    b = q0 + s[:, None] * (q1 - q0)
    d = np.linalg.norm(a[:, None] - b[None], axis=-1)
    i, j = np.unravel_index(np.argmin(d), d.shape)

    def f(x):
        return np.linalg.norm(p0 + x[0] * (p1 - p0) - q0 - x[1] * (q1 - q0))

    res = minimize(f, [s[i], s[j]], bounds=[(0, 1), (0, 1)], method="L-BFGS-B", options={"ftol": 1e-15, "gtol": 1e-12})
    return float(min(res.fun, d[i, j]))


def test_that_segment_distance_matches_brute_force_on_random_segments():
    rng = np.random.default_rng(1)
    for _ in range(50):
        p0, p1, q0, q1 = rng.normal(size=(4, 3))
        assert segment_distance(p0, p1, q0, q1) == pytest.approx(_brute_force_distance(p0, p1, q0, q1), abs=1e-7)


def test_that_nearly_parallel_collinear_and_very_unequal_segments_match_brute_force():
    # the clamping branches of the closed form: near-parallel lines (tiny denominator), collinear
    # disjoint segments, a segment 1000 times shorter than the other, end-to-end closest points
    rng = np.random.default_rng(3)
    cases = []
    for _ in range(40):
        p0, u, w = rng.normal(size=(3, 3))
        u /= np.linalg.norm(u)
        for angle in (1e-9, 1e-6, 1e-3):
            v = u + angle * np.cross(u, w)
            cases.append((p0, p0 + u, p0 + 0.1 * w + rng.uniform(-1.5, 1.5) * u, p0 + 0.1 * w + rng.uniform(-1.5, 1.5) * u + v))
        cases.append((p0, p0 + u, p0 + 1.3 * u, p0 + 2.0 * u))  # collinear, disjoint: gap 0.3
        cases.append((p0, p0 + u, p0 + 0.5 * u + 0.2 * w, p0 + 0.5 * u + 0.2 * w + 1e-3 * rng.normal(size=3)))
    for p0, p1, q0, q1 in cases:
        assert segment_distance(p0, p1, q0, q1) == pytest.approx(_brute_force_distance(p0, p1, q0, q1), abs=1e-7)
    # and batched, the same numbers
    arr = [np.array(x) for x in zip(*cases)]
    batch = segment_distance(*arr)
    assert np.allclose(batch, [segment_distance(*c) for c in cases], atol=1e-12)


def test_that_segment_distance_is_vectorised_over_leading_axes():
    rng = np.random.default_rng(2)
    p0, p1, q0, q1 = rng.normal(size=(4, 7, 5, 3))
    batch = segment_distance(p0, p1, q0, q1)
    assert batch.shape == (7, 5)
    assert batch[3, 2] == pytest.approx(float(segment_distance(p0[3, 2], p1[3, 2], q0[3, 2], q1[3, 2])))


def test_that_parallel_overlapping_segments_have_their_gap_as_distance():
    d, s, t = segment_closest_points(np.array([0, 0, 0.0]), np.array([1, 0, 0.0]), np.array([0.5, 0.3, 0]), np.array([2, 0.3, 0.0]))
    assert d == pytest.approx(0.3)
    assert 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0


def test_that_crossing_segments_have_zero_distance_at_the_crossing():
    d, s, t = segment_closest_points(np.array([-1, 0, 0.0]), np.array([1, 0, 0.0]), np.array([0, -1, 0.0]), np.array([0, 1, 0.0]))
    assert d == pytest.approx(0.0, abs=1e-12)
    assert s == pytest.approx(0.5) and t == pytest.approx(0.5)


def test_that_degenerate_segments_are_points():
    p = np.array([0.0, 0.0, 1.0])
    assert segment_distance(p, p, np.array([-1, 0, 0.0]), np.array([1, 0, 0.0])) == pytest.approx(1.0)
    assert segment_distance(np.array([-1, 0, 0.0]), np.array([1, 0, 0.0]), p, p) == pytest.approx(1.0)
    assert segment_distance(p, p, p + 2.0, p + 2.0) == pytest.approx(np.sqrt(12.0))
    beyond = segment_distance(np.array([2.0, 0, 0]), np.array([2.0, 0, 0]), np.array([-1, 0, 0.0]), np.array([1, 0, 0.0]))
    assert beyond == pytest.approx(1.0)


@pytest.fixture(scope="module")
def op3():
    robot = load_robot()
    m = compose(robot, "flat", with_actuators=False)
    return robot, m, model_index(m, robot)


def test_that_every_robot_geom_becomes_at_least_one_capsule(op3):
    robot, m, idx = op3
    caps = robot_capsules(m, idx)
    assert set(caps.geom.tolist()) == set(idx.robot_geoms.tolist())
    assert np.all(caps.radius > 0)
    upper = caps.names.index("l_upper_arm")
    assert caps.radius[upper] == pytest.approx(0.019)
    assert np.linalg.norm(caps.b_local[upper] - caps.a_local[upper]) == pytest.approx(0.072)
    head = caps.names.index("head")
    assert np.allclose(caps.a_local[head], caps.b_local[head])


def test_that_box_capsules_stay_near_the_box(op3):
    robot, m, idx = op3
    caps = robot_capsules(m, idx)
    foot = [k for k, n in enumerate(caps.names) if n == "l_foot"]
    assert 1 < len(foot) <= capsules.MAX_BOX_SEGMENTS_ROBOT
    g = m.geom("l_foot").id
    half = m.geom_size[g]
    for k in foot:
        for p in (caps.a_local[k], caps.b_local[k]):
            local = p - m.geom_pos[g]
            assert np.all(np.abs(local) <= half + 1e-9)
        assert caps.radius[k] == pytest.approx(half.min())


def test_that_capsule_endpoints_follow_the_body_in_the_world(op3):
    robot, m, idx = op3
    caps = robot_capsules(m, idx)
    d = mujoco.MjData(m)
    d.qpos[idx.qpos_root] = robot.stand_qpos[:7]
    d.qpos[idx.qpos_joints] = robot.stand_qpos[7:]
    mujoco.mj_kinematics(m, d)
    a, b = caps.world_endpoints(d)
    k = caps.names.index("l_forearm")
    g = m.geom("l_forearm").id
    axis = d.geom_xmat[g].reshape(3, 3)[:, 2] * m.geom_size[g, 1]
    ends = {tuple(np.round(d.geom_xpos[g] - axis, 9)), tuple(np.round(d.geom_xpos[g] + axis, 9))}
    assert {tuple(np.round(a[k], 9)), tuple(np.round(b[k], 9))} == ends


def test_that_neighbouring_links_are_not_paired(op3):
    robot, m, idx = op3
    caps = robot_capsules(m, idx)
    i, j = non_adjacent_pairs(m, caps)
    pairs = {(caps.names[a], caps.names[b]) for a, b in zip(i, j)} | {(caps.names[b], caps.names[a]) for a, b in zip(i, j)}
    assert ("torso", "l_upper_arm") not in pairs  # joined through a geom-less shoulder bracket
    assert ("l_upper_arm", "l_forearm") not in pairs
    assert ("l_thigh", "l_shank") not in pairs
    assert ("torso", "l_forearm") in pairs
    assert ("l_thigh", "r_thigh") in pairs
    assert ("l_foot", "l_foot") not in pairs
    assert np.all(i < j)


def test_that_the_flat_scene_has_one_ground_plane_and_no_obstacle_capsules(op3):
    robot, m, idx = op3
    planes = ground_halfspaces(m, idx)
    assert len(planes) == 1
    assert np.allclose(planes[0].normal, [0, 0, 1])
    assert planes[0].signed_distance(np.array([0.3, 0.1, 0.25])) == pytest.approx(0.25)
    assert len(world_capsules(m, idx)) == 0


def test_that_table_obstacles_become_static_capsules():
    robot = load_robot()
    m = compose(robot, "table", with_actuators=False)
    idx = model_index(m, robot)
    caps = world_capsules(m, idx)
    assert set(caps.names) >= {"table_top", "table_leg_1"}
    assert np.all(caps.body == 0)
