"""What the PSM and ECM teleoperations share: their state getters (dvrk.md 4.3), refusals on
the error channel, and the events of their desired state and following flag."""

from __future__ import annotations

from typing import TYPE_CHECKING

from davinci_sim.sim.types import CommandResult

if TYPE_CHECKING:
    from davinci_sim.sim.channels import Channels
    from davinci_sim.sim.simulation import Simulation


class TeleopBase:
    """Base of :class:`~davinci_sim.console.TeleopPSM` and
    :class:`~davinci_sim.console.TeleopECM`; the subclass sets the attributes below."""

    name: str
    sim: Simulation
    channels: Channels
    _current: str
    _desired: str
    _following: bool
    _clutched: bool
    _scale: float

    def current_state(self) -> str:
        return self._current

    def desired_state(self) -> str:
        return self._desired

    def is_following(self) -> bool:
        return self._following

    def scale(self) -> float:
        return self._scale

    def is_clutched(self) -> bool:
        return self._clutched

    def _now(self) -> float:
        return self.sim.time

    def _error(self, text: str) -> None:
        self.channels.message("error", text, self._now())

    def _refuse(self, command: str, message: str) -> CommandResult:
        """Refuse ``command``: the message on the error channel and in the result."""
        text = f"{command}: {message}"
        self._error(text)
        return CommandResult(False, f"{self.name}: {text}")

    def _set_desired(self, desired: str) -> None:
        if desired != self._desired:
            self._desired = desired
            self.channels.emit("desired_state", desired)

    def _set_following(self, following: bool) -> None:
        if following != self._following:
            self._following = following
            self.channels.emit("following", following)
