"""Shared set-up of the device tests."""

from __future__ import annotations

from davinci_sim.devices import SimulatedMTM
from davinci_sim.devices.safety import WrenchLimits
from davinci_sim.sim.simulation import Simulation


def free_mtmr():
    """MTMR enabled, homed and free (effort mode, gravity compensated), as when following,
    with its device (4 N, 500 N/s limits): ``(sim, device)``."""
    sim = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    arm = sim.arms["MTMR"]
    assert arm.state_command("enable") and arm.state_command("home")
    assert sim.run_until(lambda: arm.is_homed() and not arm.is_busy(), 10)
    device = SimulatedMTM(sim, "MTMR", limits=WrenchLimits(max_force=4.0, max_force_rate=500.0))
    sim.add_component(device)
    device.enter_effort_mode()
    return sim, device
