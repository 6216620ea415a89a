"""The two transports the compatibility API runs over, for the tests: the in-process bridge
(no socket) and the rosbridge server (a websocket), each serving the dVRK's topics of a
running simulation."""

from __future__ import annotations

from contextlib import contextmanager

from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.bridge.rosbridge.server import RosbridgeServer
from davinci_sim.compat import ral as ral_module
from davinci_sim.compat.inprocess import InProcessBridge, dvrk_nodes
from davinci_sim.compat.transport import RosbridgeClient, WebSocketConnection

TRANSPORTS = ("in-process", "rosbridge")

#: The least time a test waits for a condition, s: the deadline only ends a failing test (a
#: busy machine must not fail a passing one); no test asserts how fast a condition comes.
FAIL_AFTER = 30.0


@contextmanager
def connected(handle, transport: str):
    """Every ``ral`` of this process connected to ``handle``'s simulation through
    ``transport`` (one of :data:`TRANSPORTS`); yields the client, disconnected at the end."""
    if transport == "in-process":
        server = InProcessBridge(handle).start()
        client = RosbridgeClient(server.connect())
    else:
        server = RosbridgeServer(BridgeConfig(port=0), nodes=dvrk_nodes(handle)).start()
        client = RosbridgeClient(WebSocketConnection(server.url))
    ral_module.set_client(client)
    try:
        yield client
    finally:
        ral_module.set_client(None)
        client.close()
        server.stop()
