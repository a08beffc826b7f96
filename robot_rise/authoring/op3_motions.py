"""The OP3 motion library's source data: its get-up motions as keyframes, and the OP3's left/right symmetry.

This is the one module that names OP3 joints (robot.xml of configs/robots/op3). Joint values are
written for the left side; :func:`sym` mirrors them to the right side. In robot.xml every right
joint mirrors its left twin with the opposite sign (pitch axes are mirrored, roll/yaw axes
shared), so a symmetric posture has q_right = -q_left; :func:`mirror` turns a left-side motion
into its right-side twin. The keyframe times are only a shape: the timing of most motions is found
in MuJoCo (:mod:`robot_rise.authoring.retiming`).
"""

from __future__ import annotations

from collections.abc import Mapping

from robot_rise.authoring.keyframes import Keyframe, MotionSpec

__all__ = ["MOTION_SPECS", "mirror", "mirror_keyframes", "sym"]

_SIDES = (  # OP3 joints that come in pairs, l_<name> and r_<name>
    "sho_pitch", "sho_roll", "el", "hip_yaw", "hip_roll", "hip_pitch", "knee", "ank_pitch", "ank_roll",
)


def sym(**left: float) -> dict[str, float]:
    """Joint goals for both sides from left-side values: ``sym(knee=1.0)`` -> l_knee 1, r_knee -1.

    Keys may also be full joint names (``l_knee``, ``r_el``, ``head_tilt``) for one side only.
    """
    out: dict[str, float] = {}
    for k, v in left.items():
        if k in _SIDES:
            out[f"l_{k}"] = float(v)
            out[f"r_{k}"] = -float(v)
        else:
            out[k] = float(v)
    return out


def mirror(joints: Mapping[str, float]) -> dict[str, float]:
    """The mirror image (left <-> right) of joint goals: ``l_x = v`` becomes ``r_x = -v`` and vice versa,
    ``head_pan`` changes sign (robot.xml: right joints mirror their left twins with the opposite sign)."""
    out: dict[str, float] = {}
    for k, v in joints.items():
        if k.startswith("l_"):
            out["r_" + k[2:]] = -float(v)
        elif k.startswith("r_"):
            out["l_" + k[2:]] = -float(v)
        elif k == "head_pan":
            out[k] = -float(v)
        else:
            out[k] = float(v)
    return out


def mirror_keyframes(keyframes: tuple[Keyframe, ...]) -> tuple[Keyframe, ...]:
    """Keyframes of the mirror-image motion (see :func:`mirror`)."""
    return tuple(Keyframe(k.t_s, mirror(k.joints)) for k in keyframes)


# --- the motions ------------------------------------------------------------------------------

_STAND = sym(sho_pitch=0.0, sho_roll=1.25, el=0.0, hip_yaw=0.0, hip_roll=0.0, hip_pitch=-0.35, knee=0.7, ank_pitch=0.35, ank_roll=0.0) | {
    "head_pan": 0.0,
    "head_tilt": 0.0,
}
_LIE_FLAT = sym(sho_pitch=0.0, sho_roll=1.3, el=0.0, hip_pitch=0.0, knee=0.05, ank_pitch=0.0) | {"head_pan": 0.0, "head_tilt": 0.0}

_T_ARMS = sym(sho_pitch=-1.57, sho_roll=0.15)  # arms out sideways, turned so sho_roll pushes them down
_ALL_FOURS = sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0, hip_pitch=-1.7, knee=2.5, ank_pitch=0.6)
_SQUAT_HANDS = sym(sho_pitch=-0.8, sho_roll=1.3, el=0.0, hip_pitch=-1.7, knee=2.6, ank_pitch=1.3)
_SQUAT = sym(sho_pitch=0.0, sho_roll=1.3, el=0.0, hip_pitch=-1.7, knee=2.4, ank_pitch=1.2)


def _prone_tail(t0: float) -> tuple[Keyframe, ...]:
    """Push-up -> all fours -> squat -> stand, starting at ``t0`` from prone with T arms."""
    return (
        Keyframe(t0 + 0.6, sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0)),
        Keyframe(t0 + 1.2, _ALL_FOURS),
        Keyframe(t0 + 1.7, _SQUAT_HANDS),
        Keyframe(t0 + 2.0, _SQUAT),
        Keyframe(t0 + 2.7, _STAND),
    )


_ROLL_BACK = (
    Keyframe(0.3, sym(sho_pitch=0.3, sho_roll=1.3, hip_pitch=-0.2, knee=0.3)),  # ready: end of the supine (connect) phase
    # legs swung up over the hips, nearly straight (long lever, fast), the arms along the body start
    # pressing into the ground: the hips lift and the centre of mass moves over the shoulders
    Keyframe(0.8, sym(sho_pitch=0.8, hip_pitch=-1.8, knee=0.2)),
    Keyframe(1.4, sym(sho_pitch=2.0, hip_pitch=-1.7, knee=0.8)),  # over the head: the arms push on
    # knees bent for the landing on head and feet (prone pike); the arms, free while the robot goes
    # over its head, are swept out sideways (along the shoulder pitch axis, ready to be spun to the T)
    Keyframe(1.9, sym(sho_pitch=2.2, sho_roll=0.0, hip_pitch=-1.5, knee=1.5)),
)


def _prone_arms_from_overhead(t0: float) -> tuple[Keyframe, ...]:
    """Landed in the prone pike after a back roll (arms sideways): hips lowered to lie prone, arms
    spun about their own axis to the T, knees pulled under."""
    return (
        Keyframe(t0 + 0.5, sym(hip_pitch=-0.6, knee=0.8)),  # hips down: lying prone
        Keyframe(t0 + 1.0, sym(sho_pitch=-1.57, sho_roll=0.15, hip_pitch=-1.2, knee=2.0, ank_pitch=0.3)),  # the T; knees under
    )


# Lying on the left side: knees tucked, the lower (left) arm stretched over the head under it, feet
# apart -- this rests on the side (the box torso alone rolls onto its back).
_LEFT_SIDE = _LIE_FLAT | sym(hip_roll=-0.12, hip_pitch=-0.5, knee=1.0) | {"l_sho_pitch": 0.0, "l_sho_roll": -1.2, "r_hip_pitch": 0.9, "r_knee": -1.2}
_LEFT_TIP = (
    Keyframe(0.3, {}),  # end of the side-lying (connect) phase
    # lower arm turned forward under the head, upper arm reaching forward and down, knees pulled up:
    # the centre of mass moves in front of the support and the robot tips onto its front
    Keyframe(0.9, {"l_sho_pitch": -0.8, "r_sho_pitch": 1.2, "r_sho_roll": -0.6, "l_hip_pitch": -0.8, "l_knee": 1.2, "r_hip_pitch": 1.2, "r_knee": -1.4}),
    Keyframe(1.4, {"l_sho_pitch": -0.8}),
    Keyframe(2.0, sym(sho_roll=0.15, hip_roll=0.0, hip_pitch=-1.2, knee=2.0, ank_pitch=0.3)),  # prone: arms swept out, knees under
    Keyframe(2.4, sym(sho_pitch=-1.57)),  # arms turned about their axis: the prone T
)


_ELBOWS_KNEES = sym(sho_pitch=-1.57, sho_roll=0.15, el=-1.4, hip_pitch=-1.2, knee=2.0, ank_pitch=0.3)  # prone: forearms down, knees under


def _elbow_knees_tail(t0: float) -> tuple[Keyframe, ...]:
    """From prone in ``_ELBOWS_KNEES`` at ``t0``: elbows and shoulders push (short levers: the
    forearms stand on the ground) while the knees come further under, then straight back onto the
    feet (no separate all-fours pose: 0.4 s shorter, as robust), squat, stand."""
    return _elbow_knees_tail_at((t0 + 0.5, t0 + 0.9, t0 + 1.4, t0 + 1.7, t0 + 2.4))


def _elbow_knees_tail_at(times_s: tuple[float, float, float, float, float]) -> tuple[Keyframe, ...]:
    """The keyframes of :func:`_elbow_knees_tail` at the given times [s]."""
    return tuple(
        Keyframe(t, g)
        for t, g in zip(
            times_s,
            (
                sym(sho_pitch=-1.57, sho_roll=0.9, el=-0.6, hip_pitch=-1.4, knee=2.3, ank_pitch=0.4),
                sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0, hip_pitch=-1.5, knee=2.4, ank_pitch=0.5),
                _SQUAT_HANDS,
                _SQUAT,
                _STAND,
            ),
        )
    )


# In index order (connecting-posture selection breaks ties between equal start postures by it).
MOTION_SPECS: tuple[MotionSpec, ...] = (
    MotionSpec(
        name="prone_elbow_knees_quick",
        lying="prone",
        strategy="prone_elbow_knees in 2.42 s: the same keyframes, pushed through with momentum (times from a search in MuJoCo), goals clamped into the envelope",
        lying_joints=_LIE_FLAT | _T_ARMS,
        # First in the index: the prone motions share this start posture, and the nearest-frame
        # search breaks that tie by index order, so the canonical prone start rises through the
        # fastest one. Times: prone_elbow_knees' retimed segments scaled by an evolution strategy that kept the
        # robot standing on all five players with saturating servos (1.2 s), then all x2.0: with
        # clamp_goal_lead the servos stay within the envelope and it still stands everywhere.
        keyframes=(Keyframe(0.292, _ELBOWS_KNEES),) + _elbow_knees_tail_at((0.516, 0.588, 1.233, 1.335, 2.416)),
        connect_keyframe=3,
        retime=False,
        clamp_lead=True,
    ),
    MotionSpec(
        name="prone_pushup_squat",
        lying="prone",
        strategy="prone, arms out: lateral push-up, legs folded under to all fours, push back onto the feet, squat, stand",
        lying_joints=_LIE_FLAT | _T_ARMS,
        keyframes=_prone_tail(0.0),
        connect_keyframe=2,
    ),
    MotionSpec(
        name="prone_knees_first",
        lying="prone",
        strategy="prone, arms out: knees pulled under first, then the push-up onto all fours, push back onto the feet, squat, stand",
        lying_joints=_LIE_FLAT | _T_ARMS,
        keyframes=(
            Keyframe(0.5, _T_ARMS | sym(hip_pitch=-1.2, knee=2.0, ank_pitch=0.3)),
            Keyframe(1.1, sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0, hip_pitch=-1.5, knee=2.4, ank_pitch=0.5)),
            Keyframe(1.6, _ALL_FOURS),
            Keyframe(2.1, _SQUAT_HANDS),
            Keyframe(2.4, _SQUAT),
            Keyframe(3.1, _STAND),
        ),
        connect_keyframe=3,
    ),
    MotionSpec(
        name="prone_elbow_pushup",
        lying="prone",
        strategy="prone, arms out: forearms pushed down at the elbows first (short lever), then the shoulders, all fours, squat, stand",
        lying_joints=_LIE_FLAT | _T_ARMS,
        keyframes=(
            Keyframe(0.4, sym(sho_pitch=-1.57, sho_roll=0.15, el=-1.4)),
            Keyframe(0.9, sym(sho_pitch=-1.57, sho_roll=0.9, el=-0.6)),
            Keyframe(1.3, sym(sho_pitch=-1.57, sho_roll=1.3, el=0.0)),
            Keyframe(1.9, _ALL_FOURS),
            Keyframe(2.4, _SQUAT_HANDS),
            Keyframe(2.7, _SQUAT),
            Keyframe(3.4, _STAND),
        ),
        connect_keyframe=4,
    ),
    MotionSpec(
        name="prone_elbow_knees",
        lying="prone",
        strategy="prone, arms out: knees pulled under while the forearms are set down at the elbows (short levers), elbows and shoulders push up, straight back onto the feet, squat, stand",
        lying_joints=_LIE_FLAT | _T_ARMS,
        keyframes=(Keyframe(0.5, _ELBOWS_KNEES),) + _elbow_knees_tail(0.5),
        connect_keyframe=3,
    ),
    MotionSpec(
        name="supine_backroll_pushup",
        lying="supine",
        strategy="supine: legs swung over the head while the arms along the body push, backward roll, land prone; lying prone the arms go to the T and the knees under, forearms set down, elbows and shoulders push up and back onto the feet, squat, stand (prone_elbow_knees tail)",
        lying_joints=_LIE_FLAT,
        keyframes=_ROLL_BACK + _prone_arms_from_overhead(1.9) + (Keyframe(3.3, _ELBOWS_KNEES),) + _elbow_knees_tail(3.3),
        connect_keyframe=0,
    ),
    MotionSpec(
        name="supine_backroll_kneel",
        lying="supine",
        strategy="supine: backward roll over the head into a prone pike (head and feet down); arms to the T, knees pulled under with the elbows bent, pushed up and back onto the feet from the pike (never lying flat), squat, stand",
        # knees up, arms out at 40 deg: a different supine start from supine_backroll_pushup's, so
        # that connecting-posture selection covers more of the supine postures (same roll after 0.3 s)
        lying_joints=_LIE_FLAT | sym(sho_roll=0.7, hip_pitch=-0.6, knee=1.2, ank_pitch=0.3),
        keyframes=_ROLL_BACK
        + (
            Keyframe(2.5, sym(sho_pitch=-1.57, sho_roll=0.15)),  # arms spun about their own axis: the T
            # knees pulled under the hips, hands set down with bent elbows (short lever) while the head
            # still rests: the weight goes onto the shins before the arms push
            Keyframe(3.1, sym(sho_roll=0.5, el=-1.0, hip_pitch=-1.8, knee=2.5, ank_pitch=0.6)),
            Keyframe(4.0, _SQUAT_HANDS),  # pushed up and straight back onto the feet (no separate all-fours pose)
            Keyframe(4.4, _SQUAT),
            Keyframe(5.2, _STAND),
        ),
        connect_keyframe=0,
    ),
    MotionSpec(
        name="supine_situp_rock",
        lying="supine",
        strategy="supine, arms overhead: hands pressed into the ground behind the head sit the torso up while the legs swing up (jack-knife), the legs kick down and fold under while the arms push on (rocking momentum), the torso folds over the feet into a squat, stand",
        lying_joints=_LIE_FLAT | sym(sho_roll=-1.3),
        # Keyframe values and times found by a search in MuJoCo (a (1+1) evolution strategy, then
        # differential evolution, on all five players: stands on every one, then least torque
        # excess); the motion needs its momentum, so it is not retimed: its goals are pulled back
        # to what the servos can follow within the envelope by clamp_goal_lead.
        keyframes=(
            Keyframe(0.3, sym(sho_pitch=-0.4, hip_pitch=-0.2, knee=0.3)),  # end of the supine (connect) phase
            Keyframe(0.604, sym(sho_pitch=-0.7, hip_pitch=-1.8, knee=1.55)),  # hands press behind the head, legs up: the torso sits up
            Keyframe(1.374, sym(sho_pitch=-1.623, hip_pitch=-0.569, knee=2.6, ank_pitch=1.277)),  # legs kick down and fold under, arms push on
            Keyframe(1.624, sym(sho_pitch=-1.245, hip_pitch=-2.0, knee=2.6, ank_pitch=1.3)),  # torso folded forward over the feet
            Keyframe(2.031, sym(sho_pitch=-0.92, sho_roll=-0.081, el=0.0, hip_pitch=-0.763, knee=1.991, ank_pitch=1.087)),  # caught on the feet
            Keyframe(2.805, _STAND),
        ),
        connect_keyframe=0,
        retime=False,
        clamp_lead=True,
    ),
    MotionSpec(
        name="left_tip_forward",
        lying="left",
        strategy="left side, knees tucked: lower arm forward under the head, upper arm reaches forward and down, knees up: tip onto the front; arms to the T with the knees kept under, forearms set down, then elbows and shoulders push up and back onto the feet, squat, stand (prone_elbow_knees tail)",
        lying_joints=_LEFT_SIDE,
        keyframes=_LEFT_TIP + (Keyframe(2.8, _ELBOWS_KNEES),) + _elbow_knees_tail(2.8),
        connect_keyframe=0,
    ),
    MotionSpec(
        name="right_tip_forward",
        lying="right",
        strategy="mirror image of left_tip_forward: right side, knees tucked, tip onto the front, elbow push-up back onto the feet, squat, stand",
        lying_joints=mirror(_LEFT_SIDE),
        keyframes=mirror_keyframes(_LEFT_TIP + (Keyframe(2.8, _ELBOWS_KNEES),) + _elbow_knees_tail(2.8)),
        connect_keyframe=0,
    ),
)
