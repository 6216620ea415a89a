"""Fixtures of the bridge tests: a simulation in its thread, a server on a free port, clients.

roslibpy's default transport runs Twisted's reactor in a daemon thread that can start only
once per process: clients are closed, never ``terminate()``d.
"""

import logging
import os

os.environ.setdefault("MUJOCO_GL", "egl")


class _ClosedSends(logging.Filter):
    """Leaves out Twisted's report of a send queued for a connection that closed before the
    reactor ran it (an earlier test's stream: thousands, each a traceback the log capture
    formats while later clients' connects wait behind them, ``bridge_helpers.ros_client``)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "Attempt to send on a closed protocol" not in record.getMessage()


logging.getLogger("twisted").addFilter(_ClosedSends())

import pytest  # noqa: E402
from bridge_helpers import RawClient, ros_client  # noqa: E402

from davinci_sim.bridge import BridgeConfig, RosbridgeServer  # noqa: E402
from davinci_sim.bridge.dvrk_node import DvrkNode  # noqa: E402
from davinci_sim.sim.handle import ThreadedSimulation  # noqa: E402
from davinci_sim.sim.simulation import Simulation  # noqa: E402


@pytest.fixture
def handle():
    """PSM1 + ECM (+ SUJ) in real time (a fresh simulation per test: 40 ms to build)."""
    h = ThreadedSimulation(Simulation("psm1"), real_time=True, snapshot_period=0.001).start()
    yield h
    h.stop()


@pytest.fixture
def make_server():
    """``make_server(handle=None, **config)`` → a started server on a free port."""
    servers = []

    def make(handle=None, nodes=None, **config):
        if nodes is None:
            nodes = [DvrkNode(handle, rate=config.pop("rate", 100.0))] if handle else []
        server = RosbridgeServer(BridgeConfig(port=0, **config), nodes=nodes).start()
        servers.append(server)
        return server

    yield make
    for s in servers:
        s.stop()


@pytest.fixture
def dvrk_server(handle, make_server):
    return make_server(handle)


@pytest.fixture
def make_ros():
    """``make_ros(server)`` → a connected roslibpy client (closed after the test)."""
    clients = []

    def make(server):
        ros = ros_client(server.port)
        clients.append(ros)
        return ros

    yield make
    for ros in clients:
        try:
            ros.close()
        except Exception:
            pass


@pytest.fixture
def make_raw():
    clients = []

    def make(server, level="info"):
        c = RawClient(server, level)
        clients.append(c)
        return c

    yield make
    for c in clients:
        try:
            c.close()
        except Exception:
            pass
