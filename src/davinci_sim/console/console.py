"""The surgeon console: foot pedals, console events, teleoperation selection (dvrk.md 2.3).

* Buttons: the pedals ``clutch``, ``camera``, ``cam_minus``, ``cam_plus``, ``bicoag``,
  ``coag`` and the head sensor ``operator_present``. Console events come with the Joy
  convention (``[1]`` pressed, ``[0]`` released, ``[2]`` quick tap) through
  ``emulate_<button>`` / :meth:`Console.button` (the dVRK's ``/console/emulate_*``), as they
  are. Raw inputs (:meth:`Console.press`/:meth:`Console.release`, and the buttons of master
  devices) are like the pedal hardware: a press shorter than ``tap_duration`` also produces a
  quick tap. Every event is published on the console's channel under the button's name with
  its Joy ``buttons`` list.
* Clutch press/release goes to every teleoperation; a quick tap swaps the first MTM that has
  exactly two PSM teleoperations (MTML: PSM2/PSM3) between them.
* Camera pressed: the PSM teleoperations are disabled (the PSMs hold) and the ECM
  teleoperation runs if the operator is present; released: back to the PSMs.
* The selected PSM teleoperations are enabled only while the operator is present; otherwise
  they are told ``align_MTM``. At start-up each teleoperation is selected unless it shares
  an arm with one selected before it (the first declared wins); selecting one unselects the
  others sharing an arm.
* ``teleop_enable``, ``set_scale`` (all teleoperations), ``select_teleop``/``unselect_teleop``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from davinci_sim.console.teleop_ecm import TeleopECM
from davinci_sim.console.teleop_math import as_scale
from davinci_sim.console.teleop_psm import TeleopPSM
from davinci_sim.devices.buttons import ButtonEvent, parse_button_event
from davinci_sim.sim.channels import Channels
from davinci_sim.sim.state import capture, restore
from davinci_sim.sim.types import ACCEPTED, CommandResult
from davinci_sim.sim.validation import short_repr

if TYPE_CHECKING:
    from davinci_sim.console.haptic_loop import HapticLoop
    from davinci_sim.devices.device import MasterDevice
    from davinci_sim.sim.simulation import Simulation

#: dvrk.md 2.3: the raw foot pedals (``/footpedals/<name>``) and the console's head sensor.
PEDALS = ("clutch", "camera", "cam_minus", "cam_plus", "bicoag", "coag")
BUTTONS = (*PEDALS, "operator_present")
#: Device button names that mean the head sensor (the dVRK 2.2 code calls it ``head``).
_ALIASES = {"head": "operator_present", "operatorpresent": "operator_present"}


@dataclass(frozen=True)
class ConsoleState:
    """What the console publishes (dvrk.md 2.3, ``/console/…``)."""

    teleop_enabled: bool
    scale: float
    buttons: dict[str, bool]
    """Button name -> pressed (pedals and ``operator_present``)."""
    selected: tuple[str, ...]
    unselected: tuple[str, ...]


class Console:
    """The console component (``"console"``); see the module docstring.

    Args:
        sim: the simulation.
        tap_duration: a raw press shorter than this (s) also counts as a quick tap; None:
            only explicit quick-tap events do.
        scale: initial scale of every teleoperation (None: keep each one's own).
    """

    name = "console"

    def __init__(
        self, sim: Simulation, *, tap_duration: float | None = 0.25, scale: float | None = None
    ) -> None:
        if tap_duration is not None and not (math.isfinite(tap_duration) and tap_duration > 0):
            raise ValueError(f"tap_duration must be a time > 0 in s or None, got {tap_duration!r}")
        self.sim = sim
        self.tap_duration = tap_duration
        self.channels = Channels(self.name)
        self.psm_teleops: dict[str, TeleopPSM] = {}
        self.ecm_teleop: TeleopECM | None = None
        self._pressed = dict.fromkeys(BUTTONS, False)
        self._pressed_at = dict.fromkeys(BUTTONS, -math.inf)
        self._teleop_enabled = False
        self._scale = scale
        self.haptics: HapticLoop | None = None
        """The haptic loop (set by :func:`~davinci_sim.console.install_console`)."""

    # ------------------------------------------------------------ set-up
    def add_teleop_psm(self, teleop: TeleopPSM) -> None:
        """Declare a PSM teleoperation (declaration order decides the initial selection)."""
        if teleop.name in self.psm_teleops:
            raise ValueError(f"teleoperation {teleop.name!r} already declared")
        self.psm_teleops[teleop.name] = teleop
        teleop.selected = not any(
            t.selected and _shares_arm(t, teleop)
            for t in self.psm_teleops.values()
            if t is not teleop
        )
        if self._scale is not None:
            teleop.set_scale(self._scale)
        teleop.clutch(self._pressed["clutch"])

    def set_teleop_ecm(self, teleop: TeleopECM) -> None:
        self.ecm_teleop = teleop
        if self._scale is not None:
            teleop.set_scale(self._scale)

    def teleops(self) -> dict[str, TeleopPSM | TeleopECM]:
        out: dict[str, TeleopPSM | TeleopECM] = dict(self.psm_teleops)
        if self.ecm_teleop is not None:
            out[self.ecm_teleop.name] = self.ecm_teleop
        return out

    def devices(self) -> list[MasterDevice]:
        """The master devices of the teleoperations, each once."""
        found: dict[int, MasterDevice] = {}
        for t in self.psm_teleops.values():
            found.setdefault(id(t.device), t.device)
        if self.ecm_teleop is not None:
            for d in (self.ecm_teleop.left, self.ecm_teleop.right):
                found.setdefault(id(d), d)
        return list(found.values())

    # ------------------------------------------------------------ dVRK console API
    def teleop_enable(self, enable: bool) -> CommandResult:
        """``/console/teleop/enable``: start or stop all teleoperation."""
        if not isinstance(enable, bool):
            return self._refuse("teleop/enable", f"needs a bool, got {enable!r}")
        self._teleop_enabled = enable
        self.channels.emit("teleop_enabled", enable)
        self._update_teleops()
        return ACCEPTED

    def teleop_enabled(self) -> bool:
        return self._teleop_enabled

    def set_scale(self, scale: float) -> CommandResult:
        """``/console/teleop/set_scale``: the scale of every teleoperation."""
        s = as_scale(scale)
        if not (0.0 < s <= 1.0):
            return self._refuse(
                "teleop/set_scale", f"scale must be in ]0, 1], got {short_repr(scale)}"
            )
        for t in self.teleops().values():
            t.set_scale(s)
        self._scale = s
        self.channels.emit("scale", s)
        return ACCEPTED

    def scale(self) -> float | None:
        """The last scale set for all teleoperations (None if never set)."""
        return self._scale

    def select_teleop(self, name: str) -> CommandResult:
        """``/console/teleop/select``: select ``name`` (unselects those sharing an arm)."""
        teleop = self.psm_teleops.get(name)
        if teleop is None:
            return self._refuse("teleop/select", self._unknown(name))
        for other in self.psm_teleops.values():
            if other is not teleop and other.selected and _shares_arm(other, teleop):
                other.selected = False
                self.channels.emit("teleop_unselected", other.name)
        if not teleop.selected:
            teleop.selected = True
            self.channels.emit("teleop_selected", name)
        self._update_teleops()
        return ACCEPTED

    def unselect_teleop(self, name: str) -> CommandResult:
        """``/console/teleop/unselect``."""
        teleop = self.psm_teleops.get(name)
        if teleop is None:
            return self._refuse("teleop/unselect", self._unknown(name))
        if teleop.selected:
            teleop.selected = False
            self.channels.emit("teleop_unselected", name)
        self._update_teleops()
        return ACCEPTED

    def selected_teleops(self) -> tuple[str, ...]:
        return tuple(n for n, t in self.psm_teleops.items() if t.selected)

    def emulate_clutch(self, event) -> CommandResult:
        """``/console/emulate_clutch`` (Joy ``[1]`` press, ``[0]`` release, ``[2]`` tap)."""
        return self.button("clutch", event)

    def emulate_camera(self, event) -> CommandResult:
        return self.button("camera", event)

    def emulate_operator_present(self, event) -> CommandResult:
        return self.button("operator_present", event)

    def emulate_coag(self, event) -> CommandResult:
        return self.button("coag", event)

    def button(self, name: str, event) -> CommandResult:
        """Any console button (:data:`BUTTONS`) with any event form of
        :func:`~davinci_sim.devices.buttons.parse_button_event`."""
        name = _ALIASES.get(name, name)
        if name not in self._pressed:
            return self._refuse("button", f"unknown button {name!r}; buttons: {list(BUTTONS)}")
        try:
            ev = parse_button_event(event)
        except ValueError as e:
            return self._refuse(f"emulate_{name}", str(e))
        self._handle(name, ev)
        return ACCEPTED

    def press(self, name: str) -> CommandResult:
        """A raw button/pedal goes down (hardware-like: see :meth:`release`)."""
        return self._raw(name, ButtonEvent.PRESSED)

    def release(self, name: str) -> CommandResult:
        """A raw button/pedal goes up; after a press shorter than ``tap_duration`` this also
        produces a quick tap (``[2]``), as the pedal hardware does."""
        return self._raw(name, ButtonEvent.RELEASED)

    def _raw(self, name: str, event: ButtonEvent) -> CommandResult:
        name = _ALIASES.get(name, name)
        if name not in self._pressed:
            return self._refuse("button", f"unknown button {name!r}; buttons: {list(BUTTONS)}")
        self._handle(name, event, raw=True)
        return ACCEPTED

    def is_pressed(self, name: str) -> bool:
        """Whether button ``name`` is held."""
        if name not in self._pressed:
            raise KeyError(f"unknown button {name!r}; buttons: {list(BUTTONS)}")
        return self._pressed[name]

    def operator_present(self) -> bool:
        return self._pressed["operator_present"]

    # ------------------------------------------------------------ component
    def pre_step(self, t: float) -> None:
        """Buttons of the master devices become console events."""
        for device in self.devices():
            for name, event in device.pop_button_events():
                name = _ALIASES.get(name, name)
                if name in self._pressed:
                    self._handle(name, event, raw=True)

    def snapshot(self) -> ConsoleState:
        return ConsoleState(
            teleop_enabled=self._teleop_enabled,
            scale=self._scale if self._scale is not None else math.nan,
            buttons=dict(self._pressed),
            selected=self.selected_teleops(),
            unselected=tuple(n for n, t in self.psm_teleops.items() if not t.selected),
        )

    # ------------------------------------------------------------ internals
    def _refuse(self, command: str, message: str) -> CommandResult:
        text = f"{command}: {message}"
        self.channels.message("error", text, self.sim.time)
        return CommandResult(False, f"{self.name}: {text}")

    def _unknown(self, name) -> str:
        return f"unknown teleoperation {name!r}; PSM teleoperations: {list(self.psm_teleops)}"

    def _handle(self, name: str, event: ButtonEvent, raw: bool = False) -> None:
        now = self.sim.time
        if event == ButtonEvent.CLICKED:
            self.channels.emit(name, event.to_joy())
            self._clicked(name)
            return
        pressed = event == ButtonEvent.PRESSED
        if pressed == self._pressed[name]:
            return  # repeated state: nothing changes
        self._pressed[name] = pressed
        self.channels.emit(name, event.to_joy())
        if pressed:
            self._pressed_at[name] = now
        if name == "clutch":
            for t in self.teleops().values():
                t.clutch(pressed)
        elif name in ("camera", "operator_present"):
            self._update_teleops()
        quick = self.tap_duration is not None and now - self._pressed_at[name] < self.tap_duration
        if raw and not pressed and quick:
            self.channels.emit(name, ButtonEvent.CLICKED.to_joy())
            self._clicked(name)

    def _clicked(self, name: str) -> None:
        if name != "clutch":
            return
        by_mtm: dict[str, list[TeleopPSM]] = {}
        for t in self.psm_teleops.values():
            by_mtm.setdefault(t.mtm_name, []).append(t)
        for teleops in by_mtm.values():
            if len(teleops) == 2:
                a, b = teleops
                self.select_teleop(b.name if a.selected else a.name)
                return

    def _update_teleops(self) -> None:
        camera = self._pressed["camera"]
        present = self._pressed["operator_present"]
        for t in self.psm_teleops.values():
            if self._teleop_enabled and t.selected and not camera:
                t.state_command("enable" if present else "align_MTM")
            else:
                t.state_command("disable")
        if self.ecm_teleop is not None:
            on = self._teleop_enabled and camera and present
            self.ecm_teleop.state_command("enable" if on else "disable")

    # ------------------------------------------------------------ state
    #: Buttons held and when they were pressed, teleoperation enabled, the scale (the
    #: teleoperations, devices and haptic loop are components with their own state).
    _STATE = ("_pressed", "_pressed_at", "_teleop_enabled", "_scale")

    def get_state(self) -> dict:
        return capture(self, self._STATE)

    def set_state(self, state: dict) -> None:
        restore(self, state, self._STATE)


def _shares_arm(a: TeleopPSM, b: TeleopPSM) -> bool:
    return a.mtm_name == b.mtm_name or a.psm_name == b.psm_name
