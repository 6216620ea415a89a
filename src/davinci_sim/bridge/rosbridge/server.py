"""The rosbridge v2 WebSocket server: a thread with its own event loop.

``RosbridgeServer(config, nodes=[...]).start()`` binds (127.0.0.1:9090 by default), runs
the :class:`~davinci_sim.bridge.rosbridge.core.Bridge` and the given internal nodes in a daemon
thread, and serves every client until :meth:`RosbridgeServer.stop`. Any path and origin are
accepted; there is no permessage-deflate, as rosbridge_server (rosbridge.md §1.1, §6.1).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from websockets.asyncio.server import serve

from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.bridge.rosbridge.core import Bridge
from davinci_sim.bridge.rosbridge.rosapi import RosapiNode
from davinci_sim.bridge.rosbridge.session import Session
from davinci_sim.bridge.rosbridge.types import TypeRegistry
from davinci_sim.sim.runtime.service import AsyncService

_log = logging.getLogger("davinci_sim.bridge")


class Node(Protocol):
    """Something that lives in the bridge's loop: the dVRK API, the endoscope …"""

    def attach(self, bridge: Bridge) -> None:
        """Advertise topics and services (called in the loop's thread at start)."""

    async def detach(self) -> None:
        """Stop tasks and release resources (called in the loop's thread at stop)."""


class RosbridgeServer(AsyncService):
    """A rosbridge v2 server in its own thread (an :class:`~davinci_sim.sim.runtime.service.
    AsyncService`).

    Args:
        config: options (address, dialect, limits, authentication …).
        nodes: internal nodes to attach, in order (rosapi is always there).
        registry: message definitions (default: the built-in ones).
        clock: ROS time for stamps and ``/rosapi/get_time`` (default: wall clock, or
            what a node such as the dVRK node sets with ``bridge.clock``).
    """

    def __init__(
        self,
        config: BridgeConfig | None = None,
        *,
        nodes: Sequence[Node] = (),
        registry: TypeRegistry | None = None,
        clock: Callable[[], float] | None = None,
    ) -> None:
        super().__init__()
        self.config = config or BridgeConfig()
        self._nodes: list[Node] = [RosapiNode(), *nodes]
        self._registry = registry
        self._clock = clock
        self.bridge: Bridge | None = None
        self._port: int | None = None

    # ------------------------------------------------------------------ lifecycle
    thread_name = "rosbridge"

    def start(self, timeout: float = 10.0) -> RosbridgeServer:
        """Bind and serve; returns when clients can connect.

        Raises:
            OSError: if the address cannot be bound (e.g. the port is taken).
        """
        if self.running:
            return self
        super().start(timeout)
        _log.info("rosbridge server on %s (ROS %d)", self.url, self.config.ros_version)
        return self

    @property
    def port(self) -> int:
        """The bound port (the real one when the config asked for 0)."""
        if self._port is None:
            raise RuntimeError("the server is not started")
        return self._port

    @property
    def url(self) -> str:
        return f"ws://{self.config.host}:{self.port}"

    # ------------------------------------------------------------------ helpers
    def call(self, fn: Callable[[], Any], timeout: float = 5.0) -> Any:
        """Run ``fn()`` in the server's loop and return its result (from another thread)."""

        async def wrapper():
            return fn()

        return self.run_coroutine(wrapper()).result(timeout)

    def stats(self) -> dict:
        """Per-client queues, drops and counts; messages published per topic."""
        return self.call(lambda: self.bridge.stats())

    # ------------------------------------------------------------------ the thread
    async def main(self) -> None:
        cfg = self.config
        kwargs = {"clock": self._clock} if self._clock is not None else {}
        bridge = Bridge(cfg, self._registry, **kwargs)
        self.bridge = bridge
        bridge.setup_rosout()
        attached: list[Node] = []
        try:
            for node in self._nodes:
                node.attach(bridge)
                attached.append(node)
            async with serve(
                self._handler,
                cfg.host,
                cfg.port,
                compression=None,
                # Up to twice the limit is read and refused with an error (the connection goes
                # on); beyond that the websocket layer closes it (1009, message too big).
                max_size=2 * cfg.max_message_size + (1 << 20),
                max_queue=16,
                ping_interval=None,
                close_timeout=2,
            ) as server:
                self._port = server.sockets[0].getsockname()[1]
                self.ready()
                await self.stopping.wait()
                server.close(close_connections=True)
                await server.wait_closed()
        finally:
            for node in reversed(attached):
                try:
                    await node.detach()
                except Exception:
                    _log.exception("detaching %r failed", node)

    async def _handler(self, ws) -> None:
        bridge = self.bridge
        assert bridge is not None
        session = Session(bridge, ws)
        bridge.add_session(session)
        try:
            await session.run()
        finally:
            bridge.remove_session(session)
