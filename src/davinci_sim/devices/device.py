"""The one interface of master input devices: pose, twist, gripper and buttons in; wrench out.

A teleoperation talks to its MTM only through a :class:`MasterDevice`, whatever is behind
it: the simulated MTM of the console model (:class:`~davinci_sim.devices.SimulatedMTM`), an
external program streaming the dVRK socket-streamer format
(:class:`~davinci_sim.devices.UDPJSONDevice`), or any code that pushes poses
(:class:`~davinci_sim.devices.NetworkDevice`: web console, ROS client mode, keyboard, gamepad,
a real MTM behind a bridge).

A device is a simulation component: ``pre_step(t)`` reads its input once per tick (before the
teleoperation uses it) and ``snapshot()`` publishes its state. Every wrench sent through
:meth:`MasterDevice.servo_cf` passes the safety limits (:mod:`davinci_sim.devices.safety`); a
device with a watchdog (network devices: 30 ms, the dVRK watchdog, dvrk.md 1.7) whose last
input is older than that is *stale*: it gets a zero wrench, refuses others, and the
teleoperation stops following it.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections import deque
from typing import ClassVar

import numpy as np

from davinci_sim.devices.buttons import ButtonEvent
from davinci_sim.devices.safety import WrenchLimiter, WrenchLimits
from davinci_sim.devices.state import DeviceInput, DeviceSnapshot
from davinci_sim.sim.channels import Channels
from davinci_sim.sim.state import capture, restore
from davinci_sim.sim.types import ACCEPTED, CommandResult

#: dvrk.md 1.7: the dVRK watchdog, s.
DVRK_WATCHDOG = 0.030


class MasterDevice(ABC):
    """Base class of master devices; see the module docstring.

    Args:
        name: component name, e.g. ``"MTMR/device"``.
        limits: safety limits on the wrench sent to the device.
        dt: tick period of the loop that sends wrenches, s (the rate limit uses it).
        watchdog: maximum age of the last input, s, or None for no watchdog.
    """

    kind: ClassVar[str] = "device"
    can_align: ClassVar[bool] = False
    """True if the teleoperation can move the device to an orientation (``move_cp``)."""
    is_haptic: ClassVar[bool] = False
    """True if the device renders wrenches."""

    def __init__(
        self,
        name: str,
        *,
        limits: WrenchLimits | None = None,
        dt: float = 0.001,
        watchdog: float | None = None,
    ) -> None:
        if watchdog is not None and not (math.isfinite(watchdog) and watchdog > 0):
            raise ValueError(f"watchdog must be a time > 0 in s or None, got {watchdog!r}")
        self.name = name
        self.channels = Channels(name)
        self.watchdog = watchdog
        self._limiter = WrenchLimiter(limits, dt)
        self._input: DeviceInput | None = None
        self._now = -math.inf
        self._wrench = np.zeros(6)
        self._was_stale = False
        self._buttons: deque[tuple[str, ButtonEvent]] = deque(maxlen=256)

    # ------------------------------------------------------------ component
    def pre_step(self, t: float) -> None:
        """Read the device's input for this tick (called by the simulation)."""
        self._now = t
        new = self._read(t)
        if new is not None:
            self._input = new
        stale = self.is_stale()
        if stale and not self._was_stale:
            self.zero_wrench()
            # Before the first input this is the normal start, not a lost connection.
            age = (
                "no input yet"
                if self._input is None
                else f"last input is {1000 * self.input_age():.0f} ms old"
            )
            self.channels.message(
                "error",
                f"watchdog: {age} (limit {1000 * self.watchdog:.0f} ms, dvrk.md 1.7); "
                "wrench zeroed",
                t,
            )
        elif self._was_stale and not stale:
            self.channels.message("status", "input resumed", t)
        self._was_stale = stale

    def snapshot(self) -> DeviceSnapshot:
        return DeviceSnapshot(
            name=self.name,
            kind=self.kind,
            input=self._input,
            ready=self.is_ready(),
            stale=self.is_stale(),
            input_age=self.input_age(),
            wrench=self.wrench(),
            wrench_limited=self._limiter.active,
        )

    # ------------------------------------------------------------ input
    def input(self) -> DeviceInput | None:
        """The last input read (None before the first)."""
        return self._input

    def input_age(self) -> float:
        """Simulation time since the last input, s (inf before the first)."""
        if self._input is None:
            return math.inf
        return self._now - self._input.timestamp

    def is_stale(self) -> bool:
        """True when the device has a watchdog and its last input is older than it."""
        if self.watchdog is None:
            return False
        return self.input_age() > self.watchdog + 1e-9

    def pop_button_events(self) -> list[tuple[str, ButtonEvent]]:
        """Button events since the last call, oldest first (the console consumes them)."""
        events = list(self._buttons)
        self._buttons.clear()
        return events

    def _queue_button(self, name: str, event: ButtonEvent) -> None:
        self._buttons.append((name, event))

    # ------------------------------------------------------------ readiness
    @abstractmethod
    def is_ready(self) -> bool:
        """True when the device can be teleoperated with (powered/homed, fresh input)."""

    def not_ready_reason(self) -> str:
        """Why :meth:`is_ready` is false, for messages (``""`` when ready)."""
        if self.is_ready():
            return ""
        if self._input is None:
            return "no input received yet"
        if self.is_stale():
            return f"input is {1000 * self.input_age():.0f} ms old (watchdog)"
        return "not ready"

    def prepare(self) -> None:
        """Ask the device to become ready (power on and home a motorised MTM)."""
        return  # nothing to do for a device without motors

    def is_busy(self) -> bool:
        """True while the device is moving on its own (alignment)."""
        return False

    # ------------------------------------------------------------ modes (dVRK MTM API)
    def move_cp(self, T_hrsv_tip) -> CommandResult:
        """Move the handle to ``T_hrsv_tip`` (alignment); only devices with ``can_align``."""
        return CommandResult(False, f"{self.name}: a {self.kind} device cannot be moved")

    def hold(self) -> None:
        """Keep the handle where it is (position control) if the device can; in any case
        stop rendering wrenches (teleoperation ends)."""
        self.zero_wrench()

    def _wrench_dropped(self) -> None:
        """The device left effort mode by itself: no wrench is rendered any more."""
        self._limiter.reset()
        self._wrench = np.zeros(6)

    def enter_effort_mode(self) -> None:
        """Gravity compensation and a zero wrench: the hand moves the handle (teleop on)."""
        self.zero_wrench()

    def lock_orientation(self, R_hrsv_tip) -> None:
        """Hold the handle's orientation in effort mode (motorised devices only)."""
        return  # nothing to do for a device without motors

    def unlock_orientation(self) -> None:
        """Let the handle turn freely in effort mode."""
        return  # nothing to do for a device without motors

    # ------------------------------------------------------------ wrench out
    def servo_cf(self, wrench) -> CommandResult:
        """Wrench on the operator's hand (6,): force (N) then torque (N·m) in HRSV axes.

        Clamped to the device's safety limits (magnitude and rate of change). Refused (and
        nothing changes) for a non-finite or mis-shaped wrench, and refused with a zero wrench
        kept while the device is stale.
        """
        try:
            w = np.asarray(wrench, dtype=float)
        except (TypeError, ValueError):
            w = None
        if w is None or w.shape != (6,) or not np.isfinite(w).all():
            text = f"servo_cf: wrench must be 6 finite numbers (N, N·m), got {wrench!r}"
            self.channels.message("error", text, self._now)
            return CommandResult(False, f"{self.name}: {text}")
        return self._render_wrench(w)

    def _render_wrench(self, w: np.ndarray) -> CommandResult:
        """:meth:`servo_cf` of a wrench already checked (6 finite floats, e.g. the haptic
        loop's sum of checked fields): validated once, at the edge it came in by."""
        if self.is_stale():
            return CommandResult(False, f"{self.name}: servo_cf: device is stale (watchdog)")
        out = self._limiter.limit_checked(w)
        self._wrench = out
        self._apply_wrench(out)
        return ACCEPTED

    def zero_wrench(self) -> None:
        """Cut the wrench to zero at once (safety stop, clutch); the rate limit restarts."""
        self._limiter.reset()
        self._wrench = np.zeros(6)
        self._apply_wrench(self._wrench)

    def wrench(self) -> np.ndarray:
        """The last wrench sent (6,), N and N·m, HRSV axes."""
        return self._wrench.copy()

    @property
    def limits(self) -> WrenchLimits:
        return self._limiter.limits

    # ------------------------------------------------------------ implementation
    @abstractmethod
    def _read(self, t: float) -> DeviceInput | None:
        """This tick's input, or None if nothing new arrived."""

    @abstractmethod
    def _apply_wrench(self, wrench: np.ndarray) -> None:
        """Render the (already limited) wrench."""

    # ------------------------------------------------------------ state
    #: What :meth:`get_state` saves (subclasses add theirs): the last input, the device's
    #: clock, the wrench sent, the watchdog's memory, queued button events; the safety
    #: limiter's previous wrench and whether it is limiting are added by get_state.
    _STATE: tuple[str, ...] = ("_input", "_now", "_wrench", "_was_stale", "_buttons")

    def get_state(self) -> dict:
        """The device's state (:mod:`davinci_sim.sim.state`), deep-copied."""
        state = capture(self, self._STATE)
        state["limiter"] = (self._limiter.previous.copy(), bool(self._limiter.active))
        return state

    def set_state(self, state: dict) -> None:
        state = dict(state)
        previous, active = state.pop("limiter")
        self._limiter.previous, self._limiter.active = previous.copy(), active
        restore(self, state, self._STATE)
