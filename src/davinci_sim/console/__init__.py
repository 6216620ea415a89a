"""The surgeon console: pedals and console events, dVRK teleoperation of PSMs and the ECM.

* :func:`install_console` — devices + console + teleoperations + haptic loop on a simulation.
* :class:`Console` — pedals, ``emulate_*``, teleop enable/scale/select (dvrk.md 2.3).
* :class:`TeleopPSM` — MTM → PSM with the dVRK state machine and follow mode (dvrk.md 4).
* :class:`TeleopECM` — both MTMs move the camera while the camera pedal is held.
* :class:`HapticLoop` — force fields → wrench clamp → MTM, each tick after the physics step.
"""

from davinci_sim.console.console import BUTTONS, PEDALS, Console, ConsoleState
from davinci_sim.console.haptic_loop import HapticLoop, HapticsState
from davinci_sim.console.setup import install_console
from davinci_sim.console.teleop_config import SIMULATED_SYSTEM, TeleopECMConfig, TeleopPSMConfig
from davinci_sim.console.teleop_ecm import TeleopECM, TeleopECMState
from davinci_sim.console.teleop_psm import TeleopPSM, TeleopPSMState

__all__ = [
    "BUTTONS",
    "PEDALS",
    "SIMULATED_SYSTEM",
    "Console",
    "HapticLoop",
    "HapticsState",
    "ConsoleState",
    "TeleopECM",
    "TeleopECMConfig",
    "TeleopECMState",
    "TeleopPSM",
    "TeleopPSMConfig",
    "TeleopPSMState",
    "install_console",
]
