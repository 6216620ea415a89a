"""The dVRK system topics over the bridge (dvrk.md §2.3): power, homing, volume, sounds.

Scripts written for a real dVRK start with the system: ``/system/power_on``,
``/system/home`` (``std_msgs/Empty``; the 2.2 names ``/console/power_on``, ``/console/home``,
``/console/power_off`` too). Here they act on every arm of the simulation through the
handle: ``power_on`` enables the arms, ``home`` enables and homes them, ``power_off``
disables them. ``/system/set_volume`` (``std_msgs/Float64`` in [0, 1]) sets the value
``/system/volume`` publishes (latched). The simulator makes no sound: ``/system/beep``
(``std_msgs/Float64MultiArray``: duration s, frequency Hz, volume) and
``/system/string_to_speech`` (``std_msgs/String``) are checked and logged, so that scripts
that use them run unchanged.
"""

from __future__ import annotations

import asyncio
import logging
import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from davinci_sim.bridge.rosbridge.core import Bridge
    from davinci_sim.bridge.rosbridge.session import Session
    from davinci_sim.sim.handle import SimHandle

_log = logging.getLogger("davinci_sim.bridge")

NODE = "/davinci_sim/system"
#: Topic → the arms' ``state_command`` sequence it runs (dvrk.md §2.3; 2.2 names under
#: ``/console``).
COMMANDS = {
    "power_on": ("enable",),
    "home": ("enable", "home"),
    "power_off": ("disable",),
}


class SystemNode:
    """Serves ``/system/*`` for ``handle``'s simulation (see the module docstring)."""

    def __init__(self, handle: SimHandle, *, volume: float = 0.5) -> None:
        self.handle = handle
        self.volume = float(volume)

    def attach(self, bridge: Bridge) -> None:
        self.bridge = bridge
        self.loop = asyncio.get_running_loop()
        for name, commands in COMMANDS.items():
            for prefix in ("/system", "/console"):
                bridge.listen(f"{prefix}/{name}", "std_msgs/Empty", self._power(name, commands),
                              node=NODE)  # fmt: skip
        self._volume = bridge.advertise("/system/volume", "std_msgs/Float64", node=NODE,
                                        latch=True)  # fmt: skip
        bridge.publish(self._volume, {"data": self.volume})
        bridge.listen("/system/set_volume", "std_msgs/Float64", self._set_volume, node=NODE)
        bridge.listen("/system/beep", "std_msgs/Float64MultiArray", self._beep, node=NODE)
        bridge.listen("/system/string_to_speech", "std_msgs/String", self._speech, node=NODE)

    async def detach(self) -> None:
        self.bridge.remove_node(NODE)

    # ------------------------------------------------------------------ power and homing
    def _power(self, name: str, commands: tuple[str, ...]):
        def on_message(msg: dict, session: Session | None) -> None:
            arms = list(self.handle.snapshot().arms)
            for arm in arms:
                for command in commands:  # queued in order: the loop runs them in order
                    future = self.handle.call(arm, "state_command", command)
                    future.add_done_callback(
                        lambda f, a=arm, c=command: self.loop.call_soon_threadsafe(
                            self._done, f"{name}: {a} {c}", session, f
                        )
                    )
            _log.info("system %s: %s on %s", name, "+".join(commands), ", ".join(arms))

        return on_message

    def _done(self, what: str, session: Session | None, future) -> None:
        exc = future.exception()
        result = None if exc is not None else future.result()
        if exc is None and getattr(result, "accepted", True):
            return
        self._report(session, f"/system/{what}: {exc if exc is not None else result.message}")

    # ------------------------------------------------------------------ volume and sounds
    def _set_volume(self, msg: dict, session: Session | None) -> None:
        v = msg.get("data")
        if not isinstance(v, int | float) or not 0.0 <= v <= 1.0:  # NaN fails the range too
            self._report(session, f"/system/set_volume: volume must be in [0, 1], got {v!r}")
            return
        self.volume = float(v)
        self.bridge.publish(self._volume, {"data": self.volume})

    def _beep(self, msg: dict, session: Session | None) -> None:
        data = msg.get("data") or []
        if len(data) != 3 or not all(isinstance(x, int | float) and math.isfinite(x) for x in data):
            self._report(
                session,
                f"/system/beep: needs [duration (s), frequency (Hz), volume], got {data!r}",
            )
            return
        _log.info("system beep %.2f s at %.0f Hz (the simulator makes no sound)", *data[:2])

    def _speech(self, msg: dict, session: Session | None) -> None:
        _log.info("system says %r (the simulator makes no sound)", msg.get("data", ""))

    def _report(self, session: Session | None, text: str) -> None:
        if session is not None:
            session.report("error", text)
        else:
            _log.warning("%s", text)
