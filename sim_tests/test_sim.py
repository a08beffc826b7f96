"""The player: recording shapes, rates, servo torques within the envelope, contacts."""

from __future__ import annotations

import numpy as np
import pytest

import robot_rise.sim.player as sim
from robot_rise.errors import RobotRiseError
from robot_rise.authoring import settle
from robot_rise.model import load_robot
from robot_rise.sim.player import Player
from robot_rise.trajectory import Trajectory


@pytest.fixture(scope="module")
def robot():  # type: ignore[no-untyped-def]
    return load_robot()


def test_every_name_in_all_resolves() -> None:
    for name in sim.__all__:
        assert hasattr(sim, name), name


def test_recording_covers_the_trajectory_and_the_hold_at_the_record_rate(robot) -> None:  # type: ignore[no-untyped-def]
    start = settle(robot, "supine", robot.roles.joint_goals({"left.shoulder_roll": 0.25, "right.shoulder_roll": 0.25}))
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 1.0]), np.stack([q, q]), start)
    rec = Player(robot).play(tr, hold_s=0.5, record_hz=50)
    assert rec.t.shape == (75,)
    assert rec.t[-1] == pytest.approx(1.5)
    assert rec.q.shape == (75, robot.n_joints) and rec.root_pose.shape == (75, 7)
    assert np.all(np.diff(rec.t) > 0)


def test_a_lying_robot_touches_the_ground_with_more_than_its_feet(robot) -> None:  # type: ignore[no-untyped-def]
    start = settle(robot, "prone", robot.roles.joint_goals({"left.shoulder_roll": 0.25, "right.shoulder_roll": 0.25}))
    q = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.2]), np.stack([q, q]), start)
    rec = Player(robot).play(tr, hold_s=0.2)
    assert not rec.on_feet.any()
    assert np.all(np.isnan(rec.zmp_margin_m))
    assert rec.ground_contact[-1].any()


def _goal_jump(robot) -> Trajectory:  # type: ignore[no-untyped-def]
    """Lying supine, one shoulder's goal jumps 1.5 rad at once: the servo saturates."""
    start = settle(robot, "supine", robot.roles.joint_goals({"left.shoulder_roll": 0.25, "right.shoulder_roll": 0.25}))
    q = start.joint_vector(robot.joint_names)
    jump = q.copy()
    jump[robot.joint_index("l_sho_pitch")] -= 1.5
    return Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.002, 0.6]), np.stack([q, jump, jump]), start)


def test_servo_torques_never_exceed_the_envelope_even_for_a_goal_jump(robot) -> None:  # type: ignore[no-untyped-def]
    rec = Player(robot).play(_goal_jump(robot), hold_s=0.1)
    assert rec.peak_envelope_ratio == pytest.approx(1.0, abs=1e-6)  # saturated, never beyond
    assert np.all(rec.envelope_ratio <= 1.0 + 1e-9)
    assert np.all(np.abs(rec.torque_nm) <= 4.1 * (1 + np.abs(rec.qd) / 4.82) + 1e-6)


def test_a_play_over_the_torque_margin_stops_where_asked_and_one_within_it_plays_on(robot) -> None:  # type: ignore[no-untyped-def]
    tr = _goal_jump(robot)
    player = Player(robot)
    whole = player.play(tr, hold_s=0.3)
    stopped = player.play(tr, hold_s=0.3, stop_over=(0.305, 0.9))  # saturated at the jump: over 0.9 by then
    assert whole.stopped_s is None and stopped.stopped_s == pytest.approx(0.3)
    k = len(stopped.t)
    assert k == 30 and stopped.t[-1] == pytest.approx(0.3)
    for name in ("q", "qd", "goal", "envelope_ratio", "root_pose", "self_penetration_m", "ground_contact"):
        np.testing.assert_array_equal(getattr(stopped, name), getattr(whole, name)[:k], err_msg=name)
    assert player.play(tr, hold_s=0.3, stop_over=(0.305, 1.0 + 1e-6)).stopped_s is None  # never beyond the envelope: plays on
    assert len(player.play(tr, hold_s=0.3, stop_over=(0.305, 1.0 + 1e-6)).t) == len(whole.t)


def test_a_trajectory_for_other_joints_is_rejected(robot) -> None:  # type: ignore[no-untyped-def]
    start = settle(robot, "supine", robot.roles.joint_goals({"left.shoulder_roll": 0.25, "right.shoulder_roll": 0.25}))
    tr = Trajectory(robot.name, ("head_pan",), np.array([0.0]), np.zeros((1, 1)), start)
    with pytest.raises(RobotRiseError, match="lacks joints"):
        Player(robot).play(tr)


# --- equivalence with a plain per-step loop -------------------------------------------------
# Player.play vectorises the per-step checks and caches contact classification (see sim.py).
# This is the straightforward loop it replaced, kept as the reference: every physics step it
# computes the motor torque and envelope ratio and scans the contacts for self and obstacle
# contact; every sample it records, scans the ground contacts and computes the ZMP one body at
# a time with mj_objectAcceleration. It reads only the Player's public attributes.


def _reference_play(player: Player, tr: Trajectory, start, hold_s: float, record_hz: float) -> dict:  # type: ignore[no-untyped-def]
    import mujoco

    from robot_rise.sim.balance import support_margin, zmp_point_mass

    robot, m, d, idx, servos = player.robot, player.model, player.data, player.index, player.servos
    player.reset(start if start is not None else tr.start)
    dt = float(m.opt.timestep)
    n_steps = int(round((tr.duration_s + hold_s) / dt))
    stride = max(1, int(round(1.0 / (record_hz * dt))))
    step_t = np.arange(1, n_steps + 1) * dt
    goals = np.stack([np.interp(step_t - dt, tr.t, tr.q[:, j]) for j in range(robot.n_joints)], axis=-1)
    goals = np.clip(goals, m.actuator_ctrlrange[idx.actuators, 0], m.actuator_ctrlrange[idx.actuators, 1])
    torso = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, robot.torso_site)
    soles = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) for s in robot.sole_sites]
    kind = np.zeros(m.ngeom, dtype=int)  # 0 robot, 1 ground, 2 obstacle
    kind[idx.ground_geoms] = 1
    kind[idx.obstacle_geoms] = 2
    col = {int(g): c for c, g in enumerate(idx.robot_geoms)}
    foot_cols = set(player.foot_geom_cols.tolist())
    names = player.robot_geom_names
    K, n, ng = n_steps // stride, robot.n_joints, len(names)
    out = {
        key: np.zeros((K,) + shape, dtype=dtype)
        for key, shape, dtype in (
            ("t", (), float), ("q", (n,), float), ("qd", (n,), float), ("goal", (n,), float), ("torque", (n,), float),
            ("ratio", (n,), float), ("root_pose", (7,), float), ("root_vel", (6,), float), ("com", (3,), float),
            ("tilt", (), float), ("height", (), float), ("contact", (ng,), bool), ("on_feet", (), bool),
            ("self", (), bool), ("self_pen", (), float), ("obstacle", (), bool),
        )
    }
    out["zmp"] = np.full((K, 2), np.nan)
    out["margin"] = np.full(K, np.nan)
    iv_ratio, iv_self, iv_pen, iv_obst, peak, pairs = np.zeros(n), False, 0.0, False, 0.0, set()
    for s in range(n_steps):
        d.ctrl[idx.actuators] = goals[s]
        mujoco.mj_step(m, d)
        qd = d.qvel[idx.dof_joints].copy()
        tau = servos.motor_torque(d.actuator_force[idx.actuators], qd)
        iv_ratio = np.maximum(iv_ratio, servos.ratio(tau, qd))
        for c in range(d.ncon):
            g1, g2 = int(d.contact.geom[c][0]), int(d.contact.geom[c][1])
            if kind[g1] == 0 and kind[g2] == 0:
                iv_self = True
                iv_pen = max(iv_pen, -float(d.contact.dist[c]))
                pairs.add((names[col[g1]], names[col[g2]]))
            if {int(kind[g1]), int(kind[g2])} == {0, 2}:
                iv_obst = True
        if (s + 1) % stride:
            continue
        k = (s + 1) // stride - 1
        peak = max(peak, float(iv_ratio.max()))
        out["t"][k] = d.time
        out["q"][k] = d.qpos[idx.qpos_joints]
        out["qd"][k] = qd
        out["goal"][k] = goals[s]
        out["torque"][k] = tau
        out["ratio"][k] = iv_ratio
        out["root_pose"][k] = d.qpos[idx.qpos_root]
        out["root_vel"][k] = d.qvel[idx.qvel_root]
        out["com"][k] = d.subtree_com[idx.root_body]
        out["tilt"][k] = np.arccos(np.clip(d.site_xmat[torso].reshape(3, 3)[2, 2], -1.0, 1.0))
        out["height"][k] = d.site_xpos[torso][2] - min(d.site_xpos[i][2] for i in soles)
        out["self"][k], out["self_pen"][k], out["obstacle"][k] = iv_self, max(iv_pen, 0.0), iv_obst
        iv_ratio, iv_self, iv_pen, iv_obst = np.zeros(n), False, 0.0, False
        foot_points = []
        for c in range(d.ncon):
            g1, g2 = int(d.contact.geom[c][0]), int(d.contact.geom[c][1])
            if kind[g1] == 1 and kind[g2] == 0:
                g = g2
            elif kind[g2] == 1 and kind[g1] == 0:
                g = g1
            else:
                continue
            out["contact"][k, col[g]] = True
            if col[g] in foot_cols:
                foot_points.append(d.contact.pos[c][:2].copy())
        touching = np.flatnonzero(out["contact"][k])
        out["on_feet"][k] = touching.size > 0 and all(c in foot_cols for c in touching.tolist())
        if out["on_feet"][k]:
            mujoco.mj_rnePostConstraint(m, d)
            acc = np.zeros((m.nbody - 1, 3))
            res = np.zeros(6)
            for b in range(1, m.nbody):
                mujoco.mj_objectAcceleration(m, d, mujoco.mjtObj.mjOBJ_BODY, b, res, 0)
                acc[b - 1] = res[3:]
            zmp = zmp_point_mass(m.body_mass[1:], d.xipos[1:], acc + m.opt.gravity)
            out["zmp"][k] = zmp
            out["margin"][k] = support_margin(zmp, np.array(foot_points))
    out["peak"] = peak
    out["pairs"] = tuple(sorted(pairs))
    return out


_FIELDS = {
    "t": "t", "q": "q", "qd": "qd", "goal": "goal", "torque": "torque_nm", "ratio": "envelope_ratio",
    "root_pose": "root_pose", "root_vel": "root_vel", "com": "com", "tilt": "tilt_rad", "height": "torso_height_m",
    "contact": "ground_contact", "on_feet": "on_feet", "self": "self_contact", "self_pen": "self_penetration_m",
    "obstacle": "obstacle_contact", "zmp": "zmp", "margin": "zmp_margin_m",
}


def _arm_slam(robot):  # type: ignore[no-untyped-def]
    """Supine, arms swung hard across the body: self contact (and the low bed's edge)."""
    start = settle(robot, "supine", robot.roles.joint_goals({"left.shoulder_roll": 0.25, "right.shoulder_roll": 0.25}))
    q = start.joint_vector(robot.joint_names)
    slam = q.copy()
    for name, v in (("l_sho_roll", -1.6), ("r_sho_roll", 1.6), ("l_el", -2.0), ("r_el", 2.0)):
        slam[robot.joint_index(name)] = v
    return Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.3, 1.0]), np.stack([q, slam, slam]), start)


def _tip_over(robot):  # type: ignore[no-untyped-def]
    """Standing, feet pitched hard: on feet (ZMP, support margin), then tipping onto the body."""
    from robot_rise.posture import Posture

    sq = robot.stand_qpos
    start = Posture(robot.name, sq[:3], sq[3:7], dict(zip(robot.joint_names, sq[7:])))
    q = start.joint_vector(robot.joint_names)
    lean = q.copy()
    lean[robot.joint_index("l_ank_pitch")] += 0.6
    lean[robot.joint_index("r_ank_pitch")] -= 0.6
    return Trajectory(robot.name, robot.joint_names, np.array([0.0, 0.2, 0.6]), np.stack([q, q, lean]), start)


@pytest.mark.parametrize(
    ("scene", "make", "hold_s", "record_hz"),
    [
        ("low_bed", _arm_slam, 0.3, 100.0),  # self and obstacle contact, some on-feet samples
        ("low_bed", _arm_slam, 0.013, 33.0),  # stride 15 with unrecorded trailing steps
        ("flat", _tip_over, 0.8, 100.0),  # on feet with ZMP, then falling
        ("flat", _tip_over, 0.0, 500.0),  # a sample every step
    ],
)
def test_play_equals_the_plain_per_step_loop(robot, scene, make, hold_s, record_hz) -> None:  # type: ignore[no-untyped-def]
    tr = make(robot)
    player = Player(robot, scene)
    ref = _reference_play(player, tr, None, hold_s, record_hz)
    rec = player.play(tr, hold_s=hold_s, record_hz=record_hz)
    rec2 = player.play(tr, hold_s=hold_s, record_hz=record_hz)  # warm contact cache: same again
    for r in (rec, rec2):
        for key, name in _FIELDS.items():
            got, want = getattr(r, name), ref[key]
            assert got.shape == want.shape and got.dtype == want.dtype, name
            if want.dtype == bool:
                np.testing.assert_array_equal(got, want, err_msg=name)
            else:  # the physics is bit-identical; the batched ZMP sums in another order
                tol = 1e-9 if key in ("zmp", "margin") else 1e-12
                np.testing.assert_allclose(got, want, rtol=0, atol=tol, err_msg=name)
        assert r.peak_envelope_ratio_per_step == pytest.approx(ref["peak"], abs=1e-12)
        assert r.self_contact_pairs == ref["pairs"]
    if scene == "low_bed" and hold_s > 0.1:  # the case exercises what it is meant to
        assert rec.self_contact.any() and rec.obstacle_contact.any() and rec.self_penetration_m.max() > 0
    if scene == "flat" and record_hz == 100.0:
        assert rec.on_feet.any() and not rec.on_feet.all() and np.isfinite(rec.zmp_margin_m).any()
