"""The ROS interface of the simulator: a rosbridge v2 server, the dVRK CRTK API over it, a
client mode for an existing ROS system, and the dVRK UDP JSON stream."""

from davinci_sim.bridge.config import BridgeConfig
from davinci_sim.bridge.server import RosbridgeServer

__all__ = ["BridgeConfig", "RosbridgeServer"]
