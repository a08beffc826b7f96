"""Tests of robot_rise.planning.energy.capsules: exact segment distances and the robot as capsules."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.spatial import ConvexHull

from robot_rise.geometry import hull_vertices
from robot_rise.model import compose, load_robot, model_index
from robot_rise.planning.energy import capsules, hull_fit
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


# --- meshes: capsules enclosing MuJoCo's convex hull --------------------------------------------


def _hulls() -> dict[str, np.ndarray]:
    """Convex point sets of the shapes robot brackets have: a box, a rod, a plate, a blob."""
    rng = np.random.default_rng(7)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    blob = rng.normal(size=(300, 3)) * [0.03, 0.02, 0.015]
    return {
        "box": corners * [0.07, 0.05, 0.09],
        "rod": corners * [0.01, 0.012, 0.06],
        "plate": corners * [0.045, 0.035, 0.003],
        "blob": blob[ConvexHull(blob).vertices],
    }


def _outside_m(points: np.ndarray, fit: hull_fit.HullFit) -> np.ndarray:
    """How far each point lies outside every capsule of a fit [m] (<= 0: inside one), shape (n,)."""
    ab = fit.b - fit.a
    length2 = np.einsum("kj,kj->k", ab, ab)
    s = np.einsum("nkj,kj->nk", points[:, None, :] - fit.a[None], ab) / np.where(length2 > 0, length2, 1.0)
    nearest = fit.a[None] + np.clip(s, 0.0, 1.0)[..., None] * ab[None]
    return (np.linalg.norm(points[:, None, :] - nearest, axis=2) - fit.radius[None]).min(axis=1)


@pytest.mark.parametrize("shape", ["box", "rod", "plate", "blob"])
def test_that_hull_capsules_contain_every_hull_vertex(shape):
    hull = _hulls()[shape]
    fit = hull_fit.fit_hull_capsules(hull)
    assert 1 <= len(fit) <= hull_fit.MAX_CAPSULES_PER_MESH
    assert _outside_m(hull, fit).max() <= 1e-12


@pytest.mark.parametrize("shape", ["box", "rod", "plate", "blob"])
def test_that_the_reported_fit_error_is_how_far_the_capsules_reach_beyond_the_hull(shape):
    hull = _hulls()[shape]
    fit = hull_fit.fit_hull_capsules(hull)
    n = np.random.default_rng(11).normal(size=(200_000, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    # for convex sets, max over the capsule of the distance to the hull = max_n h_capsule(n) - h_hull(n)
    beyond = (np.maximum(n @ fit.a.T, n @ fit.b.T) + fit.radius - (n @ hull.T).max(axis=1)[:, None]).max()
    assert beyond <= fit.error_m + 1e-5
    assert beyond >= fit.error_m - 5e-4


def test_that_a_capsule_shaped_hull_is_fitted_by_one_tight_capsule():
    rng = np.random.default_rng(2)
    u = rng.normal(size=(4000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    surface = 0.02 * u + np.where(u[:, 2:] > 0, 1.0, -1.0) * [0.0, 0.0, 0.04]  # radius 20 mm, segment 80 mm
    hull = surface[ConvexHull(surface).vertices]
    fit = hull_fit.fit_hull_capsules(hull)
    assert len(fit) == 1 and fit.error_m < 0.001
    assert fit.radius[0] == pytest.approx(0.02, abs=0.001)


def test_that_more_capsules_reach_less_far_beyond_a_box():
    hull = _hulls()["box"]
    one = hull_fit.fit_hull_capsules(hull, max_error_m=0.0, max_capsules=1)
    eight = hull_fit.fit_hull_capsules(hull, max_error_m=0.0, max_capsules=8)
    assert len(one) == 1 and 1 < len(eight) <= 8
    assert eight.error_m < 0.8 * one.error_m
    with pytest.raises(ValueError, match="max_capsules"):
        hull_fit.fit_hull_capsules(hull, max_capsules=0)


FILTERED = """
<mujoco>
  <compiler angle="radian"/>
  <asset><mesh name="block" vertex="-1 -1 -1  1 -1 -1  -1 1 -1  1 1 -1  -1 -1 1  1 -1 1  -1 1 1  1 1 1" scale="0.02 0.03 0.06"/></asset>
  <worldbody>
    <geom name="ground" type="plane" size="2 2 0.1"/>
    <body name="trunk" pos="0 0 0.5"><freejoint/>
      <geom name="trunk" type="mesh" mesh="block" euler="0.2 0.1 0.3"/>
      <geom name="shell" type="sphere" size="0.2" contype="0" conaffinity="0"/>
      <body name="left" pos="0 0.1 -0.1"><joint name="left" axis="1 0 0"/>
        <geom name="left" type="capsule" size="0.02 0.05"/>
        <body name="left_foot" pos="0 0 -0.1"><joint name="left_foot" axis="0 1 0"/><geom name="left_foot" type="mesh" mesh="block"/></body>
      </body>
      <body name="right" pos="0 -0.1 -0.1"><joint name="right" axis="1 0 0"/>
        <geom name="right" type="capsule" size="0.02 0.05"/>
        <body name="right_foot" pos="0 0 -0.1"><joint name="right_foot" axis="0 1 0"/><geom name="right_foot" type="mesh" mesh="block"/></body>
      </body>
    </body>
  </worldbody>
  <contact><exclude body1="left_foot" body2="right_foot"/></contact>
</mujoco>
"""


@pytest.fixture(scope="module")
def filtered():
    m = mujoco.MjModel.from_xml_string(FILTERED)
    robot = SimpleNamespace(root_body="trunk", joint_names=("left", "left_foot", "right", "right_foot"))
    return m, model_index(m, robot)


def test_that_mesh_geoms_become_capsules_that_contain_their_hull_in_the_world(filtered):
    m, idx = filtered
    caps = robot_capsules(m, idx)
    d = mujoco.MjData(m)
    d.qpos[:] = [0.1, 0.2, 0.4, 0.9, 0.1, 0.3, 0.2, 0.5, -0.4, -0.3, 0.6]
    mujoco.mj_kinematics(m, d)
    a, b = caps.world_endpoints(d)
    for name in ("trunk", "left_foot", "right_foot"):
        g = m.geom(name).id
        k = caps.geom == g
        assert k.sum() >= 1
        world = d.geom_xpos[g] + hull_vertices(m, g) @ d.geom_xmat[g].reshape(3, 3).T
        fit = hull_fit.HullFit(a[k], b[k], caps.radius[k], 0.0)
        assert _outside_m(world, fit).max() <= 1e-9


def test_that_visual_geoms_are_no_capsules_and_model_filtered_links_are_no_pair(filtered):
    m, idx = filtered
    caps = robot_capsules(m, idx)
    assert "shell" not in caps.names  # contype = conaffinity = 0: it collides with nothing
    i, j = non_adjacent_pairs(m, caps)
    pairs = {frozenset((caps.names[a], caps.names[b])) for a, b in zip(i, j)}
    assert frozenset(("left_foot", "right_foot")) not in pairs  # <contact><exclude>
    assert frozenset(("left", "right_foot")) in pairs
    assert frozenset(("trunk", "left_foot")) in pairs


def test_that_each_mesh_fit_is_reported_with_its_error(filtered):
    m, idx = filtered
    fits = hull_fit.mesh_fits(m, idx.robot_geoms)
    assert [f.name for f in fits] == ["trunk", "left_foot", "right_foot"]
    for f in fits:
        assert f.capsules >= 1 and f.error_m >= 0.0 and f.within_bound == (f.error_m <= hull_fit.MESH_CAPSULE_MAX_ERROR_M)
        assert f.name in f.describe() and "mm beyond the hull" in f.describe()


BEZ1 = Path(__file__).resolve().parents[2] / "shared" / "robots" / "bez1" / "bez1.xml"


@pytest.mark.skipif(not BEZ1.is_file(), reason="../shared/robots/bez1 is not there")
def test_that_bez1s_capsules_overlap_at_its_zero_pose_only_where_its_hulls_are_within_the_fit_error():
    m = mujoco.MjModel.from_xml_string(BEZ1.read_text().replace('meshdir="meshes/bez1/"', f'meshdir="{BEZ1.parent / "meshes" / "bez1"}/"'))
    hinges = tuple(m.joint(j).name for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE)
    idx = model_index(m, SimpleNamespace(root_body="torso_2023", joint_names=hinges))
    caps = robot_capsules(m, idx)
    fits = {f.geom: f for f in hull_fit.mesh_fits(m, idx.robot_geoms)}
    assert len(fits) == 19 and max(f.error_m for f in fits.values()) < 0.035
    i, j = non_adjacent_pairs(m, caps)
    bodies = {frozenset((m.body(int(caps.body[p])).name, m.body(int(caps.body[q])).name)) for p, q in zip(i, j)}
    assert frozenset(("left_hip_yaw", "left_hip_pitch")) not in bodies  # bez1.xml excludes it
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    a, b = caps.world_endpoints(d)
    gap = segment_distance(a[i], b[i], a[j], b[j]) - caps.radius[i] - caps.radius[j]
    fromto = np.zeros(6)
    for p, q in zip(i[gap < 0], j[gap < 0]):
        g1, g2 = int(caps.geom[p]), int(caps.geom[q])
        hull_gap = mujoco.mj_geomDistance(m, d, g1, g2, 1.0, fromto)
        assert hull_gap < fits[g1].error_m + fits[g2].error_m
