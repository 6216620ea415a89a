"""The simulator's bridge and dVRK nodes in this process, reached without a socket.

:class:`InProcessBridge` runs the bridge core (:class:`~davinci_sim.bridge.rosbridge.core.
Bridge`) with the nodes ``davinci-sim serve`` attaches (rosapi, the dVRK arms, the console
and teleoperations, the system topics) on a thread with its own asyncio loop, as the
rosbridge server does, but binds no port: :meth:`InProcessBridge.connect` returns an
:class:`InProcessConnection`, a client session whose frames go through in-memory queues
instead of a websocket. Everything else — parsing, validation, refusals, latching,
per-subscription queues — is the server's own code, so a script behaves the same in-process
as over the network.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.bridge.rosbridge.core import Bridge
from davinci_sim.bridge.rosbridge.rosapi import RosapiNode
from davinci_sim.bridge.rosbridge.session import Session
from davinci_sim.compat.transport import TransportError
from davinci_sim.sim.runtime.service import AsyncService

if TYPE_CHECKING:
    from davinci_sim.sim.handle import SimHandle

_log = logging.getLogger("davinci_sim.compat")

_CLOSED = object()


def dvrk_nodes(handle: SimHandle, rate: float = 100.0, tf_rate: float = 50.0) -> list:
    """The nodes serving the dVRK API of ``handle``'s simulation (as ``davinci-sim serve``
    attaches them, without the endoscope images and the task topics)."""
    from davinci_sim.bridge.console_node import ConsoleNode
    from davinci_sim.bridge.dvrk_node import DvrkNode
    from davinci_sim.bridge.system_node import SystemNode

    return [DvrkNode(handle, rate=rate, tf_rate=tf_rate), ConsoleNode(handle, rate=rate),
            SystemNode(handle)]  # fmt: skip


class _PipeSocket:
    """What a :class:`~davinci_sim.bridge.rosbridge.session.Session` needs of a websocket:
    frames in (async iteration), frames out (``send``), ``close``."""

    remote_address = ("in-process", 0)

    def __init__(self, loop: asyncio.AbstractEventLoop, deliver: Callable[[str], None]) -> None:
        self._loop = loop
        self._incoming: asyncio.Queue = asyncio.Queue()
        self._deliver = deliver
        self.closed = False

    def push(self, text: str) -> None:
        """From the client's thread: one frame for the server."""
        self._loop.call_soon_threadsafe(self._incoming.put_nowait, text)

    def __aiter__(self):
        return self

    async def __anext__(self) -> str:
        frame = await self._incoming.get()
        if frame is _CLOSED:
            raise StopAsyncIteration
        return frame

    async def send(self, frame: Any, text: bool = False) -> None:
        if not self.closed:
            self._deliver(frame if isinstance(frame, str) else frame.decode("utf-8"))

    async def close(self, code: int = 1000, reason: str = "") -> None:
        self.closed = True
        self._incoming.put_nowait(_CLOSED)


class InProcessConnection:
    """A client session of an :class:`InProcessBridge` (a :class:`~davinci_sim.compat.
    transport.Connection`). Incoming frames are delivered from the bridge's loop thread."""

    def __init__(self, bridge: InProcessBridge) -> None:
        self._bridge = bridge
        self._socket: _PipeSocket | None = None
        self._on_frame: Callable[[str], None] | None = None
        self._on_close: Callable[[], None] | None = None

    def start(self, on_frame: Callable[[str], None], on_close: Callable[[], None]) -> None:
        self._on_frame, self._on_close = on_frame, on_close
        if not self._bridge.running:
            raise TransportError("the in-process bridge is not running")
        self._socket = self._bridge.open_session(on_frame, on_close)

    def send(self, text: str) -> None:
        if self._socket is None or self._socket.closed or not self._bridge.running:
            raise TransportError("the in-process bridge is closed")
        self._socket.push(text)

    def close(self) -> None:
        if self._socket is not None and not self._socket.closed and self._bridge.running:
            self._socket.closed = True
            self._socket.push(_CLOSED)  # type: ignore[arg-type]


class InProcessBridge(AsyncService):
    """The bridge core and ``nodes`` on a thread of this process, no socket (see the module
    docstring). ``nodes`` default to :func:`dvrk_nodes` of ``handle``."""

    thread_name = "crtk-in-process-bridge"

    def __init__(self, handle: SimHandle, *, nodes: Sequence[Any] | None = None,
                 config: BridgeConfig | None = None) -> None:  # fmt: skip
        super().__init__()
        self.config = config or BridgeConfig(port=0)
        self._nodes = [RosapiNode(), *(dvrk_nodes(handle) if nodes is None else nodes)]
        self.bridge: Bridge | None = None
        self._sessions: set[asyncio.Task] = set()

    async def main(self) -> None:
        bridge = Bridge(self.config)
        self.bridge = bridge
        bridge.setup_rosout()
        attached: list = []
        try:
            for node in self._nodes:
                node.attach(bridge)
                attached.append(node)
            self.ready()
            await self.stopping.wait()
            for task in list(self._sessions):
                task.cancel()
        finally:
            for node in reversed(attached):
                try:
                    await node.detach()
                except Exception:
                    _log.exception("detaching %r failed", node)

    def open_session(self, on_frame: Callable[[str], None],
                     on_close: Callable[[], None]) -> _PipeSocket:  # fmt: skip
        """A new client session (from any thread); returns its socket end."""

        async def open_() -> _PipeSocket:
            socket = _PipeSocket(asyncio.get_running_loop(), on_frame)
            session = Session(self.bridge, socket)
            self.bridge.add_session(session)

            async def run() -> None:
                try:
                    await session.run()
                finally:
                    self.bridge.remove_session(session)
                    on_close()

            task = asyncio.ensure_future(run())
            self._sessions.add(task)
            task.add_done_callback(self._sessions.discard)
            return socket

        return self.run_coroutine(open_()).result(10.0)

    def connect(self) -> InProcessConnection:
        return InProcessConnection(self)
