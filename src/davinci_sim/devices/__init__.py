"""Master input devices: pose, twist, gripper and buttons in; wrench out.

* :class:`MasterDevice` — the one interface teleoperations use.
* :class:`SimulatedMTM` — the console model's MTML/MTMR, moved by a simulated hand.
* :class:`NetworkDevice` — pushed input with the dVRK watchdog (web console, ROS client, …).
* :class:`UDPJSONDevice` — the dVRK socket-streamer JSON format over UDP (dvrk.md 5).
* :class:`WrenchLimits`, :func:`clamp_wrench` — the clamp every MTM wrench goes through.
"""

from davinci_sim.devices.buttons import ButtonEvent, parse_button_event
from davinci_sim.devices.device import DVRK_WATCHDOG, MasterDevice
from davinci_sim.devices.hand import HandImpedance, hand_wrenches
from davinci_sim.devices.network import NetworkDevice
from davinci_sim.devices.safety import WrenchLimiter, WrenchLimits, clamp_wrench
from davinci_sim.devices.scripted import HandScript, circle
from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.devices.state import DeviceInput, DeviceSnapshot
from davinci_sim.devices.udp import UDPJSONDevice

__all__ = [
    "DVRK_WATCHDOG",
    "ButtonEvent",
    "DeviceInput",
    "DeviceSnapshot",
    "HandImpedance",
    "HandScript",
    "MasterDevice",
    "NetworkDevice",
    "SimulatedMTM",
    "UDPJSONDevice",
    "WrenchLimiter",
    "WrenchLimits",
    "circle",
    "clamp_wrench",
    "hand_wrenches",
    "parse_button_event",
]
