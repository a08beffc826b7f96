"""Tests of robot_rise.geometry: collision filtering and shapes exactly as MuJoCo defines them."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from robot_rise.geometry import collision_mask, colliding_geoms, geom_radius_m, hull_vertices, lowest_point_z, mesh_hulls

BEZ1 = Path(__file__).resolve().parents[2] / "shared" / "robots" / "bez1" / "bez1.xml"

# Every geom sits at the origin, so every pair MuJoCo does not filter touches: its contacts are
# exactly the pairs the model lets collide.
FILTERS = """
<mujoco>
  {option}
  <worldbody>
    <geom name="ground" type="plane" size="1 1 0.1"/>
    <geom name="rock" type="box" size="0.1 0.1 0.1"/>
    <body name="A"><freejoint/>
      <geom name="a1" type="sphere" size="0.1"/>
      <geom name="a2" type="sphere" size="0.1" contype="2" conaffinity="0"/>
      <geom name="visual" type="sphere" size="0.1" contype="0" conaffinity="0"/>
      <body name="B"><joint type="hinge"/><geom name="b1" type="sphere" size="0.1"/>
        <body name="C"><joint type="hinge"/><geom name="c1" type="sphere" size="0.1" conaffinity="3"/></body>
      </body>
      <body name="D"><geom name="d1" type="sphere" size="0.1"/></body>
      <body name="E"><joint type="hinge"/><geom name="e1" type="sphere" size="0.1" contype="5" conaffinity="4"/></body>
      <body name="F"><joint type="hinge"/><geom name="f1" type="capsule" size="0.05 0.1"/></body>
      <body name="G"><joint type="hinge"/><geom name="g1" type="sphere" size="0.1" contype="2" conaffinity="2"/></body>
    </body>
  </worldbody>
  <contact><exclude body1="C" body2="F"/><pair geom1="visual" geom2="ground"/></contact>
</mujoco>
"""


def _model(option: str = "") -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(FILTERS.format(option=option))


def _contact_pairs(m: mujoco.MjModel) -> set[tuple[int, int]]:
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return {tuple(sorted(int(g) for g in d.contact.geom[k])) for k in range(d.ncon)}


def _mask_pairs(mask: np.ndarray) -> set[tuple[int, int]]:
    i, j = np.nonzero(np.triu(mask, 1))
    return set(zip(i.tolist(), j.tolist()))


@pytest.mark.parametrize("option", ["", '<option><flag filterparent="disable"/></option>'])
def test_that_the_collision_mask_is_exactly_the_pairs_mujoco_collides(option):
    m = _model(option)
    mask = collision_mask(m)
    assert np.array_equal(mask, mask.T) and not mask.diagonal().any()
    assert _mask_pairs(mask) == _contact_pairs(m)


def test_that_excludes_bitmasks_welds_parents_and_explicit_pairs_decide_a_pair():
    m = _model()
    mask = collision_mask(m)

    def can(a: str, b: str) -> bool:
        return bool(mask[m.geom(a).id, m.geom(b).id])

    assert not can("c1", "f1")  # <contact><exclude>
    assert not can("a1", "b1") and can("a1", "c1")  # parent, grandparent
    assert not can("a1", "d1") and not can("b1", "d1")  # D is welded to A: same body, and B's parent
    assert not can("g1", "b1") and can("g1", "c1")  # contype 2 meets conaffinity 3, not 1
    assert can("e1", "c1") and can("e1", "b1")  # contype 5 meets conaffinity 3 and 1
    assert not can("visual", "a1") and can("visual", "ground")  # an explicit pair collides anyway
    assert not can("ground", "rock")  # both on the world body


def test_that_a_model_with_contacts_disabled_has_no_pair():
    m = _model('<option><flag contact="disable"/></option>')
    assert not collision_mask(m).any()


def test_that_colliding_geoms_drops_visual_geoms_and_filters_by_partner():
    m = _model()
    mask = collision_mask(m)
    robot = np.array([g for g in range(m.ngeom) if m.geom_bodyid[g] != 0])
    names = {m.geom(int(g)).name for g in colliding_geoms(mask, robot)}
    assert "visual" in names  # it has an explicit pair with the ground
    without_pairs = collision_mask(mujoco.MjModel.from_xml_string(FILTERS.format(option="").replace('<pair geom1="visual" geom2="ground"/>', "")))
    assert "visual" not in {m.geom(int(g)).name for g in colliding_geoms(without_pairs, robot)}
    with_g = colliding_geoms(mask, robot, np.array([m.geom("g1").id]))
    assert [m.geom(int(g)).name for g in with_g] == ["c1"]


CUBE = """
<mujoco>
  <compiler angle="radian"/>
  <asset>
    <mesh name="cube" vertex="-1 -1 -1  1 -1 -1  -1 1 -1  1 1 -1  -1 -1 1  1 -1 1  -1 1 1  1 1 1  0.2 0.1 0" scale="0.03 0.02 0.05"/>
  </asset>
  <worldbody>
    <geom name="ground" type="plane" size="2 2 0.1" margin="1"/>
    <body name="thing" pos="0 0 0.5"><freejoint/>
      <geom name="mesh" type="mesh" mesh="cube" pos="0.01 0.02 0.03" euler="0.3 0.2 0.1"/>
      <geom name="cyl" type="cylinder" size="0.02 0.05" pos="0.1 0 0" euler="0.5 0 0"/>
      <geom name="ell" type="ellipsoid" size="0.03 0.02 0.05" pos="-0.1 0 0"/>
      <geom name="cap" type="capsule" size="0.02 0.04" pos="0 0.1 0" euler="0 0.7 0"/>
      <geom name="box" type="box" size="0.02 0.03 0.04" pos="0 -0.1 0" euler="0.2 0.4 0"/>
      <geom name="ball" type="sphere" size="0.025" pos="0 0 0.1"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_that_the_hull_of_an_inline_cube_is_its_eight_corners_placed_by_the_geom_frame():
    m = mujoco.MjModel.from_xml_string(CUBE)
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    g = m.geom("mesh").id
    v = hull_vertices(m, g)
    assert len(v) == 8  # the vertex inside the cube is not on its hull
    world = d.geom_xpos[g] + v @ d.geom_xmat[g].reshape(3, 3).T
    rot = np.zeros(9)
    mujoco.mju_euler2Quat(quat := np.zeros(4), np.array([0.3, 0.2, 0.1]), "xyz")
    mujoco.mju_quat2Mat(rot, quat)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    corners = np.array([0.01, 0.02, 0.53]) + (signs * [0.03, 0.02, 0.05]) @ rot.reshape(3, 3).T
    assert np.allclose(np.sort(world.round(9), axis=0), np.sort(corners.round(9), axis=0), atol=1e-6)
    assert geom_radius_m(m, m.geom("mesh").id) == pytest.approx(np.linalg.norm([0.03, 0.02, 0.05]), abs=1e-6)
    assert geom_radius_m(m, m.geom("ball").id) == pytest.approx(0.025)
    with pytest.raises(ValueError, match="not a mesh"):
        hull_vertices(m, m.geom("cyl").id)


def _ground_depth(m: mujoco.MjModel, d: mujoco.MjData, geom: int) -> float:
    """MuJoCo's deepest contact distance between one geom and the ground plane (its margin: 1 m)."""
    mujoco.mj_collision(m, d)
    dist = [d.contact.dist[k] for k in range(d.ncon) if set(d.contact.geom[k].tolist()) == {0, geom}]
    return float(min(dist))


def test_that_the_lowest_point_of_every_geom_type_is_where_mujoco_meets_the_ground():
    m = mujoco.MjModel.from_xml_string(CUBE)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(4)
    geoms = np.arange(1, m.ngeom)
    hulls = mesh_hulls(m, geoms)
    for _ in range(20):
        quat = rng.normal(size=4)
        d.qpos[:] = [0.0, 0.0, 0.5, *(quat / np.linalg.norm(quat))]
        mujoco.mj_kinematics(m, d)
        for g in geoms:
            assert lowest_point_z(m, d, np.array([g]), hulls) == pytest.approx(_ground_depth(m, d, int(g)), abs=1e-9), m.geom(int(g)).name
        assert lowest_point_z(m, d, geoms) == pytest.approx(min(lowest_point_z(m, d, np.array([g])) for g in geoms))


@pytest.mark.skipif(not BEZ1.is_file(), reason="../shared/robots/bez1 is not there")
def test_that_bez1s_lowest_point_is_its_hulls_where_mujoco_meets_the_ground_not_its_bounding_spheres():
    spec = mujoco.MjSpec.from_file(str(BEZ1))
    ground = spec.worldbody.add_geom()
    ground.type = mujoco.mjtGeom.mjGEOM_PLANE
    ground.size = [4, 4, 0.05]
    ground.margin = 1.0
    m = spec.compile()
    d = mujoco.MjData(m)
    robot = np.arange(1, m.ngeom)
    assert all(m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH for g in robot)
    hulls = mesh_hulls(m, robot)
    rng = np.random.default_rng(0)
    sphere_gap = []
    for _ in range(10):
        d.qpos[:] = m.qpos0
        quat = rng.normal(size=4)
        d.qpos[2:7] = [0.5, *(quat / np.linalg.norm(quat))]
        d.qpos[7:] = rng.uniform(-0.8, 0.8, m.nq - 7)
        mujoco.mj_kinematics(m, d)
        low = lowest_point_z(m, d, robot, hulls)
        assert low == pytest.approx(min(_ground_depth(m, d, int(g)) for g in robot), abs=1e-9)
        sphere_gap.append(low - min(d.geom_xpos[g, 2] - m.geom_rbound[g] for g in robot))
    assert min(sphere_gap) > 0.0  # the old bounding spheres reach lower than the robot does
