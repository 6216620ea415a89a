"""Configuration of the teleoperations, with the dVRK's keys and defaults (dvrk.md 4.1)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass


def _check_positive(owner: str, name: str, value, *, allow_zero: bool = False) -> None:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{owner}.{name} must be a finite number {bound}, got {value!r}")


@dataclass(frozen=True)
class TeleopPSMConfig:
    """PSM teleoperation settings (``configure_parameter`` of a dVRK ``teleop_PSMs`` entry,
    dvrk.md 4.1, HEAD/2.4 defaults). Angles in rad, rates in rad/s, times in s."""

    scale: float = 0.2
    """Translation scale MTM -> PSM, in ]0, 1]. The seed paper's path task used 0.6."""
    align_mtm: bool = True
    """Drive the MTM orientation to the PSM's before following (``align_MTM``)."""
    rotation_locked: bool = False
    translation_locked: bool = False
    start_orientation_tolerance: float = math.radians(5.0)
    """Largest MTM/PSM orientation difference (axis-angle) to start following."""
    start_gripper_threshold: float = math.radians(40.0)
    """Gripper motion range that shows the operator is there (0: always)."""
    start_roll_threshold: float = math.radians(4.0)
    """Roll motion range that shows the operator is there."""
    ignore_jaw: bool = False
    jaw_rate: float = 4.0 * math.pi
    """Fastest the jaw goal may follow the gripper (720°/s)."""
    jaw_rate_after_clutch: float = 0.2 * math.pi
    """Same, after a clutch release until the jaw caught up (36°/s)."""
    use_mtm_linear_velocity: bool = True
    """Send the scaled MTM linear velocity with ``servo_cp`` (velocity feed-forward)."""
    use_mtm_angular_velocity: bool = False
    gripper_zero: float = 0.0
    """MTM gripper angle for a just-closed jaw (``gripper_scaling.zero``)."""
    gripper_max: float = math.radians(60.0)
    """MTM gripper angle for the jaw's maximum (``gripper_scaling.max``, 1.0472)."""
    mtm_is_haptic: bool = True
    """Use the MTM's effort modes (gravity compensation, wrench, orientation lock)."""
    setting_arms_timeout: float = 60.0
    """SETTING_ARMS_STATE gives up after this long (dvrk.md 4.2)."""
    warning_interval: float = 2.0
    """Repeated ALIGNING_MTM warnings, every this long (dvrk.md 4.2)."""

    def __post_init__(self) -> None:
        owner = type(self).__name__
        _check_positive(owner, "scale", self.scale)
        if self.scale > 1.0:
            raise ValueError(f"{owner}.scale must be in ]0, 1] (dvrk.md 4.1), got {self.scale!r}")
        for name in ("start_gripper_threshold", "start_roll_threshold"):
            _check_positive(owner, name, getattr(self, name), allow_zero=True)
        for name in (
            "start_orientation_tolerance",
            "jaw_rate",
            "jaw_rate_after_clutch",
            "setting_arms_timeout",
            "warning_interval",
        ):
            _check_positive(owner, name, getattr(self, name))
        for name in ("gripper_zero", "gripper_max"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise ValueError(f"{owner}.{name} must be a finite angle in rad, got {value!r}")
        if not self.gripper_max > self.gripper_zero:
            raise ValueError(
                f"{owner}: gripper_max ({self.gripper_max!r}) must exceed gripper_zero "
                f"({self.gripper_zero!r})"
            )

    def replace(self, **changes) -> TeleopPSMConfig:
        """A copy with ``changes`` (validated)."""
        return dataclasses.replace(self, **changes)


SIMULATED_SYSTEM = TeleopPSMConfig(start_gripper_threshold=0.0)
"""The dVRK's simulated full system sets ``start_gripper_threshold`` 0, so teleoperation
starts without pinching the gripper (dvrk.md 4.1); the console uses this by default."""


@dataclass(frozen=True)
class TeleopECMConfig:
    """ECM teleoperation (camera control with both MTMs) settings.

    The dVRK documents only the scale (default 0.2, dvrk.md 4.3); the hand geometry and the
    haptic constants below are the ones the dVRK's ``mtsTeleOperationECM`` uses (read for
    this issue): a 150 N/m spring keeps the hands' relative placement and a viscous friction
    of 10/10/40 N·s/m (HRSV x/y/z) steadies them.
    """

    scale: float = 0.2
    """Insertion per change of the hands' distance from the eyes (m/m)."""
    hands_stiffness: float = 150.0
    """N/m."""
    hands_friction: tuple[float, float, float] = (10.0, 10.0, 40.0)
    """N·s/m along HRSV x, y, z."""
    haptic_feedback_ratio: float = 1.0
    """Scales the wrench on the hands (0: none)."""
    camera_roll_offset: float = 0.0
    """Roll between the ECM and the endoscope image, rad."""
    setting_arms_timeout: float = 60.0

    def __post_init__(self) -> None:
        owner = type(self).__name__
        _check_positive(owner, "scale", self.scale)
        _check_positive(owner, "hands_stiffness", self.hands_stiffness, allow_zero=True)
        _check_positive(owner, "haptic_feedback_ratio", self.haptic_feedback_ratio, allow_zero=True)
        _check_positive(owner, "setting_arms_timeout", self.setting_arms_timeout)
        if len(self.hands_friction) != 3:
            raise ValueError(f"{owner}.hands_friction needs 3 values, got {self.hands_friction!r}")
        for b in self.hands_friction:
            _check_positive(owner, "hands_friction", b, allow_zero=True)
        if not math.isfinite(self.camera_roll_offset):
            raise ValueError(f"{owner}.camera_roll_offset must be finite")

    def replace(self, **changes) -> TeleopECMConfig:
        return dataclasses.replace(self, **changes)
