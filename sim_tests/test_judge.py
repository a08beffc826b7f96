"""Standing judge, ZMP (paper 003 eq. 2.11-2.12) and support polygon."""

from __future__ import annotations

import numpy as np
import pytest

import robot_rise.sim.balance as balance
import robot_rise.sim.standing as judge_mod
from robot_rise.sim.balance import convex_hull_2d, support_margin, zmp_point_mass
from robot_rise.sim.standing import judge
from robot_rise.model import load_robot
from robot_rise.posture import Posture
from robot_rise.sim.player import Player
from robot_rise.trajectory import Trajectory


def test_every_name_in_all_resolves() -> None:
    for name in judge_mod.__all__:
        assert hasattr(judge_mod, name), name


def test_zmp_of_static_masses_is_the_ground_projection_of_their_centre_of_mass() -> None:
    m = np.array([1.0, 3.0])
    p = np.array([[0.0, 0.0, 0.5], [0.4, 0.2, 0.1]])
    zmp = zmp_point_mass(m, p, np.zeros((2, 3)))
    assert zmp == pytest.approx([0.3, 0.15])


def test_forward_acceleration_moves_the_zmp_backwards() -> None:
    m = np.array([1.0])
    p = np.array([[0.0, 0.0, 0.5]])
    zmp = zmp_point_mass(m, p, np.array([[1.0, 0.0, 0.0]]))
    assert zmp[0] == pytest.approx(-0.5 / 9.81)


def test_convex_hull_drops_interior_points() -> None:
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]])
    assert len(convex_hull_2d(pts)) == 4


def test_support_margin_is_positive_inside_and_negative_outside() -> None:
    square = np.array([[0, 0], [0.1, 0], [0.1, 0.1], [0, 0.1]])
    assert support_margin(np.array([0.05, 0.05]), square) == pytest.approx(0.05)
    assert support_margin(np.array([0.15, 0.05]), square) == pytest.approx(-0.05)
    assert support_margin(np.array([0.05, 0.0]), square[:2]) == pytest.approx(0.0)


def _stand_start(robot):  # type: ignore[no-untyped-def]
    sq = robot.stand_qpos
    return Posture(robot.name, sq[:3], sq[3:7], dict(zip(robot.joint_names, sq[7:])))


def test_standing_still_in_the_stand_keyframe_is_judged_standing() -> None:
    robot = load_robot()
    start = _stand_start(robot)
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.5]), np.stack([q, q]), start)
    rec = Player(robot).play(tr, hold_s=2.5)
    v = judge(rec)
    assert v.standing, v.reason
    assert v.min_zmp_margin_m > 0.01
    assert not v.self_collision
    assert v.peak_envelope_ratio < 0.5


def test_standing_on_a_low_bed_is_standing_and_lying_across_a_beam_is_not() -> None:
    robot = load_robot()
    start = _stand_start(robot)
    on_bed = start.with_root(np.array([0.30, 0.0, start.root_pos[2] + 0.06]))  # the bed's top is 0.06 m high
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.5]), np.stack([q, q]), on_bed)
    rec = Player(robot, "low_bed").play(tr, hold_s=2.5)
    assert not rec.on_feet[-1]  # the ground itself is not touched: the bed carries the robot
    v = judge(rec)
    assert v.standing, v.reason
    # the feet alone on the floor while the torso rests on an obstacle (a beam): not on its feet
    from types import SimpleNamespace

    feet_on_floor = np.array([[True, True, False]])  # columns: l_foot, r_foot, torso
    torso_on_beam = np.array([[False, False, True]])
    fake = SimpleNamespace(ground_contact=feet_on_floor, obstacle_touch=torso_on_beam, foot_geoms=np.array([0, 1]))
    assert not judge_mod.supported_on_feet(fake)[0]
    fake = SimpleNamespace(ground_contact=feet_on_floor, obstacle_touch=np.zeros((1, 3), dtype=bool), foot_geoms=np.array([0, 1]))
    assert judge_mod.supported_on_feet(fake)[0]


def test_a_robot_that_falls_over_is_not_standing() -> None:
    robot = load_robot()
    start = _stand_start(robot)
    q = start.joint_vector(robot.joint_names)
    lean = q.copy()
    for name, sign in (("l_ank_pitch", 1.0), ("r_ank_pitch", -1.0)):
        lean[robot.joint_index(name)] += sign * 1.0  # feet pitched hard: the robot tips over
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.3]), np.stack([q, lean]), start)
    v = judge(Player(robot).play(tr, hold_s=2.5))
    assert not v.standing
    assert v.reason


def test_a_too_short_recording_is_not_standing() -> None:
    robot = load_robot()
    start = _stand_start(robot)
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.1]), np.stack([q, q]), start)
    v = judge(Player(robot).play(tr, hold_s=1.0))
    assert not v.standing
    assert "stood only" in v.reason or "settled" in v.reason


# --- the fast hull / margin against the plain numpy version they replaced ------------------


def _reference_hull(points: np.ndarray) -> np.ndarray:
    pts = np.unique(np.round(np.asarray(points, dtype=float), 9), axis=0)
    if len(pts) <= 2:
        return pts

    def cross(o, a, b):  # type: ignore[no-untyped-def]
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in pts[::-1]:
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _reference_margin(point: np.ndarray, contact_points: np.ndarray) -> float:
    def seg(p, a, b):  # type: ignore[no-untyped-def]
        ab = b - a
        L = float(ab @ ab)
        s = 0.0 if L < 1e-18 else float(np.clip((p - a) @ ab / L, 0.0, 1.0))
        return float(np.linalg.norm(p - (a + s * ab)))

    p = np.asarray(point, dtype=float)
    hull = _reference_hull(contact_points)
    if len(hull) == 1:
        return -float(np.linalg.norm(p - hull[0]))
    if len(hull) == 2:
        return -seg(p, hull[0], hull[1])
    dists = [seg(p, hull[i], hull[(i + 1) % len(hull)]) for i in range(len(hull))]
    edge = np.roll(hull, -1, axis=0) - hull
    rel = p - hull
    inside = bool(np.all(edge[:, 0] * rel[:, 1] - edge[:, 1] * rel[:, 0] >= 0))
    return min(dists) if inside else -min(dists)


def test_hull_and_margin_equal_the_plain_numpy_version_on_random_contact_sets() -> None:
    rng = np.random.default_rng(7)
    for i in range(600):
        pts = rng.normal(size=(int(rng.integers(1, 12)), 2)) * 0.05
        if i % 5 == 0:
            pts = np.round(pts, 2)  # duplicates and collinear points
        if i % 7 == 0:
            pts[:, 1] = pts[0, 1]  # all on a line
        if i % 11 == 0:
            pts = (np.round(pts * 1e9) + 0.5) / 1e9  # ties at the rounding digit
        p = rng.normal(size=2) * 0.06
        np.testing.assert_array_equal(convex_hull_2d(pts), _reference_hull(pts))
        assert support_margin(p, pts) == pytest.approx(_reference_margin(p, pts), abs=1e-15)


def test_zmp_of_many_samples_equals_one_at_a_time() -> None:
    rng = np.random.default_rng(3)
    m = rng.uniform(0.1, 1.0, 21)
    p, a = rng.normal(size=(40, 21, 3)), rng.normal(size=(40, 21, 3))
    many = balance.zmp_point_mass_many(m, p, a)
    one = np.array([zmp_point_mass(m, p[i], a[i]) for i in range(40)])
    np.testing.assert_allclose(many, one, rtol=0, atol=1e-12)
    a[:, :, 2] = -balance.GRAVITY_M_S2  # free fall
    assert np.isnan(balance.zmp_point_mass_many(m, p, a)).all()
