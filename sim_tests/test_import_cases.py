"""Issue 38: the robot files people really have import (ROS packages, xacro, CAD quirks, fixed
links, scene MJCF, other axes, limits), each on a synthetic file built for it and, where
../shared/robots has one, on the real file."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from robot_rise.bench.import_cases import CASES, SERVO, humanoid_urdf, write_box_stl, write_case
from robot_rise.errors import ConfigError
from robot_rise.model import compose, load_robot, model_index
from robot_rise.robot_import import import_robot, read_model

SHARED = Path(__file__).resolve().parents[2] / "shared" / "robots"


def _import(case, out: Path, **kwargs):  # type: ignore[no-untyped-def]
    return import_robot(case.model, out, servos=case.servos, servo_models=None if case.servos else {"*": SERVO}, package_paths=case.package_paths, **kwargs)


@pytest.mark.parametrize("name", list(CASES))
def test_each_feature_of_published_files_imports_keeping_mass_and_collision_geoms(name: str, tmp_path: Path) -> None:
    case = write_case(name, tmp_path / "src")
    result = _import(case, tmp_path / "robot")
    for expected in case.expect_notes:
        assert any(expected in n for n in result.notes), (expected, result.notes)
    assert abs(result.mass_kg - result.declared_mass_kg) <= 0.01 * result.declared_mass_kg
    assert result.collision_geoms == result.declared_collision_geoms >= 18
    robot = load_robot(result.directory)
    have = robot.roles.by_role()
    for side in ("left", "right"):
        for role in ("hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll", "shoulder_pitch", "shoulder_roll", "elbow"):
            assert f"{side}.{role}" in have, (name, side, role)
        assert have[f"{side}.knee"].joint == f"{side[0]}_knee"  # the left leg is the file's l_ leg
    assert "held" in result.stand and robot.stand_height_m > 0.25
    assert compose(robot, "flat").nu == robot.n_joints


def test_a_turned_root_frame_stands_as_the_unturned_file_does(tmp_path: Path) -> None:
    """The same body written in turned axes: the same roles, signs and standing height."""
    plain = _import(write_case("fixed_links", tmp_path / "a"), tmp_path / "plain")
    turned = _import(write_case("turned_frame", tmp_path / "b"), tmp_path / "turned")
    a, b = load_robot(plain.directory), load_robot(turned.directory)
    assert {(r.role, r.sign) for r in a.roles.joints} == {(r.role, r.sign) for r in b.roles.joints}
    assert a.stand_height_m == pytest.approx(b.stand_height_m, abs=0.003)
    assert b.root_body == "robot_rise_base"


def test_a_mesh_that_cannot_be_found_is_one_line_naming_the_uri_and_where_it_looked(tmp_path: Path) -> None:
    model = tmp_path / "pkg" / "urdf" / "robot.urdf"
    model.parent.mkdir(parents=True)
    model.write_text(humanoid_urdf(foot_mesh="package://no_such_pkg/meshes/foot.stl"))
    with pytest.raises(ConfigError) as e:
        import_robot(model, tmp_path / "out", servo_models={"*": SERVO}, package_paths=[tmp_path])
    msg = str(e.value)
    assert "\n" not in msg and "package://no_such_pkg/meshes/foot.stl" in msg
    assert f"{tmp_path}/no_such_pkg/meshes/foot.stl" in msg and "--package-path" in msg
    assert not (tmp_path / "out").exists()


def test_ros_package_path_finds_a_package_the_file_does_not_sit_in(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    case = write_case("package_path", tmp_path / "src")
    with pytest.raises(ConfigError, match="cannot find package://mini_meshes"):
        import_robot(case.model, tmp_path / "a", servo_models={"*": SERVO})
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(case.package_paths[0]))
    assert "held" in import_robot(case.model, tmp_path / "b", servo_models={"*": SERVO}).stand


def test_xacro_is_expanded_without_file_uris_reaching_mujoco(tmp_path: Path) -> None:
    case = write_case("xacro", tmp_path / "src")
    source = read_model(case.model)
    assert source.kind == "xacro" and "$(find" not in source.urdf_text
    assert all(Path(m.file).is_absolute() and Path(m.file).is_file() for m in source.spec.meshes)
    assert not any(m.file.startswith("file:") for m in source.spec.meshes)


def test_mujocos_reason_reaches_the_user_in_one_line_with_the_element(tmp_path: Path) -> None:
    """A collision mesh MuJoCo cannot hull: its message's first line (not its last) and the element."""
    mesh = tmp_path / "meshes" / "plate.stl"
    write_box_stl(mesh, (0.06, 0.035, 0.0), flat=True)
    model = tmp_path / "robot.urdf"
    model.write_text(humanoid_urdf(foot_mesh=str(mesh)))
    with pytest.raises(ConfigError) as e:
        import_robot(model, tmp_path / "out", servo_models={"*": SERVO})
    msg = str(e.value)
    assert "\n" not in msg and str(model) in msg
    assert "coplanar" in msg and "Element name" in msg


def test_a_servo_limit_a_rounding_outside_is_taken_further_is_refused(tmp_path: Path) -> None:
    case = write_case("limits", tmp_path / "src")
    result = _import(case, tmp_path / "ok")
    robot = load_robot(result.directory)
    hip = robot.joint_names.index("l_hip_flex")
    assert robot.servos[hip].lower == pytest.approx(-1.8, abs=1e-6)  # the servo map's -1.8015, the model's -1.8
    neck = robot.joint_names.index("neck_yaw")
    assert (robot.joint_lower[neck], robot.joint_upper[neck]) == pytest.approx((-1.2, 1.2))  # placeholder +-pi replaced
    text = case.servos.read_text().replace("min = -1.8015", "min = -1.8035")
    case.servos.write_text(text)
    with pytest.raises(ConfigError, match=r"l_hip_flex.*by more than a rounding \(2 mrad\)") as e:
        _import(case, tmp_path / "refused")
    assert "\n" not in str(e.value) and not (tmp_path / "refused").exists()


def test_dry_run_prints_every_inference_and_writes_nothing(tmp_path: Path) -> None:
    case = write_case("cad_urdf", tmp_path / "src")
    out = tmp_path / "robot"
    r = subprocess.run(
        [sys.executable, "-m", "robot_rise", "robot", "import", str(case.model), "--out", str(out), "--servo-model", SERVO, "--dry-run"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "triangle inequality" in r.stdout and "mass floor" in r.stdout and "standing posture" in r.stdout
    assert "dry run" in r.stdout and not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


def test_the_stand_is_taken_from_a_posture_file_and_a_missing_one_is_one_line(tmp_path: Path) -> None:
    case = write_case("fixed_links", tmp_path / "src")
    with pytest.raises(ConfigError, match="--stand nope.json: no such posture file"):
        _import(case, tmp_path / "a", stand="nope.json")
    bend = {f"{s}_{j}": v for s in "lr" for j, v in (("hip_flex", -0.3), ("knee", 0.6), ("ankle_pitch", -0.3))}
    stand = tmp_path / "stand.json"
    stand.write_text(json.dumps({"format": "robot-rise/posture@1", "robot": "mini", "root_pos": [0, 0, 0.3], "root_quat": [1, 0, 0, 0], "joints": bend}))
    result = _import(case, tmp_path / "b", stand=stand)
    assert result.stand.startswith(f"standing posture: --stand {stand}")
    robot = load_robot(result.directory)
    assert robot.stand_qpos[7 + robot.joint_names.index("l_knee")] == pytest.approx(0.6)


def test_no_stand_says_what_was_tried_and_how_to_give_one(tmp_path: Path) -> None:
    """Feet too small to stand on: every candidate's reason, then the way out."""
    model = tmp_path / "stilts.urdf"
    model.write_text(humanoid_urdf().replace('<box size="0.12 0.07 0.01"/>', '<sphere radius="0.004"/>'))
    with pytest.raises(ConfigError) as e:
        import_robot(model, tmp_path / "out", servo_models={"*": SERVO})
    assert "tried knees 40 deg" in str(e.value) and "\n" not in str(e.value)
    assert "--stand POSTURE.json" in e.value.hint
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(not (SHARED / "poppy").is_dir(), reason="../shared/robots not beside the repository")
def test_poppy_as_solidworks_exported_it_imports(tmp_path: Path) -> None:
    """package://meshes with the package name lost, .URDF and .STL in upper case, names whose case
    differs from the disk, no floating joint, axes with y backward, a 5-joint spine, CAD meshes
    drawn into each other, mirrored knees that disagree, MX-28 knees that lock to stand."""
    result = import_robot(SHARED / "poppy/robots/Poppy_Humanoid.URDF", tmp_path / "poppy", servos=SHARED / "poppy/poppy_servos.toml")
    notes = "\n".join(result.notes)
    assert "differ in case" in notes and "free joint added" in notes and "forward is its -y" in notes
    assert "spine: 5 joints" in notes and "collision excluded between" in notes
    assert "left.knee and right.knee disagree" in notes
    robot = load_robot(result.directory)
    assert robot.name == "poppy" and set(robot.roles.missing_roles()) == {"left.ankle_roll", "right.ankle_roll"}
    assert abs(result.mass_kg - result.declared_mass_kg) < 0.01 * result.declared_mass_kg and result.collision_geoms == 26


@pytest.mark.skipif(not (SHARED / "wolfgang_ros").is_dir(), reason="../shared/robots not beside the repository")
def test_wolfgang_as_its_ros_package_publishes_it_imports(tmp_path: Path) -> None:
    result = import_robot(
        SHARED / "wolfgang_ros/wolfgang_description/urdf/robot.urdf", tmp_path / "w", servos=SHARED / "wolfgang_ros/servos.toml"
    )
    notes = "\n".join(result.notes)
    assert "taken as the model's: RShoulderPitch [-3.1415, 3.1415] -> [-3.14000, 3.14000]" in notes
    assert "base_link" in notes and "sole tilted 15 deg" in notes
    robot = load_robot(result.directory)
    assert robot.name == "wolfgang_robot" and not robot.roles.missing_roles()
    assert result.mass_kg == pytest.approx(6.1167, abs=1e-3) and result.collision_geoms == result.declared_collision_geoms
    # its soles lie flat where it stands (the file's zero pose tilts them 15 deg)
    m = compose(robot, None, with_actuators=False)
    d = mujoco.MjData(m)
    idx = model_index(m, robot)
    d.qpos[idx.qpos_root] = robot.stand_qpos[:7]
    d.qpos[idx.qpos_joints] = robot.stand_qpos[7:]
    mujoco.mj_kinematics(m, d)
    for site in robot.sole_sites:
        assert d.site(site).xmat.reshape(3, 3)[:, 2] @ [0, 0, 1] > np.cos(np.radians(3))


def test_a_four_bar_knee_keeps_its_loop_closed_and_its_servos_on_the_driven_joints(tmp_path: Path) -> None:
    """The import keeps the connect constraints, the rods are passive (no servo, no role), the
    knee is the driven joint's role; in simulation the loop stays closed while the knee bends."""
    from robot_rise.linkage import close_loops, constraint_residual, linkage_of
    from robot_rise.posture import stand_posture
    from robot_rise.sim.player import Player
    from robot_rise.trajectory import Trajectory

    result = _import(write_case("four_bar_knee", tmp_path / "src"), tmp_path / "robot")
    robot = load_robot(result.directory)
    assert robot.passive_joints == ("l_knee_rocker", "l_knee_coupler", "r_knee_rocker", "r_knee_coupler")
    assert "l_knee_rocker" not in robot.joint_names and robot.roles.by_role()["left.knee"].joint == "l_knee"
    m = compose(robot, "flat")
    assert m.nu == robot.n_joints == 17 and m.neq == 2
    # the stand keyframe closes the loops
    d = mujoco.MjData(m)
    idx = model_index(m, robot)
    d.qpos[idx.qpos_root] = robot.stand_qpos[:7]
    d.qpos[idx.qpos_joints] = robot.stand_qpos[7:]
    assert close_loops(m, d, linkage_of(m, robot.passive_joints)) < 1e-6
    knee = d.qpos[idx.qpos_joints[robot.joint_names.index("l_knee")]]
    rod = d.qpos[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "l_knee_rocker")]]
    assert rod == pytest.approx(knee, abs=1e-4) and abs(rod) > 0.5  # a parallelogram: the rocker turns as the knee
    # bend the knees further on the servo model: the rods follow, the loop holds within 1 mm
    start = stand_posture(robot)
    q0 = start.joint_vector(robot.joint_names)
    q1 = q0.copy()
    for role, extra in (("left.knee", 0.4), ("right.knee", 0.4), ("left.hip_pitch", -0.2), ("right.hip_pitch", -0.2), ("left.ankle_pitch", -0.2), ("right.ankle_pitch", -0.2)):
        r = robot.roles.by_role()[role]
        q1[robot.joint_names.index(r.joint)] += r.sign * extra
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 1.0]), np.array([q0, q1]), start)
    player = Player(robot, "flat")
    player.play(tr, hold_s=0.5)
    pm, pd = player.model, player.data
    assert np.abs(constraint_residual(pm, pd, tuple(range(pm.neq)))).max() < 1e-3
    assert pm.nu == robot.n_joints  # servos on the driven joints only
    rod_after = pd.qpos[pm.jnt_qposadr[mujoco.mj_name2id(pm, mujoco.mjtObj.mjOBJ_JOINT, "l_knee_rocker")]]
    knee_after = pd.qpos[pm.jnt_qposadr[mujoco.mj_name2id(pm, mujoco.mjtObj.mjOBJ_JOINT, "l_knee")]]
    assert rod_after == pytest.approx(knee_after, abs=0.01) and abs(rod_after - rod) > 0.2


def test_coupled_joints_follow_their_drivers_in_simulation(tmp_path: Path) -> None:
    from robot_rise.linkage import constraint_residual
    from robot_rise.posture import stand_posture
    from robot_rise.sim.player import Player
    from robot_rise.trajectory import Trajectory

    result = _import(write_case("coupled_joints", tmp_path / "src"), tmp_path / "robot")
    robot = load_robot(result.directory)
    assert set(robot.passive_joints) == {"neck_yaw_upper", "l_wrist", "r_wrist"}
    start = stand_posture(robot)
    q0 = start.joint_vector(robot.joint_names)
    q1 = q0.copy()
    q1[robot.joint_names.index("neck_yaw")] += 0.6
    q1[robot.joint_names.index("l_elbow")] -= 0.8
    player = Player(robot, "flat")
    player.play(Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.8]), np.array([q0, q1]), start), hold_s=0.5)
    m, d = player.model, player.data
    assert m.neq == 3 and m.ntendon == 4  # the couplings and their tendons survive composition with the scene

    def q(name: str) -> float:
        return float(d.qpos[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)]])

    assert q("neck_yaw") == pytest.approx(q1[robot.joint_names.index("neck_yaw")], abs=0.05)
    assert q("neck_yaw_upper") == pytest.approx(0.5 * q("neck_yaw"), abs=0.01)
    assert q("l_wrist") == pytest.approx(0.3 * q("l_elbow"), abs=0.01) and abs(q("l_wrist")) > 0.15
    assert np.abs(constraint_residual(m, d, tuple(range(m.neq)))).max() < 1e-3


def test_a_servo_map_names_the_driven_joints_and_an_unmoved_joint_is_refused(tmp_path: Path) -> None:
    case = write_case("four_bar_knee", tmp_path / "src")
    spec = mujoco.MjSpec.from_file(str(case.model))
    driven = [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_HINGE and "_knee_" not in j.name]
    rows = "".join(
        f'\n[[servo]]\nid = {i + 1}\njoint = "{j.name}"\nmodel = "{SERVO}"\nmin = {j.range[0]}\nmax = {j.range[1]}\n' for i, j in enumerate(driven)
    )  # each joint's own range: the user's frame allows what the file says
    servos = tmp_path / "servos.toml"
    servos.write_text(f'format = "robot-rise/servos@1"\nrobot = "four_bar"\n{rows}')
    robot = load_robot(import_robot(case.model, tmp_path / "ok", servos=servos).directory)
    assert len(robot.passive_joints) == 4 and len(robot.servos) == len(driven)
    servos.write_text(servos.read_text().replace('joint = "neck_yaw"', 'joint = "neck_yaw_not"'))
    with pytest.raises(ConfigError):
        import_robot(case.model, tmp_path / "bad", servos=servos)
    fewer = "\n[[servo]]".join(servos.read_text().split("\n[[servo]]")[:-1]).replace('joint = "neck_yaw_not"', 'joint = "neck_yaw"')
    servos.write_text(fewer)  # the last driven joint without a servo: nothing moves it
    with pytest.raises(ConfigError, match="no servo in the servo map that no constraint moves") as e:
        import_robot(case.model, tmp_path / "bad2", servos=servos)
    assert "\n" not in str(e.value) and not (tmp_path / "bad2").exists()


def test_the_proof_judges_a_closed_linkage_robot_with_its_constraints_simulated(tmp_path: Path) -> None:
    """check proves a hold of the four-bar robot's stand: the servo model on the driven joints,
    the loops closed by the simulator."""
    from robot_rise.posture import stand_posture
    from robot_rise.trajectory import Trajectory, write_trajectory

    result = _import(write_case("four_bar_knee", tmp_path / "src"), tmp_path / "robot")
    robot = load_robot(result.directory)
    start = stand_posture(robot)
    q = start.joint_vector(robot.joint_names)
    t = np.arange(0.0, 0.5, 0.01)
    hold = tmp_path / "hold.json"
    write_trajectory(hold, Trajectory(robot.name, robot.joint_names, t, np.tile(q, (len(t), 1)), start))
    r = subprocess.run([sys.executable, "-m", "robot_rise", "check", str(hold), "--robot", str(result.directory), "--variants", "2"],
                       capture_output=True, text=True, timeout=600)  # fmt: skip
    assert r.returncode == 0 and "PROVEN" in r.stdout, r.stdout + r.stderr


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (("id = 1\n", "id = 300\n"), r"id must be a whole number in 0\.\.252 \(Dynamixel IDs\), not 300"),
        (("id = 2\n", "id = 1\n"), "id 1 appears twice"),
        (("min = -1.2\nmax = 1.2", "min = 1.2\nmax = -1.2"), "min 1.2 must be below max -1.2"),
        (("direction = 1\n", "direction = 2\n"), "direction must be 1 or -1, not 2"),
        (('model = "XL430-W250"', 'model = "XL999"'), "unknown servo model 'XL999'"),
    ],
)
def test_a_bad_servo_map_is_one_line_at_import_not_a_failed_stand(tmp_path: Path, edit: tuple[str, str], message: str) -> None:
    case = write_case("limits", tmp_path / "src")
    case.servos.write_text(case.servos.read_text().replace(*edit, 1))
    with pytest.raises(ConfigError, match=message) as e:
        _import(case, tmp_path / "out")
    assert "\n" not in str(e.value) and "standing posture" not in str(e.value)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("bad", ['lower="nan" upper="nan"', 'lower="1.0" upper="-1.0"'])
def test_a_joint_range_that_is_not_a_range_is_one_line_at_import(tmp_path: Path, bad: str) -> None:
    model = tmp_path / "bad_range.urdf"
    model.write_text(humanoid_urdf().replace('lower="-1.5" upper="1.5"', bad, 1))
    with pytest.raises(ConfigError, match="neck_yaw: range .* is not a range") as e:
        import_robot(model, tmp_path / "out", servo_models={"*": SERVO})
    assert "\n" not in str(e.value) and not (tmp_path / "out").exists()
