"""Putting a console on a simulation: devices, console, teleoperations, haptic loop.

:func:`install_console` registers the components in the order the haptic loop needs
(components run in registration order each tick):

1. the master devices (``MTML/device``, ``MTMR/device``): read the operator's input;
2. ``console``: pedal and button events, teleoperation states;
3. the PSM teleoperations in the dVRK full system's declaration order (``MTMR_PSM1``,
   ``MTML_PSM2``, ``MTML_PSM3``, dvrk.md 6), then ``MTML_MTMR_ECM``: setpoints of the arms;
4. the arms and the physics step;
5. ``haptics`` (after the step): force fields → safety limits → wrench to each MTM.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from davinci_sim.console.console import Console
from davinci_sim.console.haptic_loop import HapticLoop
from davinci_sim.console.teleop_config import SIMULATED_SYSTEM, TeleopECMConfig, TeleopPSMConfig
from davinci_sim.console.teleop_ecm import TeleopECM
from davinci_sim.console.teleop_psm import TeleopPSM
from davinci_sim.devices.device import MasterDevice
from davinci_sim.devices.safety import WrenchLimits
from davinci_sim.devices.scripted import HandScript, circle
from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.haptics.contact import ContactFeedback
from davinci_sim.sim.simulation import Simulation

#: dvrk.md 6: teleoperations of the dVRK's simulated full system, in declaration order.
PSM_TELEOPS = (("MTMR", "PSM1"), ("MTML", "PSM2"), ("MTML", "PSM3"))
MTM_NAMES = ("MTML", "MTMR")


def install_console(
    sim: Simulation,
    *,
    devices: Mapping[str, MasterDevice] | None = None,
    teleop_config: TeleopPSMConfig = SIMULATED_SYSTEM,
    ecm_config: TeleopECMConfig | None = None,
    limits: WrenchLimits | None = None,
    contact_feedback: bool = False,
    tap_duration: float | None = 0.25,
    operator_present: bool = False,
    teleop_enabled: bool = False,
) -> Console:
    """Register master devices, the console, the teleoperations and the haptic loop.

    Args:
        sim: a simulation with at least one MTM and one PSM (or MTMs given as ``devices``).
        devices: MTM name -> device to use instead of the simulated MTM (e.g. a
            :class:`~davinci_sim.devices.UDPJSONDevice` acting as MTMR).
        teleop_config: settings of every PSM teleoperation (default: the dVRK's simulated
            system, no gripper pinch needed to start, dvrk.md 4.1).
        ecm_config: settings of the ECM teleoperation.
        limits: safety limits of the simulated MTM devices.
        contact_feedback: register the :class:`~davinci_sim.haptics.ContactFeedback` field.
        tap_duration: see :class:`Console`.
        operator_present, teleop_enabled: emulate the head sensor / enable teleoperation now.

    Returns:
        The console (``console.haptics`` is the haptic loop).

    Raises:
        ValueError: if a component name is taken or there is nothing to teleoperate.
    """
    devices = dict(devices or {})
    unknown = sorted(set(devices) - set(MTM_NAMES))
    if unknown:
        raise ValueError(f"devices for unknown MTMs {unknown}; MTMs: {list(MTM_NAMES)}")
    for mtm in MTM_NAMES:
        if mtm not in devices and mtm in sim.arms:
            devices[mtm] = SimulatedMTM(sim, mtm, limits=limits)
    pairs = [(m, p) for m, p in PSM_TELEOPS if m in devices and p in sim.arms]
    if not pairs:
        raise ValueError(
            f"nothing to teleoperate: MTM devices {sorted(devices)}, arms {sorted(sim.arms)}"
        )
    console = Console(sim, tap_duration=tap_duration)
    teleops = [TeleopPSM(sim, devices[m], mtm=m, psm=p, config=teleop_config) for m, p in pairs]
    ecm = None
    if "ECM" in sim.arms and all(m in devices for m in MTM_NAMES):
        ecm = TeleopECM(sim, devices["MTML"], devices["MTMR"], config=ecm_config)
    haptics = HapticLoop(sim, console)
    components = [
        *(devices[m] for m in MTM_NAMES if m in devices),
        console,
        *teleops,
        *([ecm] if ecm else []),
        haptics,
    ]
    taken = [c.name for c in components if c.name in sim.components]
    if taken:
        raise ValueError(f"component names already registered in the simulation: {taken}")
    for component in components:
        sim.add_component(component)
    for teleop in teleops:
        console.add_teleop_psm(teleop)
    if ecm is not None:
        console.set_teleop_ecm(ecm)
    console.haptics = haptics
    from davinci_sim.console import chunk

    if chunk.COMPILED:
        sim.set_chunker(chunk.ConsoleChunk(sim, console))
    if contact_feedback:
        haptics.add_field(ContactFeedback(dt=sim.dt), name="contact")
    if operator_present:
        console.emulate_operator_present(True)
    if teleop_enabled:
        console.teleop_enable(True)
    return console


def add_scripted_hands(
    sim: Simulation, console: Console, *, radius: float = 0.02, frequency: float = 0.5
) -> list[HandScript]:
    """A :class:`~davinci_sim.devices.HandScript` on each simulated MTM whose PSM
    teleoperation is selected: circles in the display plane and a gripper opening and
    closing between 6° and 40°; registered first, so each tick uses the new targets."""
    scripts = []
    for teleop in console.psm_teleops.values():
        device = teleop.device
        if not teleop.selected or not isinstance(device, SimulatedMTM):
            continue
        script = HandScript(
            device,
            circle(radius, frequency),
            gripper=lambda s: 0.4 + 0.3 * math.sin(2.0 * math.pi * 0.7 * s),
            when=teleop.is_following,
        )
        if script.name in sim.components:
            raise ValueError(f"component {script.name!r} already registered")
        scripts.append(script)
    first = next(iter(sim.components), None)  # the scripts go first, in this order
    for script in scripts:
        sim.add_component(script, before=first)
    return scripts
