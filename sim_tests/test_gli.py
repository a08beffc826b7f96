"""Tests of robot_rise.planning.energy.gli: the Gauss linking integral (paper 004 eq. 7-8)."""

from __future__ import annotations

import numpy as np
import pytest

from robot_rise.constants import GLI_SAFE_ZONE_THRESHOLD
from robot_rise.model import compose, load_robot, model_index
from robot_rise.planning.energy.gli import GliMatrix, LINKAGE_ORDER, gli_difference, in_safe_zone, polyline_gli, segment_pair_gli


def _numeric_gli(p1, p2, p3, p4, n=400) -> float:
    """Midpoint-rule double integral of eq. (7)."""
    s = (np.arange(n) + 0.5) / n
    g1 = p1 + s[:, None] * (p2 - p1)
    g2 = p3 + s[:, None] * (p4 - p3)
    r = g1[:, None] - g2[None]
    c = np.cross((p2 - p1) / n, (p4 - p3) / n)
    return float(np.sum(r @ c / np.linalg.norm(r, axis=-1) ** 3) / (4 * np.pi))


def _circle(center, u, v, n=48):
    t = np.linspace(0.0, 2 * np.pi, n + 1)
    return center + np.cos(t)[:, None] * u + np.sin(t)[:, None] * v


def test_that_the_closed_form_matches_the_double_integral():
    rng = np.random.default_rng(3)
    for _ in range(10):
        p = rng.normal(size=(4, 3))
        assert segment_pair_gli(*p) == pytest.approx(_numeric_gli(*p), abs=1e-5)


def test_that_two_linked_loops_have_gli_one():
    a = _circle(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    b = _circle(np.array([1.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]))
    assert abs(polyline_gli(a, b)) == pytest.approx(1.0, abs=1e-9)


def test_that_unlinked_loops_have_gli_zero():
    a = _circle(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    b = _circle(np.array([3.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]))
    assert polyline_gli(a, b) == pytest.approx(0.0, abs=1e-9)


def test_that_far_unlinked_segments_have_gli_near_zero():
    g = segment_pair_gli(np.array([0, 0, 0.0]), np.array([1, 0, 0.0]), np.array([0, 100, 0.0]), np.array([0, 100, 1.0]))
    assert abs(g) < 1e-4


def test_that_reversing_one_curve_flips_the_sign_and_swapping_curves_keeps_it():
    a = _circle(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    b = _circle(np.array([1.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]))
    assert polyline_gli(a, b[::-1]) == pytest.approx(-polyline_gli(a, b))
    assert polyline_gli(b, a) == pytest.approx(polyline_gli(a, b))
    rng = np.random.default_rng(4)
    p = rng.normal(size=(4, 3))
    assert segment_pair_gli(p[1], p[0], p[2], p[3]) == pytest.approx(-segment_pair_gli(*p))


def test_that_passing_one_long_segment_through_another_changes_gli_by_one():
    # perpendicular, crossing at a small gap: the quadrilateral subtends half the sphere, |GLI| -> 1/2,
    # and the sign follows which segment is above, so passing through jumps by ~1 (why eq. 8 works)
    def crossing(gap):
        return segment_pair_gli(np.array([-1e3, 0, 0.0]), np.array([1e3, 0, 0.0]), np.array([0, -1e3, gap]), np.array([0, 1e3, gap]))

    assert abs(crossing(1e-3)) == pytest.approx(0.5, abs=1e-3)
    assert crossing(1e-3) - crossing(-1e-3) == pytest.approx(np.sign(crossing(1e-3)) * 1.0, abs=2e-3)


def test_that_coplanar_segments_contribute_nothing():
    assert segment_pair_gli(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([1.0, 2.0, 0])) == 0.0


@pytest.fixture(scope="module")
def op3_gli():
    robot = load_robot()
    m = compose(robot, "flat", with_actuators=False)
    idx = model_index(m, robot)
    return robot, m, idx, GliMatrix(robot, m, idx)


def _stand_qpos(robot, m, idx, **joints):
    q = m.qpos0.copy()
    q[idx.qpos_root] = robot.stand_qpos[:7]
    q[idx.qpos_joints] = robot.stand_qpos[7:]
    for name, value in joints.items():
        q[idx.qpos_joints[robot.joint_index(name)]] = value
    return q


def test_that_the_robot_has_five_linkages_in_paper_order(op3_gli):
    robot, m, idx, gli = op3_gli
    assert gli.names == LINKAGE_ORDER
    assert all(len(lk.joint) >= 3 for lk in gli.linkages)


def test_that_the_gli_matrix_is_symmetric_with_a_zero_diagonal(op3_gli):
    robot, m, idx, gli = op3_gli
    mat = gli(_stand_qpos(robot, m, idx))
    assert mat.shape == (5, 5)
    assert np.allclose(mat, mat.T)
    assert np.allclose(np.diag(mat), 0.0)


def test_that_mirror_symmetric_postures_have_mirror_symmetric_gli(op3_gli):
    robot, m, idx, gli = op3_gli
    mat = gli(_stand_qpos(robot, m, idx))
    torso, la, ra, ll, rl = range(5)
    assert mat[la, ll] == pytest.approx(-mat[ra, rl], abs=1e-9)  # a mirror flips handedness
    assert mat[torso, la] == pytest.approx(-mat[torso, ra], abs=1e-9)


def test_that_a_small_joint_change_stays_in_the_safe_zone(op3_gli):
    robot, m, idx, gli = op3_gli
    q = _stand_qpos(robot, m, idx)
    q2 = _stand_qpos(robot, m, idx, l_el=0.3, r_sho_pitch=0.2)
    assert in_safe_zone(gli(q), gli(q2))
    assert gli_difference(gli(q), gli(q)) == 0.0
    assert GLI_SAFE_ZONE_THRESHOLD == 0.3
