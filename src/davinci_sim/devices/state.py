"""Values a master input device reports: its input at one tick, and its published state."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np


def _frozen(a, shape: tuple[int, ...]) -> np.ndarray:
    """A read-only float array of ``shape`` (no copy if ``a`` already is one)."""
    if isinstance(a, np.ndarray) and not a.flags.writeable and a.dtype == float:
        arr = a
    else:
        arr = np.array(a, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"expected shape {shape}, got {arr.shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class DeviceInput:
    """What the operator's hand gives a master device at one tick.

    Frames: the display frame HRSV of the console (dvrk.md 1.5: x to the operator's left, y
    up, z away from the operator). The teleoperation maps motion in HRSV to tool motion in
    the camera frame with the same axes.
    """

    T_hrsv_tip: np.ndarray
    """Handle (tip) pose in HRSV, 4x4, m."""
    twist_hrsv_tip: np.ndarray
    """Handle velocity in HRSV axes: linear (m/s) then angular (rad/s), (6,)."""
    gripper: float
    """Gripper opening, rad (0 = closed, dvrk.md 4.1 ``gripper_scaling``)."""
    timestamp: float
    """Simulation time (s) at which this input was read."""
    buttons: Mapping[str, bool] = field(default_factory=dict)
    """Buttons on the device (name -> pressed), e.g. a gamepad's clutch button (a copy:
    changing it changes nothing)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_hrsv_tip", _frozen(self.T_hrsv_tip, (4, 4)))
        object.__setattr__(self, "twist_hrsv_tip", _frozen(self.twist_hrsv_tip, (6,)))
        object.__setattr__(self, "gripper", float(self.gripper))
        if self.buttons:
            object.__setattr__(self, "buttons", dict(self.buttons))

    @classmethod
    def _checked(cls, T_hrsv_tip: np.ndarray, twist_hrsv_tip: np.ndarray, gripper: float,
                 timestamp: float) -> DeviceInput:  # fmt: skip
        """An input of values known to be what ``__post_init__`` makes (read-only float
        arrays (4, 4) and (6,), a float gripper, no buttons), without checking them again:
        the console's compiled ticks make one per device and call (what a pass's Python
        costs)."""
        out = object.__new__(cls)
        out.__dict__.update(T_hrsv_tip=T_hrsv_tip, twist_hrsv_tip=twist_hrsv_tip,
                            gripper=gripper, timestamp=timestamp, buttons={})  # fmt: skip
        return out

    @property
    def position(self) -> np.ndarray:
        return self.T_hrsv_tip[:3, 3]

    @property
    def rotation(self) -> np.ndarray:
        return self.T_hrsv_tip[:3, :3]


@dataclass(frozen=True, eq=False)
class DeviceSnapshot:
    """A device's published state (``snapshot()``), for bridges and GUIs."""

    name: str
    kind: str
    """``simulated``, ``network`` or ``udp``."""
    input: DeviceInput | None
    """The last input, None before the first one."""
    ready: bool
    stale: bool
    """True when the watchdog tripped (network devices, dvrk.md 1.7)."""
    input_age: float
    """Simulation time since the last input, s (inf before the first)."""
    wrench: np.ndarray
    """Last wrench sent to the device (6,), N and N·m, HRSV axes."""
    wrench_limited: bool
    """Whether the safety limits clamped that wrench."""
