"""A master device fed by pushed samples: the plug for remote and non-motorised inputs.

The web console, the ROS client mode, a keyboard, mouse or gamepad driver, or a bridge to a
real MTM call :meth:`NetworkDevice.push` (through ``SimHandle.call("<name>", "push", ...)``
from another thread or process) with the handle pose in HRSV, the gripper angle, optional
twist and button events; they read the wrench to render back with :meth:`wrench` (or
``snapshot()``). The device has the dVRK watchdog: if no pose arrives for 30 ms (dvrk.md 1.7)
it is stale, gets a zero wrench, and the teleoperation stops following it.

Such devices cannot be moved by the teleoperation, so ``align_MTM`` does not apply to them:
the alignment offset absorbs any orientation difference (dvrk.md 4.2).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from davinci_sim.devices.buttons import parse_button_event
from davinci_sim.devices.device import DVRK_WATCHDOG, MasterDevice
from davinci_sim.devices.safety import WrenchLimits
from davinci_sim.devices.state import DeviceInput
from davinci_sim.geometry import so3
from davinci_sim.sim.types import ACCEPTED, CommandResult
from davinci_sim.sim.validation import as_transform, as_twist, as_vector

#: A remote gripper opening beyond one turn is an error (the MTM's gripper spans 0 to 60°,
#: dvrk.md 1.5).
MAX_GRIPPER_RAD = 2 * np.pi


class NetworkDevice(MasterDevice):
    """A master device whose input is pushed by external code; see the module docstring.

    Args:
        name: component name, e.g. ``"MTMR/device"``.
        watchdog: maximum age of the last pose, s (dvrk.md 1.7: 30 ms); None disables it.
        limits: safety limits on the wrench sent back.
        dt: tick period, s.
        clock: returns the current simulation time, used to stamp pushes that arrive
            between ticks (default: the time of the last tick the device saw).
    """

    kind = "network"
    is_haptic = True

    def __init__(
        self,
        name: str,
        *,
        watchdog: float | None = DVRK_WATCHDOG,
        limits: WrenchLimits | None = None,
        dt: float = 0.001,
        clock: Callable[[], float] | None = None,
    ) -> None:
        super().__init__(name, limits=limits, dt=dt, watchdog=watchdog)
        self._clock = clock
        self._T: np.ndarray | None = None
        self._T_time = 0.0
        self._twist: np.ndarray | None = None
        self._gripper = 0.0
        self._pressed: dict[str, bool] = {}
        self._fresh = False
        self._prev_T: np.ndarray | None = None
        self._prev_T_time = 0.0

    def _time(self) -> float:
        return self._clock() if self._clock is not None else max(self._now, 0.0)

    def push(
        self,
        T_hrsv_tip=None,
        *,
        gripper: float | None = None,
        twist=None,
        buttons: Mapping | None = None,
    ) -> CommandResult:
        """New input from the remote device; any part may be omitted (kept from before).

        Args:
            T_hrsv_tip: handle pose in HRSV, 4x4, m. Only a pose refreshes the watchdog.
            gripper: gripper opening, rad.
            twist: handle twist in HRSV axes (6,), m/s then rad/s; if never given, it is
                estimated from successive poses.
            buttons: button name -> event (True/False, Joy ``[1]``/``[0]``/``[2]``, ...);
                the console acts on ``clutch``, ``camera``, ``coag``, ``operator_present`` …

        Returns:
            A refused result (and nothing changed) if any part is invalid.
        """
        T = tw = None
        if T_hrsv_tip is not None:
            T, msg = as_transform(T_hrsv_tip, "pose")
            if T is None:
                return self._refuse_push(msg)
        if twist is not None:
            tw, msg = as_twist(twist, "twist")
            if tw is None:
                return self._refuse_push(msg)
        if gripper is not None:
            g, msg = as_vector([gripper] if np.ndim(gripper) == 0 else gripper, 1, "gripper")
            if g is None:
                return self._refuse_push(msg)
            if not abs(g[0]) <= MAX_GRIPPER_RAD:
                return self._refuse_push(
                    f"gripper = {g[0]:.4g} rad is beyond ±{MAX_GRIPPER_RAD:.4g} rad (one turn)"
                )
            gripper = float(g[0])
        events = []
        if buttons is not None:
            if not isinstance(buttons, Mapping):
                return self._refuse_push(
                    f"buttons must be a mapping name -> event, got {buttons!r}"
                )
            try:
                events = [(str(k), parse_button_event(v)) for k, v in buttons.items()]
            except ValueError as e:
                return self._refuse_push(str(e))
        now = self._time()
        if T is not None:
            self._prev_T, self._prev_T_time = self._T, self._T_time
            self._T, self._T_time = T.copy(), now
        if tw is not None:
            self._twist = tw.copy()
        if gripper is not None:
            self._gripper = gripper
        for name, event in events:
            self._queue_button(name, event)
            if event.name != "CLICKED":
                self._pressed[name] = event.name == "PRESSED"
        self._fresh = self._fresh or T is not None or tw is not None or gripper is not None
        return ACCEPTED

    def _refuse_push(self, message: str) -> CommandResult:
        text = f"push: {message}"
        self.channels.message("error", text, self._time())
        return CommandResult(False, f"{self.name}: {text}")

    def _estimated_twist(self) -> np.ndarray:
        if self._prev_T is None or self._T is None or self._T_time <= self._prev_T_time:
            return np.zeros(6)
        dt = self._T_time - self._prev_T_time
        v = (self._T[:3, 3] - self._prev_T[:3, 3]) / dt
        w = so3.rotation_vector(self._T[:3, :3] @ self._prev_T[:3, :3].T) / dt
        return np.concatenate([v, w])

    def _read(self, t: float) -> DeviceInput | None:
        if not self._fresh or self._T is None:
            return None
        self._fresh = False
        twist = self._twist if self._twist is not None else self._estimated_twist()
        return DeviceInput(self._T, twist, self._gripper, self._T_time, self._pressed)

    def is_ready(self) -> bool:
        return self._input is not None and not self.is_stale()

    def _apply_wrench(self, wrench: np.ndarray) -> None:
        """The remote reads it with :meth:`wrench` (subclasses also send it)."""

    # ------------------------------------------------------------ state
    _STATE = MasterDevice._STATE + (
        "_T",
        "_T_time",
        "_twist",
        "_gripper",
        "_pressed",
        "_fresh",
        "_prev_T",
        "_prev_T_time",
    )
