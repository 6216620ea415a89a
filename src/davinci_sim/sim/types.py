"""Values the arm API returns: joint states, poses, twists, operating state, command results.

They mirror the CRTK/ROS messages the dVRK publishes (dvrk.md 2.2): ``sensor_msgs/JointState``,
``geometry_msgs/PoseStamped``, ``TwistStamped``, ``WrenchStamped``, ``crtk_msgs/OperatingState``.
Timestamps are simulation time in s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _readonly(a: np.ndarray | None) -> np.ndarray | None:
    if a is None:
        return None
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class JointState:
    """Joint positions (rad or m), velocities (rad/s or m/s), efforts (N·m or N)."""

    name: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray | None = None
    effort: np.ndarray | None = None
    timestamp: float = 0.0

    def __post_init__(self) -> None:
        for f in ("position", "velocity", "effort"):
            object.__setattr__(self, f, _readonly(getattr(self, f)))


@dataclass(frozen=True, eq=False)
class CartesianPose:
    """``T_reference_moving`` (4x4, m) like a ``PoseStamped`` with its frame names."""

    T: np.ndarray
    reference_frame: str
    moving_frame: str
    timestamp: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "T", _readonly(self.T))

    @property
    def position(self) -> np.ndarray:
        return self.T[:3, 3]

    @property
    def rotation(self) -> np.ndarray:
        return self.T[:3, :3]


@dataclass(frozen=True, eq=False)
class CartesianTwist:
    """Linear (m/s) then angular (rad/s) velocity, like a ``TwistStamped``."""

    twist: np.ndarray
    reference_frame: str
    moving_frame: str
    timestamp: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "twist", _readonly(self.twist))


@dataclass(frozen=True)
class OperatingState:
    """``crtk_msgs/OperatingState`` (dvrk.md 2.4)."""

    state: str
    is_homed: bool
    is_busy: bool
    timestamp: float = 0.0


@dataclass(frozen=True)
class CommandResult:
    """Outcome of a command: accepted or refused with the message sent to the error channel."""

    accepted: bool
    message: str = ""

    def __bool__(self) -> bool:
        return self.accepted


ACCEPTED = CommandResult(True)


@dataclass(frozen=True)
class ArmMessage:
    """A message on an arm's ``error``, ``warning`` or ``status`` channel."""

    level: str
    text: str
    timestamp: float = field(default=0.0)
