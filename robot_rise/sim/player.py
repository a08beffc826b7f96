"""The player: plays a joint-target trajectory through the servo model and records what happens.

Given a robot, a scene, a start posture and a trajectory, :class:`Player` composes the MuJoCo
model (robot + scene + one Dynamixel position servo per joint, see ``robot_rise/model.py`` and
``robot_rise/servo.py``), puts the robot in the start posture at rest, and steps physics at the
model's timestep (2 ms = 500 Hz). Servo goals follow the trajectory, linearly interpolated between
its rows, and are held at the last row afterwards for ``hold_s``.

Every physics step is checked for the servo envelope (peak torque / envelope ratio) and self
contact; the rest is recorded at ``record_hz``: joint positions, velocities and goals, motor
torques, envelope ratios (max over the interval), root pose and velocity, centre of mass, torso
tilt and height, which robot geoms touch the ground, and, when only the feet touch the ground,
the ZMP and the support polygon margin (paper 003 section 2, eq. 2.11-2.12; see judge.py).

Speed (BENCHMARKS.md, "Player speed"): the loop around ``mj_step`` does as little Python as it
can. Per step it only sets the controls, copies ``qvel`` and ``actuator_force`` into preallocated
arrays, and classifies the contacts through a cache keyed by the contact list's geom ids (the
same few contact sets recur for thousands of steps); the envelope ratios of every step are then
computed in one vectorised pass at the end. Per sample it copies a few arrays; the ZMP (which
needs ``mj_rnePostConstraint`` at the sample) is computed for all on-feet samples at once at the
end from the copied ``cvel``/``cacc``/``xipos``. The results equal a plain per-step loop's
(sim_tests/test_sim.py keeps one as the reference).
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np

from robot_rise.errors import RobotRiseError
from robot_rise.sim.balance import support_margin, zmp_point_mass_many
from robot_rise.model import ModelIndex, Robot, compose, model_index
from robot_rise.posture import Posture
from robot_rise.servo import ServoArrays, servo_arrays
from robot_rise.sim.variants import ModelVariant, apply_to_model
from robot_rise.trajectory import Trajectory
from robot_rise.linkage import close_loops

__all__ = ["Recording", "Player", "play", "DEFAULT_RECORD_HZ", "DEFAULT_HOLD_S"]

log = logging.getLogger(__name__)

DEFAULT_RECORD_HZ = 100.0  # recording rate [Hz]; envelope and self contact are checked every step
DEFAULT_HOLD_S = 3.0  # time the last goal is held after the trajectory ends [s] (judge needs 2 s + settling)
_CONTACT_CACHE_MAX = 100_000  # contact-list kinds kept per Player (a play sees tens to hundreds)


@dataclass(frozen=True)
class Recording:
    """What happened when a trajectory was played. K samples at ``record_hz``; n joints.

    Attributes:
        joint_names: joint order, shape (n,).
        t: sample times [s], shape (K,).
        q, qd, goal: joint positions [rad], velocities [rad/s], servo goals [rad], shape (K, n).
        torque_nm: motor torque per joint at the sample [N m], shape (K, n).
        envelope_ratio: max over the interval ending at the sample of |tau| / envelope, shape (K, n).
        root_pose: root x, y, z [m], qw, qx, qy, qz, shape (K, 7).
        root_vel: root linear [m/s] (world) and angular [rad/s] (local) velocity, shape (K, 6).
        com: whole-robot centre of mass [m], shape (K, 3).
        tilt_rad: angle between the torso's z axis and the world vertical [rad], shape (K,).
        torso_height_m: torso site height above the lowest sole site [m], shape (K,).
        ground_contact: which robot geom touches the ground, shape (K, len(robot_geom_names)), bool.
        robot_geom_names: names of the robot geoms (columns of ground_contact).
        foot_geoms: column indices of the foot (sole) geoms in robot_geom_names.
        on_feet: only foot geoms touch the ground (and at least one does), shape (K,).
        zmp: ZMP on the ground [m], shape (K, 2); NaN when not on feet.
        zmp_margin_m: signed distance of the ZMP inside the support polygon [m] (negative: outside),
            shape (K,); NaN when not on feet.
        self_contact: a self contact occurred during the interval ending at the sample, shape (K,).
        self_penetration_m: deepest self penetration during the interval [m] (>= 0), shape (K,).
        obstacle_contact: a robot geom touched a scene obstacle during the interval, shape (K,).
        obstacle_touch: which robot geom touches a scene obstacle at the sample, shape like
            ground_contact (what rests on a bed or a beam; the judge counts it as support).
        obstacle_contact_pairs: every (robot geom, obstacle geom, first contact time [s]) of the
            play, in the order they first touched.
        stand_height_m: torso height of the ``stand`` keyframe [m] (judge reference).
        trajectory_end_s: when the trajectory's last row is reached [s].
        wall_time_s: wall-clock time the play took [s].
        peak_envelope_ratio_per_step: max over every physics step and joint of the ratio.
        stopped_s: when the play was stopped short (``Player.play``'s ``stop_over``) [s]; None:
            played to the end of the hold.
    """

    joint_names: tuple[str, ...]
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    goal: np.ndarray
    torque_nm: np.ndarray
    envelope_ratio: np.ndarray
    root_pose: np.ndarray
    root_vel: np.ndarray
    com: np.ndarray
    tilt_rad: np.ndarray
    torso_height_m: np.ndarray
    ground_contact: np.ndarray
    robot_geom_names: tuple[str, ...]
    foot_geoms: np.ndarray
    on_feet: np.ndarray
    zmp: np.ndarray
    zmp_margin_m: np.ndarray
    self_contact: np.ndarray
    self_penetration_m: np.ndarray
    obstacle_contact: np.ndarray
    stand_height_m: float
    trajectory_end_s: float
    wall_time_s: float
    peak_envelope_ratio_per_step: float
    self_contact_pairs: tuple[tuple[str, str], ...] = field(default_factory=tuple)
    obstacle_touch: np.ndarray | None = None
    obstacle_contact_pairs: tuple[tuple[str, str, float], ...] = ()
    stopped_s: float | None = None

    @property
    def peak_envelope_ratio(self) -> float:
        """Largest torque / envelope ratio over the whole play (every physics step)."""
        return self.peak_envelope_ratio_per_step

    def touching(self, k: int) -> list[str]:
        """Names of the robot geoms touching the ground at sample ``k``."""
        return [self.robot_geom_names[g] for g in np.flatnonzero(self.ground_contact[k])]


class Player:
    """Plays trajectories of one robot in one scene through the servo model.

    Not thread-safe (owns one MjData); make one per thread.
    """

    def __init__(
        self,
        robot: Robot,
        scene: str | os.PathLike[str] | None = "flat",
        *,
        voltage_v: float | None = None,
        friction_scale: float = 1.0,
        mass_scale: float = 1.0,
        variant: ModelVariant | None = None,
    ) -> None:
        """
        Args:
            robot: the robot.
            scene: scene name or MJCF path; None for the robot alone.
            voltage_v: servo supply [V] (None: the robot's own; a ``variant`` scales it).
            friction_scale: every geom's sliding friction times this.
            mass_scale: every body's mass and inertia times this.
            variant: a model variant (``robot_rise.sim.variants``) applied to the composed model;
                its input changes (latency, ticks, start) are the caller's to apply.
        """
        self.robot = robot
        self.scene = scene
        self.variant = variant
        if voltage_v is None:
            voltage_v = robot.supply_voltage_v
        if variant is not None:
            voltage_v *= variant.supply_scale
        self.model = compose(robot, scene, with_actuators=True, voltage_v=voltage_v, friction_scale=friction_scale, mass_scale=mass_scale)
        self.data = mujoco.MjData(self.model)
        self.index: ModelIndex = model_index(self.model, robot)
        if variant is not None:
            apply_to_model(self.model, self.index, variant)
        if self.index.actuators.size != robot.n_joints:
            raise RobotRiseError(f"composed model has {self.index.actuators.size} servos for {robot.n_joints} joints")
        self.servos: ServoArrays = servo_arrays(robot.servo_datasheets(), voltage_v)
        m = self.model
        self._torso_site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, robot.torso_site)
        self._sole_sites = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) for s in robot.sole_sites]
        foot_bodies = {int(m.site_bodyid[s]) for s in self._sole_sites}
        for b in range(m.nbody):  # with their rigid parts (cleats, toe plates) as child bodies
            if int(m.body_parentid[b]) in foot_bodies and m.body_jntnum[b] == 0:
                foot_bodies.add(b)
        rg = self.index.robot_geoms
        self._robot_geom_col = np.full(m.ngeom, -1, dtype=int)
        self._robot_geom_col[rg] = np.arange(rg.size)
        self._geom_kind = self.index.geom_kind  # 0 robot, 1 ground, 2 obstacle
        self._is_foot_geom = np.zeros(m.ngeom, dtype=bool)
        for g in rg:
            if int(m.geom_bodyid[g]) in foot_bodies:
                self._is_foot_geom[g] = True
        # an unnamed geom (a published model names few) by its body, so that a message says what touched
        self.robot_geom_names = tuple(m.geom(int(g)).name or f"{m.body(int(m.geom_bodyid[g])).name}.geom{int(g)}" for g in rg)
        self.foot_geom_cols = np.array([self._robot_geom_col[g] for g in rg if self._is_foot_geom[g]], dtype=int)
        self._robot_bodies = np.arange(1, m.nbody)
        self._body_mass = m.body_mass[1:].copy()
        self._root_body = self.index.root_body
        self._nonfoot_cols = np.setdiff1d(np.arange(rg.size), self.foot_geom_cols)
        self._sole_site_ids = np.asarray(self._sole_sites, dtype=int)
        # contact list (its geom ids as bytes) -> _classify_contacts(...); valid for the model's life
        self._contact_cache: dict[bytes, tuple] = {}
        self._no_contact = self._classify_contacts(np.zeros((0, 2), dtype=np.int32))

    def _classify_contacts(self, geoms: np.ndarray) -> tuple:
        """What a contact list (its geom id pairs, shape (ncon, 2)) means for the checks.

        Returns ``(flags, self_rows, self_pairs, touching, foot_rows, on_feet)``: flags bit 0 = a
        self contact (robot geom on robot geom), bit 1 = a robot geom on a scene obstacle;
        ``self_rows`` the self contacts' rows and ``self_pairs`` their geom names; ``touching``
        which robot geom touches the ground (bool per robot geom); ``foot_rows`` the rows of
        foot-ground contacts; ``on_feet`` only feet touch the ground (and one does);
        ``on_obstacle`` which robot geom touches an obstacle (bool per robot geom) and
        ``obstacle_pairs`` those contacts' (robot geom, obstacle geom) names.
        """
        kind, col, names = self._geom_kind, self._robot_geom_col, self.robot_geom_names
        g1, g2 = geoms[:, 0], geoms[:, 1]
        k1, k2 = kind[g1], kind[g2]
        selfc = (k1 == 0) & (k2 == 0)
        obstacle = ((k1 == 0) & (k2 == 2)) | ((k1 == 2) & (k2 == 0))
        self_rows = np.flatnonzero(selfc)
        self_pairs = tuple((names[col[a]], names[col[b]]) for a, b in geoms[selfc])
        first = (k1 == 1) & (k2 == 0)  # ground, robot
        second = (k2 == 1) & (k1 == 0)  # robot, ground
        ground = first | second
        robot_geom = np.where(first, g2, np.where(second, g1, 0))
        touching = np.zeros(len(names), dtype=bool)
        touching[col[robot_geom[ground]]] = True
        touching.setflags(write=False)
        foot_rows = np.flatnonzero(ground & self._is_foot_geom[robot_geom])
        on_feet = bool(touching.any()) and not bool(touching[self._nonfoot_cols].any())
        flags = (1 if self_rows.size else 0) | (2 if obstacle.any() else 0)
        on_obstacle = np.zeros(len(names), dtype=bool)
        obstacle_pairs: tuple[tuple[str, str], ...] = ()
        if obstacle.any():
            rg = np.where(k1[obstacle] == 0, g1[obstacle], g2[obstacle])
            og = np.where(k1[obstacle] == 0, g2[obstacle], g1[obstacle])
            on_obstacle[col[rg]] = True
            obstacle_pairs = tuple((names[col[a]], self.model.geom(int(b)).name or f"geom{int(b)}") for a, b in zip(rg, og))
        on_obstacle.setflags(write=False)
        return (flags, self_rows, self_pairs, touching, foot_rows, on_feet, on_obstacle, obstacle_pairs)

    def reset(self, start: Posture) -> None:
        """Put the robot at rest in ``start`` with the servo goals at its joint angles."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[:] = start.qpos(self.robot, self.index, m.qpos0)
        if self.index.linkage is not None:  # the passive joints where the driven ones put them
            close_loops(m, d, self.index.linkage)
        d.qvel[:] = 0.0
        d.ctrl[self.index.actuators] = start.joint_vector(self.robot.joint_names)
        mujoco.mj_forward(m, d)

    def play(
        self,
        trajectory: Trajectory,
        start: Posture | None = None,
        *,
        hold_s: float = DEFAULT_HOLD_S,
        record_hz: float = DEFAULT_RECORD_HZ,
        stop_over: tuple[float, float] | None = None,
    ) -> Recording:
        """Play ``trajectory`` from ``start`` (default: the trajectory's own start posture).

        Args:
            trajectory: joint goals over time; its joint names must be the robot's joints.
            start: posture at t = 0 (at rest).
            hold_s: time the last goal is held after the trajectory ends [s].
            record_hz: recording rate [Hz] (at most the physics rate).
            stop_over: (time [s], envelope ratio): stop the play at that time if a physics step
                before it exceeded that torque / envelope ratio (a replay already over the margin
                need not be played on); the recording then ends there (``Recording.stopped_s``).

        Returns:
            The :class:`Recording`.

        Raises:
            RobotRiseError: the trajectory does not fit the robot.
        """
        robot = self.robot
        if tuple(trajectory.joint_names) != robot.joint_names:
            cols = [trajectory.joint_names.index(j) if j in trajectory.joint_names else -1 for j in robot.joint_names]
            if min(cols) < 0:
                missing = [j for j, c in zip(robot.joint_names, cols) if c < 0]
                raise RobotRiseError(f"trajectory lacks joints {', '.join(missing)} of robot {robot.name}")
            goals_all = trajectory.q[:, cols]
        else:
            goals_all = trajectory.q
        m, d = self.model, self.data
        self.reset(start if start is not None else trajectory.start)
        dt = float(m.opt.timestep)
        n_steps = int(round((trajectory.duration_s + hold_s) / dt))
        stride = max(1, int(round(1.0 / (record_hz * dt))))
        step_t = np.arange(1, n_steps + 1) * dt
        n = robot.n_joints
        goals = np.stack([np.interp(step_t - dt, trajectory.t, goals_all[:, j]) for j in range(n)], axis=-1).reshape(n_steps, n)
        acts = self.index.actuators
        lo = m.actuator_ctrlrange[acts, 0]
        hi = m.actuator_ctrlrange[acts, 1]
        goals = np.clip(goals, lo, hi)
        ctrl_seq = np.tile(d.ctrl, (n_steps, 1))  # the whole ctrl vector per step
        ctrl_seq[:, acts] = goals

        K = n_steps // stride  # samples; steps past K * stride are played but not recorded
        ng = len(self.robot_geom_names)
        # per physics step
        qvel_steps = np.empty((n_steps, m.nv))
        force_steps = np.empty((n_steps, m.nu))
        self_step = np.zeros(n_steps, dtype=bool)
        pen_step = np.zeros(n_steps)
        obstacle_step = np.zeros(n_steps, dtype=bool)
        obstacle_first: dict[tuple[str, str], float] = {}  # (robot geom, obstacle geom) -> first contact [s]
        pairs: set[tuple[str, str]] = set()
        # per sample
        t_rec = np.zeros(K)
        qpos_rec = np.zeros((K, m.nq))
        com_rec = np.zeros((K, 3))
        zz_rec = np.zeros(K)  # torso z axis . world z
        site_rec = np.zeros((K, m.nsite, 3))
        contact_rec = np.zeros((K, ng), dtype=bool)
        obstacle_touch_rec = np.zeros((K, ng), dtype=bool)
        on_feet_rec = np.zeros(K, dtype=bool)
        zmp_rec = np.full((K, 2), np.nan)
        margin_rec = np.full(K, np.nan)
        # per on-feet sample (ZMP inputs)
        nb = m.nbody
        feet_k = np.zeros(K, dtype=int)
        feet_cvel = np.empty((K, nb, 6))
        feet_cacc = np.empty((K, nb, 6))
        feet_xipos = np.empty((K, nb, 3))
        feet_subtree_com = np.empty((K, nb, 3))
        feet_points: list[np.ndarray] = []
        nfeet = 0

        cache = self._contact_cache
        if len(cache) > _CONTACT_CACHE_MAX:
            cache.clear()
        cache[b""] = self._no_contact
        classify = self._classify_contacts
        torso, root = self._torso_site, self._root_body
        ctrl, qvel, force, qpos = d.ctrl, d.qvel, d.actuator_force, d.qpos
        site_xpos, site_xmat, subtree_com = d.site_xpos, d.site_xmat, d.subtree_com
        mj_step = mujoco.mj_step
        next_sample = stride
        k = 0
        idx = self.index
        # on a sample's step (so the recording ends on a sample), at or before the time asked
        stop_step = -1 if stop_over is None else min(n_steps - 1, max(stride, int(round(stop_over[0] / dt)) // stride * stride) - 1)
        stopped_s: float | None = None
        t0 = time.perf_counter()
        for s, row in enumerate(ctrl_seq):
            ctrl[:] = row
            mj_step(m, d)
            qvel_steps[s] = qvel
            force_steps[s] = force
            if s == stop_step and s + 1 < n_steps and stop_over is not None:
                qd_so_far = qvel_steps[: s + 1, idx.dof_joints]
                over = self.servos.ratio(self.servos.motor_torque(force_steps[: s + 1, acts], qd_so_far), qd_so_far)
                if float(np.nanmax(over, initial=0.0)) > stop_over[1]:
                    stopped_s = float((s + 1) * dt)
            geoms = d.contact.geom
            key = geoms.tobytes()  # b"" without contacts
            kinds = cache.get(key)
            if kinds is None:
                kinds = cache[key] = classify(geoms.copy())
            if kinds[0]:
                if kinds[0] & 1:
                    self_step[s] = True
                    pen_step[s] = max(0.0, float(-d.contact.dist[kinds[1]].min()))
                    pairs.update(kinds[2])
                if kinds[0] & 2:
                    obstacle_step[s] = True
                    for pair in kinds[7]:
                        if pair not in obstacle_first:
                            obstacle_first[pair] = float(d.time)
            if s + 1 != next_sample:
                continue
            next_sample += stride
            if k >= K:
                continue
            t_rec[k] = d.time
            qpos_rec[k] = qpos
            com_rec[k] = subtree_com[root]
            zz_rec[k] = site_xmat[torso, 8]
            site_rec[k] = site_xpos
            contact_rec[k] = kinds[3]
            if kinds[0] & 2:
                obstacle_touch_rec[k] = kinds[6]
            if kinds[5]:
                on_feet_rec[k] = True
                feet_points.append(d.contact.pos[kinds[4], :2])
                mujoco.mj_rnePostConstraint(m, d)
                feet_k[nfeet] = k
                feet_cvel[nfeet] = d.cvel
                feet_cacc[nfeet] = d.cacc
                feet_xipos[nfeet] = d.xipos
                feet_subtree_com[nfeet] = subtree_com
                nfeet += 1
            k += 1
            if stopped_s is not None:
                break
        if stopped_s is not None:  # the recording ends at the last sample taken
            n_steps = stop_step + 1
            K = n_steps // stride
            qvel_steps, force_steps, goals = qvel_steps[:n_steps], force_steps[:n_steps], goals[:n_steps]
            self_step, pen_step, obstacle_step = self_step[:n_steps], pen_step[:n_steps], obstacle_step[:n_steps]
            t_rec, qpos_rec, com_rec, zz_rec, site_rec = t_rec[:K], qpos_rec[:K], com_rec[:K], zz_rec[:K], site_rec[:K]
            contact_rec, obstacle_touch_rec, on_feet_rec = contact_rec[:K], obstacle_touch_rec[:K], on_feet_rec[:K]
            zmp_rec, margin_rec = zmp_rec[:K], margin_rec[:K]

        # envelope of every physics step, vectorised
        qd_steps = qvel_steps[:, idx.dof_joints]
        tau_steps = self.servos.motor_torque(force_steps[:, acts], qd_steps)
        ratio_steps = self.servos.ratio(tau_steps, qd_steps)
        n_rec = K * stride
        interval_ratio = ratio_steps[:n_rec].reshape(K, stride, n).max(axis=1)
        peak = float(np.nanmax(interval_ratio, initial=0.0)) if K else 0.0
        rec_steps = np.arange(1, K + 1) * stride - 1  # the step each sample is taken after
        # ZMP and support margin of the on-feet samples
        if nfeet:
            acc = _body_com_acc_many(m, feet_cvel[:nfeet], feet_cacc[:nfeet], feet_xipos[:nfeet], feet_subtree_com[:nfeet])
            zmp = zmp_point_mass_many(self._body_mass, feet_xipos[:nfeet, 1:], acc)
            zmp_rec[feet_k[:nfeet]] = zmp
            margin_rec[feet_k[:nfeet]] = [support_margin(z, pts) for z, pts in zip(zmp, feet_points)]
        wall = time.perf_counter() - t0
        log.debug("played %.2f s of motion in %.3f s wall", n_steps * dt, wall)
        return Recording(
            joint_names=robot.joint_names,
            t=t_rec,
            q=qpos_rec[:, idx.qpos_joints],
            qd=qd_steps[rec_steps],
            goal=goals[rec_steps],
            torque_nm=tau_steps[rec_steps],
            envelope_ratio=interval_ratio,
            root_pose=qpos_rec[:, idx.qpos_root],
            root_vel=qvel_steps[rec_steps][:, idx.qvel_root],
            com=com_rec,
            tilt_rad=np.arccos(np.clip(zz_rec, -1.0, 1.0)),
            torso_height_m=site_rec[:, torso, 2] - site_rec[:, self._sole_site_ids, 2].min(axis=1),
            ground_contact=contact_rec,
            robot_geom_names=self.robot_geom_names,
            foot_geoms=self.foot_geom_cols,
            on_feet=on_feet_rec,
            zmp=zmp_rec,
            zmp_margin_m=margin_rec,
            self_contact=self_step[:n_rec].reshape(K, stride).any(axis=1),
            self_penetration_m=pen_step[:n_rec].reshape(K, stride).max(axis=1),
            obstacle_contact=obstacle_step[:n_rec].reshape(K, stride).any(axis=1),
            stand_height_m=robot.stand_height_m,
            trajectory_end_s=trajectory.duration_s,
            wall_time_s=wall,
            peak_envelope_ratio_per_step=peak,
            self_contact_pairs=tuple(sorted(pairs)),
            obstacle_touch=obstacle_touch_rec,
            obstacle_contact_pairs=tuple((a, b, t) for (a, b), t in sorted(obstacle_first.items(), key=lambda kv: kv[1])),
            stopped_s=stopped_s,
        )


def _body_com_acc_many(m: mujoco.MjModel, cvel: np.ndarray, cacc: np.ndarray, xipos: np.ndarray, subtree_com: np.ndarray) -> np.ndarray:
    """Linear acceleration of every body's centre of mass (world frame, gravity excluded) [m/s^2].

    For S samples of ``cvel``, ``cacc`` (after ``mj_rnePostConstraint``), ``xipos`` and
    ``subtree_com`` (each shape (S, nbody, .)). This is ``mj_objectAcceleration`` (body, world
    frame) vectorised: ``cacc`` is the spatial acceleration about the subtree root's centre of mass
    and includes the -gravity offset MuJoCo seeds the recursion with, which we remove; the point
    acceleration adds omega x v (the frame is not co-moving). Shape (S, nbody-1, 3).
    """
    w, v = cvel[:, 1:, :3], cvel[:, 1:, 3:]
    dif = xipos[:, 1:] - subtree_com[:, m.body_rootid[1:]]
    v_point = v - np.cross(dif, w)
    acc = cacc[:, 1:, 3:] - np.cross(dif, cacc[:, 1:, :3])
    acc += np.cross(w, v_point)
    return acc + m.opt.gravity  # cacc carries acc - gravity (accelerometer-like)


def play(
    robot: Robot,
    trajectory: Trajectory,
    *,
    scene: str | os.PathLike[str] | None = "flat",
    start: Posture | None = None,
    hold_s: float = DEFAULT_HOLD_S,
    friction_scale: float = 1.0,
    mass_scale: float = 1.0,
    voltage_v: float | None = None,
    record_hz: float = DEFAULT_RECORD_HZ,
) -> Recording:
    """One-shot :meth:`Player.play` (composes the model each call)."""
    player = Player(robot, scene, voltage_v=voltage_v, friction_scale=friction_scale, mass_scale=mass_scale)
    return player.play(trajectory, start, hold_s=hold_s, record_hz=record_hz)
