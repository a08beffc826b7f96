"""Issue 15: adapting a strategy to a body (robot_rise/authoring/adapt.py) -- a no-op on the robot the
strategies were written for, statics and self contact on imported bodies, the search deterministic."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from robot_rise.authoring import build_trajectory, motion_specs, robustness_players, settle
from robot_rise.authoring.adapt import (
    BodyAdaptation,
    Statics,
    adapt_to_body,
    apply_adaptation,
    body_parts,
    collision_free,
    fit_to_body,
    reference_statics,
    standing_phase,
    support_phases,
)
from robot_rise.authoring.keyframes import Keyframe
from robot_rise.library import load_strategies
from robot_rise.model import compose, load_robot, model_index
from robot_rise.sim.player import Player
from robot_rise.sim.standing import judge

# ``imported``: the published robots (../shared/robots), imported once per session (sim_tests/conftest.py)


def _role(robot, role: str, q: dict[str, float]) -> float:  # type: ignore[no-untyped-def]
    j = robot.roles.by_role()[role]
    return j.sign * (q[j.joint] - j.neutral_rad)


def test_adaptation_is_a_no_op_on_the_robot_the_strategies_were_written_for() -> None:
    """The OP3 is the strategies' own robot: fitting its statics to itself changes nothing, and
    every shipped strategy stands on it as written, so the search is never run there; except a
    momentum motion searched with its goals clamped into the envelope (``clamp_lead``), which
    stands only as the library authors it (clamped): its shipped motion is proven instead."""
    from robot_rise.proof import Proof
    from robot_rise.library import load_library

    robot = load_robot()
    player = Player(robot, "flat")
    shipped = load_library()
    for spec in motion_specs(robot):
        start = settle(robot, spec.lying, spec.lying_joints, yaw_rad=spec.lying_yaw_rad)
        ref = reference_statics(robot, spec.keyframes, start)
        if spec.clamp_lead and not ref.stands:
            assert Proof.from_dict(shipped.get(spec.name).trajectory.report).proven, spec.name
            continue
        assert ref.stands and ref.stand_from is not None, spec.name
        fitted, notes = fit_to_body(robot, spec.keyframes, start, ref)
        assert not notes and [dict(k.joints) for k in fitted] == [dict(k.joints) for k in spec.keyframes], (spec.name, notes)
        v = judge(player.play(build_trajectory(robot, start, spec.keyframes)))
        assert v.standing, (spec.name, v.summary())


def test_standing_phase_is_the_final_run_on_the_feet_alone() -> None:
    f, fh, o = frozenset({"foot"}), frozenset({"foot", "hand"}), frozenset({"other"})
    assert standing_phase([o, fh, fh, f, f, f]) == 3
    assert standing_phase([o, f, fh, f]) == 3
    assert standing_phase([f, f]) == 0
    assert standing_phase([o, fh]) is None


def test_support_phases_of_a_prone_strategy_on_the_op3() -> None:
    robot = load_robot()
    spec = next(s for s in motion_specs(robot) if s.name == "prone_knees_first")
    start = settle(robot, spec.lying, spec.lying_joints)
    phases = support_phases(Player(robot, "flat"), start, spec.keyframes)
    assert len(phases) == len(spec.keyframes)
    assert phases[-1] == frozenset({"foot"})
    assert standing_phase(phases) == 3  # hands and feet until the push, then the feet alone
    assert "hand" in phases[1]


def test_body_parts_finds_the_feet_and_hands() -> None:
    robot = load_robot()
    m = compose(robot, None, with_actuators=False)
    idx = model_index(m, robot)
    parts = body_parts(robot, m, idx.robot_geoms)
    assert {0, 1, 2} <= set(parts.tolist())
    st = Statics(robot)
    st.place(np.asarray(robot.stand_qpos[7:], dtype=float))
    feet = idx.robot_geoms[parts == 0]
    assert abs(st.lowest(feet)) < 2e-3  # standing: the soles on the ground


def test_adaptation_offsets_are_role_values() -> None:
    """Offsets are applied in roles (sign per joint), on the push keyframes only; times stretched."""
    robot = load_robot()
    spec = next(s for s in motion_specs(robot) if s.name == "prone_knees_first")
    start = settle(robot, spec.lying, spec.lying_joints)
    a = BodyAdaptation(time_scale=2.0, arm=0.1, hip=0.2)
    ref = reference_statics(robot, spec.keyframes, start)
    assert ref.stand_from == 3
    kfs, _ = apply_adaptation(robot, spec.keyframes, start, ref, a)
    assert [k.t_s for k in kfs] == [round(2.0 * k.t_s, 3) for k in spec.keyframes]
    before, after = dict(spec.keyframes[2].joints), dict(kfs[2].joints)
    for side in ("left", "right"):
        assert _role(robot, f"{side}.shoulder_pitch", after) == pytest.approx(_role(robot, f"{side}.shoulder_pitch", before) + 0.1, abs=1e-9)
        assert _role(robot, f"{side}.hip_pitch", after) == pytest.approx(_role(robot, f"{side}.hip_pitch", before) + 0.2, abs=1e-9)
    assert dict(kfs[0].joints) == dict(spec.keyframes[0].joints)  # before the push: unchanged


def test_mesh_statics_use_vertices(imported) -> None:  # type: ignore[no-untyped-def]
    """Bez1's collision meshes: its standing posture is on its feet alone (a mesh's bounding box
    would put its shins on the ground)."""
    robot = imported["bez1"].robot
    st = Statics(robot)
    st.place(np.asarray(robot.stand_qpos[7:], dtype=float))
    # the sole site sits at the foot mesh's lowest vertex (robot import): the ankles clear by ~11 mm
    assert st.lowest(st.other_geoms) > 0.005


def test_collision_free_opens_a_knee_the_body_cannot_flex_that_far(imported) -> None:  # type: ignore[no-untyped-def]
    robot = imported["bez1"].robot
    goals = robot.roles.joint_goals({f"{s}.{r}": v for s in ("left", "right") for r, v in (("hip_pitch", -1.7), ("knee", 2.6), ("ankle_pitch", -1.2))})
    spec = next(s for s in motion_specs(robot) if s.name == "prone_knees_first")
    start = settle(robot, spec.lying, spec.lying_joints)
    st = Statics(robot)
    kfs, notes = collision_free(robot, (Keyframe(1.0, goals),), start, st=st)
    assert notes and "self contact" in notes[0]
    q = np.array([kfs[0].joints.get(j, start.joints[j]) for j in robot.joint_names])
    assert not st.self_contacts(np.clip(q, robot.joint_lower, robot.joint_upper))
    assert _role(robot, "left.knee", dict(kfs[0].joints)) < 2.6
    # a posture that does not touch itself is left alone
    stand = dict(zip(robot.joint_names, robot.stand_qpos[7:]))
    same, notes = collision_free(robot, (Keyframe(1.0, stand),), start, st=st)
    assert not notes and dict(same[0].joints) == stand


@pytest.mark.slow
def test_adapt_to_body_is_deterministic(imported) -> None:  # type: ignore[no-untyped-def]
    robot, reference = imported["wolfgang"].robot, load_robot()
    strategy = next(s for s in load_strategies() if s.name == "prone_knees_first")
    spec, ref_spec = motion_specs(robot, (strategy,))[0], motion_specs(reference, (strategy,))[0]
    start = settle(robot, spec.lying, spec.lying_joints)
    ref = reference_statics(reference, ref_spec.keyframes, settle(reference, ref_spec.lying, ref_spec.lying_joints))
    players = robustness_players(robot)
    runs = [adapt_to_body(robot, spec.keyframes, start, players, ref, seed=zlib.crc32(b"x"), max_plays=12) for _ in range(2)]
    assert runs[0].note == runs[1].note and runs[0].plays == runs[1].plays <= 12
