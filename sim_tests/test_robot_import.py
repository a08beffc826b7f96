"""Issue 15: importing robots as their teams published them (../shared/robots), joint roles, bad inputs."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from drivers import load_servo_map
from robot_rise.errors import ConfigError
from robot_rise.model import compose, load_robot, model_index
from robot_rise.posture import stand_posture
from robot_rise.robot_import import import_robot, infer_roles
from robot_rise.roles import ROLES, mirror_role_values

# the published robots (sim_tests/conftest.py: ``shared_robots``, ``imported``: each imported once per session)
PUBLISHED = ("bez1", "wolfgang")


@pytest.mark.parametrize("name", PUBLISHED)
def test_import_writes_a_robot_that_loads_composes_and_stands(imported, name: str) -> None:  # type: ignore[no-untyped-def]
    result, robot = imported[name]
    assert robot.name == name and robot.roles is not None
    assert (result.directory / "robot.xml").is_file() and (result.directory / "servos.toml").is_file()
    m = compose(robot, "flat")  # actuators are robot_rise's own, one per joint
    assert m.nu == robot.n_joints
    assert any("standing posture" in n and "held" in n for n in result.notes)
    # every leg role on both sides
    have = robot.roles.by_role()
    for side in ("left", "right"):
        for role in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll", "shoulder_pitch", "elbow"):
            assert f"{side}.{role}" in have, (name, side, role)


def test_bez1_has_no_shoulder_roll_and_says_so(imported) -> None:  # type: ignore[no-untyped-def]
    result, robot = imported["bez1"]
    assert set(robot.roles.missing_roles()) == {"left.shoulder_roll", "right.shoulder_roll"}
    assert any("no joint for" in n and "shoulder_roll" in n for n in result.notes)
    assert any("ctrlrange" in n for n in result.notes)  # ranges only on the actuators


def _fk(robot, roles: dict[str, float]) -> tuple[mujoco.MjModel, mujoco.MjData]:  # type: ignore[no-untyped-def]
    m = compose(robot, None, with_actuators=False)
    d = mujoco.MjData(m)
    idx = model_index(m, robot)
    d.qpos[idx.qpos_root] = [0, 0, 0, 1, 0, 0, 0]
    goals = robot.roles.joint_goals(roles)
    for i, j in enumerate(robot.joint_names):
        d.qpos[idx.qpos_joints[i]] = goals.get(j, 0.0 if robot.roles.joints[i].role == "extra" else robot.roles.joints[i].neutral_rad)
    mujoco.mj_kinematics(m, d)
    return m, d


def _sole(m: mujoco.MjModel, d: mujoco.MjData, robot, side: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    return d.site_xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, robot.sole_sites[side])].copy()


@pytest.mark.parametrize("name", ["op3", "wolfgang", "bez1"])
def test_a_role_means_the_same_movement_on_every_robot(imported, name: str) -> None:  # type: ignore[no-untyped-def]
    """Knee flexion moves the foot backward, hip roll moves it outward, hip yaw turns the toes out,
    and a symmetric role posture is a mirror-symmetric body (the signs of both sides agree)."""
    robot = load_robot() if name == "op3" else imported[name].robot
    m, d = _fk(robot, {})
    base = [_sole(m, d, robot, s) for s in (0, 1)]  # soles: left, right
    for side, k in (("left", 0), ("right", 1)):
        outward = 1.0 if side == "left" else -1.0
        m, d = _fk(robot, {f"{side}.knee": 0.8})
        assert _sole(m, d, robot, k)[0] < base[k][0] - 0.02, (name, side, "knee")
        m, d = _fk(robot, {f"{side}.hip_roll": 0.3})
        assert outward * (_sole(m, d, robot, k)[1] - base[k][1]) > 0.02, (name, side, "hip_roll")
        m, d = _fk(robot, {f"{side}.hip_pitch": -0.6})
        assert _sole(m, d, robot, k)[0] > base[k][0] + 0.02, (name, side, "hip_pitch: negative flexes forward")
    sym = {"left.hip_roll": 0.2, "left.hip_pitch": -0.5, "left.knee": 0.9, "left.ankle_roll": 0.1, "left.hip_yaw": 0.2, "left.shoulder_pitch": -0.7, "left.elbow": 0.6}
    m, d = _fk(robot, sym | mirror_role_values(sym))
    left, right = _sole(m, d, robot, 0), _sole(m, d, robot, 1)
    root_y = d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, robot.root_body)][1]
    assert left[0] == pytest.approx(right[0], abs=0.01) and left[2] == pytest.approx(right[2], abs=0.01)
    assert left[1] - root_y == pytest.approx(-(right[1] - root_y), abs=0.015)


def test_the_op3_roles_in_robot_toml_are_what_the_import_infers() -> None:
    robot = load_robot()
    m = compose(robot, None, with_actuators=False)
    root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, robot.root_body)
    inferred = infer_roles(m, m.qpos0.copy(), root).roles
    assert {j.joint: (j.role, j.sign, j.neutral_rad) for j in inferred.joints} == {
        j.joint: (j.role, j.sign, j.neutral_rad) for j in robot.roles.joints
    }
    assert not robot.roles.missing_roles()


def test_a_servo_map_gives_ids_models_and_limits(shared_robots, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path, _ = shared_robots["bez1"]
    spec = mujoco.MjSpec.from_file(str(path))
    joints = [j.name for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_HINGE]
    rows = "\n".join(
        f'[[servo]]\nid = {10 + i}\njoint = "{j}"\nmodel = "MX-28"\ndirection = {-1 if i % 2 else 1}\nzero_offset = 0.0\nmin = -1.0\nmax = 1.0\n'
        for i, j in enumerate(joints)
    )
    servos = tmp_path / "servos.toml"
    servos.write_text(f'format = "robot-rise/servos@1"\n\n{rows}')
    # knees' ctrlrange is [0, 2.793]: -1 is outside the range the model gives them... through the actuator only,
    # so the servo map (the user's hardware truth) sets it; the joints with a model range refuse it
    with pytest.raises(ConfigError, match="outside the model range"):
        import_robot(path, tmp_path / "bez1", servos=servos)
    assert not (tmp_path / "bez1").exists()
    spec_rows = "\n".join(
        f'[[servo]]\nid = {10 + i}\njoint = "{j}"\nmodel = "MX-28"\ndirection = 1\nzero_offset = 0.0\nmin = -0.5\nmax = 0.5\n' for i, j in enumerate(joints)
    )
    # the user's [bus] is their hardware too: baud rate and supply kept as given
    servos.write_text(f'format = "robot-rise/servos@1"\n\n[bus]\nbaud_rate = 3000000\nsupply_voltage_v = 11.1\n\n{spec_rows}')
    result = import_robot(path, tmp_path / "bez1", servos=servos)
    robot = load_robot(result.directory)
    assert [s.id for s in robot.servos][:3] == [10 + joints.index(j) for j in robot.joint_names[:3]]
    knee = robot.joint_names.index(robot.roles.by_role()["left.knee"].joint)
    assert robot.joint_lower[knee] == pytest.approx(-0.5) and robot.joint_upper[knee] == pytest.approx(0.5)
    assert robot.supply_voltage_v == 11.1
    assert load_servo_map(result.directory / "servos.toml").bus.baud_rate == 3_000_000
    # --supply-voltage overrides the map's; one no servo runs on is one line, and nothing is written
    again = import_robot(path, tmp_path / "bez1_4s", servos=servos, supply_voltage_v=14.8)
    assert load_robot(again.directory).supply_voltage_v == 14.8
    with pytest.raises(ConfigError, match=r"--supply-voltage must be a number of volts in 5..30, not 48") as e:
        import_robot(path, tmp_path / "bez1_48", servos=servos, supply_voltage_v=48.0)
    assert "\n" not in str(e.value) and not (tmp_path / "bez1_48").exists()


_NO_BASE = """<mujoco><worldbody><body name="torso" pos="0 0 1"><geom type="box" size=".1 .1 .1"/>
<body name="leg"><joint name="a" axis="0 1 0" range="-1 1"/><geom type="capsule" fromto="0 0 0 0 0 -.3" size=".02"/></body>
</body></worldbody></mujoco>"""
_ONE_LEG = """<mujoco><worldbody><body name="torso" pos="0 0 1"><freejoint/><geom type="box" size=".1 .1 .1"/>
<body name="leg"><joint name="a" axis="0 1 0" range="-1 1"/><geom type="capsule" fromto="0 0 0 0 0 -.3" size=".02"/></body>
</body></worldbody></mujoco>"""


@pytest.mark.parametrize(
    ("xml", "kwargs", "message"),
    [
        (_NO_BASE, {"servo_models": {"*": "XM430-W350"}}, "no floating base"),
        (_ONE_LEG, {"servo_models": {"*": "XM430-W350"}}, "no recognisable legs"),
        ("<mujoco><worldbody><body", {"servo_models": {"*": "XM430-W350"}}, "cannot load the model"),
    ],
)
def test_bad_models_fail_in_one_line_and_write_nothing(tmp_path: Path, xml: str, kwargs: dict, message: str) -> None:
    src = tmp_path / "model.xml"
    src.write_text(xml)
    with pytest.raises(ConfigError, match=message) as e:
        import_robot(src, tmp_path / "out", **kwargs)
    assert "\n" not in str(e.value)
    assert not (tmp_path / "out").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["model.xml"]  # no scratch directory left


def test_bad_servo_inputs_fail_in_one_line(shared_robots, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path, _ = shared_robots["wolfgang"]
    with pytest.raises(ConfigError, match="unknown servo model 'XM999'"):
        import_robot(path, tmp_path / "a", servo_models={"*": "XM999"})
    with pytest.raises(ConfigError, match="--servo-model names joints the model lacks: no_such_joint"):
        import_robot(path, tmp_path / "b", servo_models={"*": "MX-106", "no_such_joint": "MX-64"})
    servos = tmp_path / "s.toml"
    servos.write_text('format = "robot-rise/servos@1"\n[[servo]]\nid = 1\njoint = "tail"\nmodel = "MX-28"\nmin = -1\nmax = 1\n')
    with pytest.raises(ConfigError, match="names joints the model lacks: tail"):
        import_robot(path, tmp_path / "c", servos=servos)
    # a joint with no range anywhere (wolfgang's knees have only ctrlrange: drop the actuators)
    text = path.read_text()
    stripped = re.sub(r"<actuator>.*?</actuator>", "", text, flags=re.S)
    model = tmp_path / "wolfgang.xml"
    model.write_text(stripped)
    with pytest.raises(ConfigError, match=r"no joint limit known for .*knee"):
        import_robot(model, tmp_path / "d", servo_models={"*": "MX-106"})
    assert not any((tmp_path / n).exists() for n in "abcd")


def test_cli_import_prints_every_inference_and_exits_0(shared_robots, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path, _ = shared_robots["bez1"]
    out = tmp_path / "bez1"
    r = subprocess.run(
        [sys.executable, "-m", "robot_rise", "robot", "import", str(path), "--out", str(out), "--servo-model", "MX-28", "--servo-model", "head_yaw=XL430-W250"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "floating base" in r.stdout and "standing posture" in r.stdout and "roles this robot has no joint for" in r.stdout
    robot = load_robot(out)
    assert {s.joint: s.model for s in robot.servos}["head_yaw"] == "XL430-W250"
    again = subprocess.run([sys.executable, "-m", "robot_rise", "robot", "import", str(path), "--out", str(out), "--servo-model", "MX-28"], capture_output=True, text=True, timeout=300)
    assert again.returncode != 0 and again.stderr.count("\n") <= 2 and "exists" in again.stderr
    assert stand_posture(robot).robot == "bez1"


def test_no_joint_name_of_any_robot_appears_in_the_product_code(published_models) -> None:  # type: ignore[no-untyped-def]
    """Issue 15: joint roles, not joint names (the OP3's, and the two imported robots')."""
    names = set(load_robot().joint_names)
    for path, _ in published_models.values():
        m = mujoco.MjSpec.from_file(str(path)).compile()
        names |= {m.joint(j).name for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE}
    root = Path(__file__).resolve().parents[1]
    hits = []
    for f in [*(root / "robot_rise").rglob("*.py"), *(root / "drivers").rglob("*.py")]:
        text = f.read_text()
        hits += [f"{f.relative_to(root)}: {n}" for n in names if re.search(rf"\b{re.escape(n)}\b", text)]
    assert not hits
    assert all("." in r for r in ROLES)


@pytest.mark.slow
def test_an_imported_robot_goes_through_sample_check_report_and_the_twin(imported, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Issue 15: the commands take --robot DIR for an imported robot (the HTML report names it)."""
    from robot_rise.trajectory import Trajectory, write_trajectory

    result, robot = imported["bez1"]
    rd = str(result.directory)

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "robot_rise", *args], capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)

    r = run("sample", "--robot", rd, "--n", "1", "--kind", "left", "--seed", "3", "--out", str(tmp_path / "postures"))
    assert r.returncode == 0, r.stderr
    posture = next((tmp_path / "postures").glob("*.json"))
    assert '"robot": "bez1"' in posture.read_text().replace("  ", " ")
    start = stand_posture(robot)
    q = start.joint_vector(robot.joint_names)
    t = np.arange(0.0, 0.5, 0.01)
    hold = tmp_path / "hold.json"
    write_trajectory(hold, Trajectory(robot.name, robot.joint_names, t, np.tile(q, (len(t), 1)), start))
    r = run("check", str(hold), "--robot", rd, "--variants", "2")
    assert r.returncode == 0 and "PROVEN" in r.stdout, r.stdout + r.stderr
    r = run("report", str(hold), "--robot", rd, "--out", str(tmp_path / "rep"), "--no-video")
    assert r.returncode == 0, r.stderr
    assert "<h1>bez1" in (tmp_path / "rep" / "report.html").read_text()
    r = run("execute", str(hold), "--mock", "--twin", "--robot", rd, "--allow-unproven", "--yes")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "upright" in r.stdout and "safety-clamped cycles 0" in r.stdout
    # the servo catalog's MX-28 is the bus's MX-28(2.0): one turn of limits at most
    assert all(-3.1416 < s.lower < s.upper < 3.1416 for s in robot.servos)


_MINI_URDF = """<?xml version="1.0"?>
<robot name="mini">
  <link name="torso"><inertial><mass value="1.0"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.1"/><geometry><box size="0.1 0.16 0.2"/></geometry></collision></link>
  <link name="head"><inertial><mass value="0.1"/><inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.04"/><geometry><sphere radius="0.04"/></geometry></collision></link>
  <joint name="neck_yaw" type="revolute"><parent link="torso"/><child link="head"/><origin xyz="0 0 0.22"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="3" velocity="5"/></joint>
  
  <link name="a_thigh"><inertial><origin xyz="0 0 -0.06"/><mass value="0.2"/><inertia ixx="0.001" iyy="0.001" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.06"/><geometry><cylinder radius="0.02" length="0.1"/></geometry></collision></link>
  <link name="a_hipr"><inertial><mass value="0.05"/><inertia ixx="0.0001" iyy="0.0001" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="a_shank"><inertial><origin xyz="0 0 -0.06"/><mass value="0.15"/><inertia ixx="0.001" iyy="0.001" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.06"/><geometry><cylinder radius="0.018" length="0.1"/></geometry></collision></link>
  <link name="a_foot"><inertial><origin xyz="0.01 0 -0.02"/><mass value="0.1"/><inertia ixx="0.0002" iyy="0.0002" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0.015 0 -0.025"/><geometry><box size="0.12 0.07 0.01"/></geometry></collision></link>
  <link name="a_upperarm"><inertial><origin xyz="0 0 -0.05"/><mass value="0.08"/><inertia ixx="0.0003" iyy="0.0003" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.05"/><geometry><cylinder radius="0.015" length="0.08"/></geometry></collision></link>
  <link name="a_forearm"><inertial><origin xyz="0 0 -0.05"/><mass value="0.06"/><inertia ixx="0.0003" iyy="0.0003" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.05"/><geometry><cylinder radius="0.013" length="0.08"/></geometry></collision></link>
  <joint name="a_hr" type="revolute"><parent link="torso"/><child link="a_hipr"/><origin xyz="0 0.045 -0.02"/><axis xyz="1 0 0"/><limit lower="-0.5" upper="0.5" effort="3" velocity="5"/></joint>
  <joint name="a_hp" type="revolute"><parent link="a_hipr"/><child link="a_thigh"/><origin xyz="0 0 0"/><axis xyz="0 1 0"/><limit lower="-2.0" upper="0.5" effort="3" velocity="5"/></joint>
  <joint name="a_kn" type="revolute"><parent link="a_thigh"/><child link="a_shank"/><origin xyz="0 0 -0.12"/><axis xyz="0 1 0"/><limit lower="0" upper="2.5" effort="3" velocity="5"/></joint>
  <joint name="a_ap" type="revolute"><parent link="a_shank"/><child link="a_foot"/><origin xyz="0 0 -0.12"/><axis xyz="0 1 0"/><limit lower="-1.2" upper="1.2" effort="3" velocity="5"/></joint>
  <joint name="a_sp" type="revolute"><parent link="torso"/><child link="a_upperarm"/><origin xyz="0 0.1 0.18"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="3" velocity="5"/></joint>
  <joint name="a_el" type="revolute"><parent link="a_upperarm"/><child link="a_forearm"/><origin xyz="0 0 -0.1"/><axis xyz="0 1 0"/><limit lower="-2.5" upper="0" effort="3" velocity="5"/></joint>

  <link name="b_thigh"><inertial><origin xyz="0 0 -0.06"/><mass value="0.2"/><inertia ixx="0.001" iyy="0.001" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.06"/><geometry><cylinder radius="0.02" length="0.1"/></geometry></collision></link>
  <link name="b_hipr"><inertial><mass value="0.05"/><inertia ixx="0.0001" iyy="0.0001" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="b_shank"><inertial><origin xyz="0 0 -0.06"/><mass value="0.15"/><inertia ixx="0.001" iyy="0.001" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.06"/><geometry><cylinder radius="0.018" length="0.1"/></geometry></collision></link>
  <link name="b_foot"><inertial><origin xyz="0.01 0 -0.02"/><mass value="0.1"/><inertia ixx="0.0002" iyy="0.0002" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0.015 0 -0.025"/><geometry><box size="0.12 0.07 0.01"/></geometry></collision></link>
  <link name="b_upperarm"><inertial><origin xyz="0 0 -0.05"/><mass value="0.08"/><inertia ixx="0.0003" iyy="0.0003" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.05"/><geometry><cylinder radius="0.015" length="0.08"/></geometry></collision></link>
  <link name="b_forearm"><inertial><origin xyz="0 0 -0.05"/><mass value="0.06"/><inertia ixx="0.0003" iyy="0.0003" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.05"/><geometry><cylinder radius="0.013" length="0.08"/></geometry></collision></link>
  <joint name="b_hr" type="revolute"><parent link="torso"/><child link="b_hipr"/><origin xyz="0 -0.045 -0.02"/><axis xyz="1 0 0"/><limit lower="-0.5" upper="0.5" effort="3" velocity="5"/></joint>
  <joint name="b_hp" type="revolute"><parent link="b_hipr"/><child link="b_thigh"/><origin xyz="0 0 0"/><axis xyz="0 1 0"/><limit lower="-2.0" upper="0.5" effort="3" velocity="5"/></joint>
  <joint name="b_kn" type="revolute"><parent link="b_thigh"/><child link="b_shank"/><origin xyz="0 0 -0.12"/><axis xyz="0 1 0"/><limit lower="0" upper="2.5" effort="3" velocity="5"/></joint>
  <joint name="b_ap" type="revolute"><parent link="b_shank"/><child link="b_foot"/><origin xyz="0 0 -0.12"/><axis xyz="0 1 0"/><limit lower="-1.2" upper="1.2" effort="3" velocity="5"/></joint>
  <joint name="b_sp" type="revolute"><parent link="torso"/><child link="b_upperarm"/><origin xyz="0 -0.1 0.18"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="3" velocity="5"/></joint>
  <joint name="b_el" type="revolute"><parent link="b_upperarm"/><child link="b_forearm"/><origin xyz="0 0 -0.1"/><axis xyz="0 1 0"/><limit lower="-2.5" upper="0" effort="3" velocity="5"/></joint>

</robot>
"""


def test_a_urdf_robot_imports_with_a_floating_base_added(tmp_path: Path) -> None:
    """A robot we never saw, as URDF (no floating joint in URDF): legs with pitch joints only,
    pitch-only arms, a head with pan only."""
    src = tmp_path / "mini.urdf"
    src.write_text(_MINI_URDF)
    result = import_robot(src, tmp_path / "mini", servo_models={"*": "XL430-W250"})
    robot = load_robot(result.directory)
    assert any("free joint added" in n for n in result.notes)
    have = robot.roles.by_role()
    assert {"left.hip_roll", "left.hip_pitch", "left.knee", "left.ankle_pitch", "left.shoulder_pitch", "left.elbow", "head.pan"} <= set(have)
    assert "left.ankle_roll" in robot.roles.missing_roles()
    assert have["left.knee"].joint == "a_kn" and have["right.knee"].joint == "b_kn"  # +y is left
    assert robot.stand_height_m > 0.2


def test_xacro_needs_xacrodoc_and_says_so(tmp_path: Path) -> None:
    import importlib.util

    src = tmp_path / "robot.urdf.xacro"
    src.write_text('<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="x"/>')
    if importlib.util.find_spec("xacrodoc") is None:
        with pytest.raises(ConfigError, match="needs the xacrodoc package"):
            import_robot(src, tmp_path / "x", servo_models={"*": "XL430-W250"})
    else:
        with pytest.raises(ConfigError):  # expands, then has no hinge joints
            import_robot(src, tmp_path / "x", servo_models={"*": "XL430-W250"})
    assert not (tmp_path / "x").exists()
