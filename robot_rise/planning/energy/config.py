"""The energy planner's parameters: the energy and Algorithms 1-2, and the section 6.2 second stage.

Every default is a number of robot_rise/constants.py, with paper 004's value or an "ours" reason
beside it; this module only gathers them into two frozen dataclasses.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from robot_rise.constants import (
    ENERGY_CONSTRAINT_GAMMA,
    ENERGY_CONSTRAINT_OMEGA,
    ENERGY_DESCENT_BETA,
    ENERGY_EXTERNAL_EXPONENT,
    ENERGY_EXTERNAL_WEIGHT,
    ENERGY_FALLOFF_D,
    ENERGY_LOCAL_MINIMUM_PATIENCE,
    ENERGY_MAX_ITERATIONS,
    ENERGY_SOFTENING_M,
    ENERGY_STEP_RAD,
    ENERGY_VERIFY_RESOLUTION_M,
    ENERGY_WINDOW_FRACTION,
    GLI_SAFE_ZONE_THRESHOLD,
    ROOT_TRANSLATION_SCALE_M,
    SECOND_STAGE_FRAME_SPACING_RAD,
    SECOND_STAGE_HALVINGS,
    SECOND_STAGE_ITERATIONS,
    SECOND_STAGE_TOLERANCE_RAD,
    SECOND_STAGE_W_LAP,
    SECOND_STAGE_W_LM,
)

__all__ = ["EnergyConfig", "SecondStageConfig"]


@dataclass(frozen=True)
class SecondStageConfig:
    """Parameters of the section 6.2 projection (``second_stage``; defaults in robot_rise/constants.py).

    Attributes:
        iterations: maximum iterations (paper: 30).
        frame_spacing_rad: the first-stage motion is resampled so that consecutive frames are at
            most this far apart in the scaled tangent space [rad].
        w_lap: weight of the trajectory Laplacian (second difference of the frames), eq. (19).
        w_lm: weight of the linear-momentum deviation of eq. (18) (CoM second difference).
        halvings: step halvings of a frame made illegal before it keeps its previous posture.
        tolerance_rad: stop when no frame moves more than this [rad].
    """

    iterations: int = SECOND_STAGE_ITERATIONS
    frame_spacing_rad: float = SECOND_STAGE_FRAME_SPACING_RAD
    w_lap: float = SECOND_STAGE_W_LAP
    w_lm: float = SECOND_STAGE_W_LM
    halvings: int = SECOND_STAGE_HALVINGS
    tolerance_rad: float = SECOND_STAGE_TOLERANCE_RAD

    def __post_init__(self) -> None:
        if self.frame_spacing_rad <= 0 or self.w_lap < 0 or self.w_lm < 0 or self.iterations < 0 or self.halvings < 0:
            raise ValueError("second stage: spacing must be positive; weights, iterations and halvings non-negative")


@dataclass(frozen=True)
class EnergyConfig:
    """Parameters of the energy and of Algorithms 1-2 (defaults in robot_rise/constants.py).

    Attributes:
        falloff_d: fall-off exponent d of eq. (1) (paper: 2..5).
        external_exponent: exponent of eq. (2) (paper: 2).
        softening_m: softening length of the surface distance [m] (ours).
        external_weight: weight of E_ext against E_int (paper: 1).
        step_rad: step length alpha of eq. (4)-(5) in the scaled tangent space [rad].
        descent_beta: extra descent on a projected step, fraction of alpha (ours).
        gli_threshold: safe-zone threshold of eq. (8) (paper: 0.3).
        use_safe_zone: take linear steps inside the safe zone (section 5.2.2).
        patience: local-minimum iterations of section 8 (paper: 50).
        window_fraction: height of the energy window, fraction of its top energy (ours).
        gamma, omega: eq. (10)-(11) constants (paper: 0.01, -0.01).
        max_iterations: hard cap on iterations.
        verify_resolution_m: travel bound between checked postures of the output path [m].
        root_translation_scale_m: metres of root travel that count as one radian (ours).
        move_root: let the energy move the root (position and orientation); if False, the root
            follows the straight interpolation only and the energy acts on the joints.
        ground_contacts: when every plain attempt of an iteration is rejected, repeat them with
            the touched ground as positional constraints (Algorithm 2; ours: automatic contacts).
        keyframes: ``plan_energy`` returns the key postures of each leg (``safe_zone_keyframes``,
            section 5.2) instead of every alpha step.
        straighten_limbs: undo the expansion of the root and of each linkage that a leg's key
            postures do not need (``straighten_limbs``; ours, section 5.1's "unnecessary
            expansion"), before the second stage.
        dense_output: write the second stage's motion out densely (``dense_output``).
        second_stage: project each leg's motion by ``second_stage`` (section 6.2); on by default
            (None: off). On by measurement (BENCHMARKS.md, issue 7, first round): through the
            shared smoother it was smoother than the key postures alone on 58/60 lying problems
            and 15/15 crossed-limb problems (dimensionless jerk, median ratio 0.05). With the
            straightening and the dense output (second round) the planner is the smoothest of
            the three benchmarked at a common duration on all 75 problems.
    """

    falloff_d: int = ENERGY_FALLOFF_D
    external_exponent: int = ENERGY_EXTERNAL_EXPONENT
    softening_m: float = ENERGY_SOFTENING_M
    external_weight: float = ENERGY_EXTERNAL_WEIGHT
    step_rad: float = ENERGY_STEP_RAD
    descent_beta: float = ENERGY_DESCENT_BETA
    gli_threshold: float = GLI_SAFE_ZONE_THRESHOLD
    use_safe_zone: bool = True
    patience: int = ENERGY_LOCAL_MINIMUM_PATIENCE
    window_fraction: float = ENERGY_WINDOW_FRACTION
    gamma: float = ENERGY_CONSTRAINT_GAMMA
    omega: float = ENERGY_CONSTRAINT_OMEGA
    max_iterations: int = ENERGY_MAX_ITERATIONS
    verify_resolution_m: float = ENERGY_VERIFY_RESOLUTION_M
    root_translation_scale_m: float = ROOT_TRANSLATION_SCALE_M
    move_root: bool = True
    ground_contacts: bool = True
    keyframes: bool = True
    straighten_limbs: bool = True
    dense_output: bool = True
    second_stage: SecondStageConfig | None = field(default_factory=SecondStageConfig)

    def __post_init__(self) -> None:
        if self.falloff_d < 1:
            raise ValueError(f"falloff_d must be >= 1 (paper 004 section 4.2), got {self.falloff_d}")
        if self.softening_m <= 0 or self.step_rad <= 0 or self.verify_resolution_m <= 0:
            raise ValueError("softening_m, step_rad and verify_resolution_m must be positive")
