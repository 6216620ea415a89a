"""The ROS interface of the simulator: a rosbridge v2 server, the dVRK CRTK API over it, a
client mode for an existing ROS system, and the dVRK UDP JSON stream.

Typical use (what ``davinci-sim serve`` does)::

    sim = Simulation("full")
    handle = ThreadedSimulation(sim, snapshot_period=0.01).start()
    server = RosbridgeServer(BridgeConfig(port=9090), nodes=[DvrkNode(handle)]).start()
    ...
    server.stop(); handle.stop()

``rosbridge/`` is the generic rosbridge v2 server, with nothing of the dVRK in it: ``server``
(thread + event loop + websockets), ``session`` (one client), ``core`` (graph and routing),
``protocol`` (typed ops), ``codec`` (JSON/CBOR/PNG/fragments), ``msgdefs``/``types``/``convert``
(message definitions as data and validation), ``dialect`` (ROS 1 / ROS 2), ``rosapi``,
``auth``, ``publisher``, ``config``. Here, the simulator's side: the nodes ``dvrk_node``/
``dvrk_messages`` (the arms), ``console_node``, ``system_node``, ``task_node``, ``endoscope``;
``udp`` (the dVRK socket streamer), ``client_mode`` and ``app`` (``serve``).
"""

from davinci_sim.bridge.client_mode import ClientModeConfig, RosClientMode
from davinci_sim.bridge.console_node import ConsoleNode
from davinci_sim.bridge.dvrk_node import DvrkNode
from davinci_sim.bridge.endoscope import EndoscopeNode, QposProbe
from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.bridge.rosbridge.server import RosbridgeServer
from davinci_sim.bridge.udp import StreamConfig, UdpStreamer

__all__ = [
    "BridgeConfig",
    "ClientModeConfig",
    "ConsoleNode",
    "DvrkNode",
    "EndoscopeNode",
    "QposProbe",
    "RosClientMode",
    "RosbridgeServer",
    "StreamConfig",
    "UdpStreamer",
]
