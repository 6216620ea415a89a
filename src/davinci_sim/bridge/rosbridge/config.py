"""Options of the rosbridge server, checked when built."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal


@dataclass(frozen=True)
class BridgeConfig:
    """What a :class:`~davinci_sim.bridge.rosbridge.server.RosbridgeServer` does.

    Defaults follow rosbridge_server (rosbridge.md §1.1) where it has one.
    """

    host: str = "127.0.0.1"
    """Interface to bind: loopback unless told otherwise (``0.0.0.0`` for every interface)."""
    port: int = 9090
    """TCP port; 0 picks a free one (read it back from ``server.port``)."""
    ros_version: Literal[1, 2] = 2
    """Dialect: 1 (``pkg/Type``, ``secs``/``nsecs``, Header ``seq``) or 2 (``pkg/msg/Type``,
    ``sec``/``nanosec``). Both spellings are accepted on input."""
    max_message_size: int = 10_000_000
    """Largest incoming message, bytes (rosbridge's default). A larger one is refused with an
    error and the connection carries on; beyond twice this (+1 MiB) the websocket layer closes
    the connection (close code 1009, message too big)."""
    send_queue_length: int = 100
    """Messages kept per subscription when a client reads too slowly (oldest dropped). A
    subscription's own ``queue_length`` (> 0) replaces it."""
    control_queue_length: int = 1000
    """Service responses, status and action messages kept per client (oldest dropped)."""
    auth_token: str | None = None
    """If set, every client must first send an ``auth`` op whose ``mac`` is this token
    (``{"op": "auth", "mac": TOKEN}``), or the rosauth-style SHA-512 of ``token + client +
    dest + rand + t + level + end`` (roslibpy's ``Ros.authenticate``); only ``set_level`` may
    come before it. A client that sends anything else first, or a wrong or expired ``mac``,
    gets a ``status`` op at level error saying why, then the connection closes (code 1008)."""
    service_timeout: float = 10.0
    """Seconds to wait for a client that provides a service or an action server."""
    fragment_timeout: float = 60.0
    """Seconds an incomplete incoming fragmented message is kept."""
    stamp_clock: Literal["wall", "sim"] = "wall"
    """Header stamps and ``/rosapi/get_time``: ``wall`` = ROS time from the wall clock, as on
    the real dVRK; ``sim`` = simulation time (seconds since the simulation started)."""

    def __post_init__(self) -> None:
        if self.ros_version not in (1, 2):
            raise ValueError(f"ros_version must be 1 or 2, got {self.ros_version!r}")
        if not 0 <= self.port < 65536:
            raise ValueError(f"port must be in [0, 65535], got {self.port!r}")
        for name in ("max_message_size", "send_queue_length", "control_queue_length"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        for name in ("service_timeout", "fragment_timeout"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        if self.stamp_clock not in ("wall", "sim"):
            raise ValueError(f"stamp_clock must be 'wall' or 'sim', got {self.stamp_clock!r}")
        if self.auth_token is not None and not self.auth_token:
            raise ValueError("auth_token must be a non-empty string or None")
