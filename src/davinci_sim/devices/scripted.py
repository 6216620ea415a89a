"""Scripted hands: a component that moves a simulated MTM's hand along a path.

For demos, benchmarks and tests: once ``when()`` is true (e.g. the teleoperation follows),
the hand grasps the handle where it is and its target becomes that position plus
``offset(t − t_start)`` (HRSV, m); ``gripper(t − t_start)`` sets the fingers. Register it
before the device so the new target is used in the same tick.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.sim.state import capture, restore


def circle(
    radius: float, frequency: float, axes: tuple[int, int] = (0, 1)
) -> Callable[[float], np.ndarray]:
    """Offset on a circle through the start point: ``radius`` m, ``frequency`` Hz, in the
    plane of the two HRSV ``axes`` (default x-y: the display plane)."""
    i, j = axes

    def offset(t: float) -> np.ndarray:
        a = 2.0 * math.pi * frequency * t
        out = np.zeros(3)
        out[i] = radius * (math.cos(a) - 1.0)
        out[j] = radius * math.sin(a)
        return out

    return offset


class HandScript:
    """Moves ``device``'s hand; see the module docstring.

    Args:
        device: the simulated MTM.
        offset: t (s since start) -> position offset in HRSV (3,), m.
        gripper: t -> gripper opening, rad (None: the fingers are left alone).
        when: start condition, checked every tick until true (None: start at once).
        name: component name (default ``"<device>/script"``).
    """

    def __init__(
        self,
        device: SimulatedMTM,
        offset: Callable[[float], np.ndarray],
        *,
        gripper: Callable[[float], float] | None = None,
        when: Callable[[], bool] | None = None,
        name: str | None = None,
    ) -> None:
        self.device = device
        self.offset = offset
        self.gripper = gripper
        self.when = when
        self.name = name or f"{device.name}/script"
        self._t0: float | None = None
        self._anchor = np.zeros(3)

    @property
    def started(self) -> bool:
        return self._t0 is not None

    def pre_step(self, t: float) -> None:
        if self._t0 is None:
            if self.when is not None and not self.when():
                return
            inp = self.device.input()
            T = inp.T_hrsv_tip if inp is not None else self.device.arm.measured_cp().T
            self._t0 = t
            self._anchor = T[:3, 3].copy()
            self.device.grasp(T)
        s = t - self._t0
        self.device.move_hand(self._anchor + np.asarray(self.offset(s), dtype=float))
        if self.gripper is not None:
            self.device.squeeze(self.gripper(s))

    def snapshot(self) -> dict:
        return {"started": self.started, "t_start": self._t0}

    def get_state(self) -> dict:
        """When the script started and where the hand was then."""
        return capture(self, ("_t0", "_anchor"))

    def set_state(self, state: dict) -> None:
        restore(self, state, ("_t0", "_anchor"))
