"""A master device on UDP in the dVRK socket-streamer JSON format (dvrk.md 5).

An external program (or a dVRK running ``sawSocketStreamer`` with a configuration like the
dVRK's ``streamerMTML.json``: ``measured_cp``, ``gripper/measured_js`` …) sends datagrams to
this device's port; each tick the device drains its socket, so it acts as the MTM of a
teleoperation. Every ``send_period`` it sends the wrench to render back to the last sender
(or a fixed ``reply_to`` address) as ``{"spatial/servo_cf": {"Force": [...]}}`` (HRSV axes).

Socket I/O is confined to this module; parsing is :mod:`davinci_sim.devices.streamer`.
The socket is non-blocking: reading it costs the tick a few µs per datagram.
"""

from __future__ import annotations

import atexit
import math
import socket
from collections.abc import Callable

import numpy as np

from davinci_sim.devices import streamer
from davinci_sim.devices.device import DVRK_WATCHDOG
from davinci_sim.devices.network import NetworkDevice
from davinci_sim.devices.safety import WrenchLimits

#: Name of the outgoing wrench command: spatial (HRSV axes), as the wrench is computed.
WRENCH_COMMAND = "spatial/servo_cf"
#: Errors about bad datagrams are reported at most this often (s), with a count.
ERROR_INTERVAL = 1.0


class UDPJSONDevice(NetworkDevice):
    """A :class:`NetworkDevice` fed by socket-streamer datagrams; see the module docstring.

    Args:
        name: component name.
        host, port: address to bind (loopback by default; port 0 picks a free port, see
            :attr:`address`). The dVRK example configuration uses 48054 for MTML.
        reply_to: ``(host, port)`` to send wrenches to; default: the last sender.
        send_period: sim time between two wrench datagrams, s (0.001: every tick).
        watchdog, limits, dt, clock: as :class:`NetworkDevice`.
    """

    kind = "udp"

    def __init__(
        self,
        name: str,
        *,
        host: str = "127.0.0.1",
        port: int = 48054,
        reply_to: tuple[str, int] | None = None,
        send_period: float = 0.001,
        watchdog: float | None = DVRK_WATCHDOG,
        limits: WrenchLimits | None = None,
        dt: float = 0.001,
        clock: Callable[[], float] | None = None,
    ) -> None:
        if not (math.isfinite(send_period) and send_period > 0):
            raise ValueError(f"send_period must be a time > 0 in s, got {send_period!r}")
        super().__init__(name, watchdog=watchdog, limits=limits, dt=dt, clock=clock)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((host, port))
        except OSError as e:
            self._sock.close()
            raise OSError(f"{name}: cannot bind UDP {host}:{port}: {e}") from None
        self._sock.setblocking(False)
        self._peer = reply_to
        self._fixed_peer = reply_to is not None
        self.send_period = send_period
        self._next_send = -math.inf
        self._errors = 0
        self._last_error_report = -math.inf
        self.datagrams_received = 0
        self.datagrams_sent = 0
        atexit.register(self.close)

    @property
    def address(self) -> tuple[str, int]:
        """The bound ``(host, port)``."""
        return self._sock.getsockname()

    def close(self) -> None:
        """Close the socket (idempotent)."""
        if self._sock.fileno() >= 0:
            self._sock.close()

    # ------------------------------------------------------------ the tick
    def pre_step(self, t: float) -> None:
        self._now = t
        self._drain()
        super().pre_step(t)
        if self._peer is not None and t >= self._next_send:
            self._send_wrench(t)

    def _drain(self) -> None:
        while self._sock.fileno() >= 0:
            try:
                data, sender = self._sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as e:  # e.g. ICMP port unreachable from a closed peer
                self._report(f"receive failed: {e}")
                return
            self.datagrams_received += 1
            if not self._fixed_peer:
                self._peer = sender
            self._handle(data)

    def _handle(self, data: bytes) -> None:
        try:
            obj = streamer.parse_datagram(data)
            T = twist = gripper = None
            buttons = {}
            for key, payload in obj.items():
                if key in streamer.IGNORED:
                    continue
                if isinstance(payload, dict) and not streamer.is_valid(payload):
                    continue
                if key == streamer.POSE:
                    T = streamer.decode_pose(payload)
                elif key == streamer.TWIST:
                    twist = streamer.decode_twist(payload)
                elif key == streamer.GRIPPER:
                    gripper = float(streamer.decode_joint_position(payload)[0])
                elif key in streamer.BUTTONS:
                    buttons[key] = streamer.decode_button(payload)
                else:
                    known = sorted({streamer.POSE, streamer.TWIST, streamer.GRIPPER,
                                    *streamer.BUTTONS, *streamer.IGNORED})  # fmt: skip
                    raise streamer.StreamerFormatError(f"unknown name {key!r}; known: {known}")
        except streamer.StreamerFormatError as e:
            self._report(str(e))
            return
        self.push(T, gripper=gripper, twist=twist, buttons=buttons or None)

    def _report(self, text: str) -> None:
        """Bad datagrams: one error message per ERROR_INTERVAL, with a count."""
        self._errors += 1
        if self._now - self._last_error_report >= ERROR_INTERVAL:
            suffix = f" ({self._errors} bad datagrams so far)" if self._errors > 1 else ""
            self.channels.message("error", f"{text}{suffix}", self._now)
            self._last_error_report = self._now

    def _send_wrench(self, t: float) -> None:
        self._next_send = t + self.send_period - 1e-9
        message = streamer.datagram(
            **{WRENCH_COMMAND: streamer.encode_wrench(self._wrench, self.name)}
        )
        try:
            self._sock.sendto(message, self._peer)
            self.datagrams_sent += 1
        except OSError as e:
            self._report(f"send to {self._peer} failed: {e}")

    def _apply_wrench(self, wrench: np.ndarray) -> None:
        """Sent with the next periodic datagram (see ``send_period``)."""

    # ------------------------------------------------------------ state
    #: The socket, the peer and the datagram counters are not state: a restored device keeps
    #: talking to whoever it talks to now.
    _STATE = NetworkDevice._STATE + ("_next_send",)
